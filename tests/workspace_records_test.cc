// SPDX-License-Identifier: BSD-3-Clause
// The workspace's typed records: what a stage writes reads back the same, a
// corrupt or foreign record is refused naming the file and the field, and the
// fingerprints change exactly when an option that shapes the product does.
#include "libphoto/pipeline/workspace.h"

#include <gtest/gtest.h>

#include "libphoto/base/error.h"

namespace aerotri {
namespace {

TEST(WorkspaceRecords, MatchRecordRoundTripsAndRefusesCorruptFiles) {
  MatchRecord r;
  r.strategy = "gps neighbours (12)";
  r.candidate_pairs = 40;
  r.verified_pairs = 31;
  r.images = {{"a.jpg", 900, 4, 1200}, {"b.jpg", 0, 0, 0}};
  r.options = {{"ratio", 0.8}};
  const nlohmann::json doc = ToJson(r);
  EXPECT_EQ(doc.at("schema_version"), MatchRecord::kSchemaVersion);
  const MatchRecord back = MatchRecordFromJson(doc, "matches.json");
  EXPECT_EQ(back.strategy, r.strategy);
  EXPECT_EQ(back.candidate_pairs, 40);
  EXPECT_EQ(back.verified_pairs, 31);
  ASSERT_EQ(back.images.size(), 2u);
  EXPECT_EQ(back.images[0].name, "a.jpg");
  EXPECT_EQ(back.images[0].verified_matches, 1200);
  EXPECT_EQ(back.options, r.options);
  EXPECT_EQ(ToJson(back), doc);

  nlohmann::json missing = doc;
  missing.erase("verified_pairs");
  try {
    MatchRecordFromJson(missing, "ws/matches.json");
    FAIL() << "accepted";
  } catch (const ParseError& e) {
    EXPECT_EQ(std::string(e.what()), "ws/matches.json: missing field 'verified_pairs'");
  }
  nlohmann::json wrong_type = doc;
  wrong_type["images"][0]["features"] = "many";
  EXPECT_THROW(MatchRecordFromJson(wrong_type, "ws/matches.json"), ParseError);
  nlohmann::json future = doc;
  future["schema_version"] = 99;
  try {
    MatchRecordFromJson(future, "ws/matches.json");
    FAIL() << "accepted";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("schema_version 99"), std::string::npos) << e.what();
  }
}

TEST(WorkspaceRecords, ReconstructionRecordRoundTripsAndReadsUnversionedFiles) {
  ReconstructionRecord r;
  r.initial_pair = "a.jpg-b.jpg";
  r.tracks = 5000;
  r.global_adjustments = 17;
  r.adjustment_iterations = 187;
  r.registered = 1;
  r.images = {{"a.jpg", true, ""}, {"c.jpg", false, "PnP: 3 inliers of 40, needs 15"}};
  r.options = {{"min_pnp_inliers", 15}};
  const nlohmann::json doc = ToJson(r);
  EXPECT_FALSE(doc.at("images")[0].contains("why_not"));  // registered: nothing to say
  const ReconstructionRecord back = ReconstructionRecordFromJson(doc, "reconstruction.json");
  EXPECT_EQ(back.initial_pair, r.initial_pair);
  EXPECT_EQ(back.tracks, 5000);
  EXPECT_EQ(back.adjustment_iterations, 187);
  ASSERT_EQ(back.images.size(), 2u);
  EXPECT_FALSE(back.images[1].registered);
  EXPECT_EQ(back.images[1].why_not, r.images[1].why_not);
  EXPECT_EQ(ToJson(back), doc);

  // Written before records had a version (and options): read as version 1.
  nlohmann::json old = doc;
  old.erase("schema_version");
  old.erase("options");
  const ReconstructionRecord read = ReconstructionRecordFromJson(old, "reconstruction.json");
  EXPECT_TRUE(read.options.is_null());
  EXPECT_EQ(read.registered, 1);
}

TEST(WorkspaceRecords, FingerprintsFollowTheOptionsThatShapeEachProduct) {
  PipelineOptions o;
  o.workspace = "no_such_workspace";
  const nlohmann::json features = FeatureFingerprint(o);
  const nlohmann::json match = MatchFingerprint(o);
  const nlohmann::json mapper = ReconstructFingerprint(o);

  PipelineOptions other = o;
  other.features.max_features = 4000;
  EXPECT_NE(FeatureFingerprint(other), features);
  EXPECT_EQ(MatchFingerprint(other), match);  // through the recorded features only

  other = o;
  other.matching.gps_neighbours = 20;
  EXPECT_EQ(FeatureFingerprint(other), features);
  EXPECT_NE(MatchFingerprint(other), match);
  EXPECT_EQ(FingerprintChanges(match, MatchFingerprint(other)), "gps_neighbours: 12 -> 20");

  other = o;
  other.mapper.max_reprojection_px = 2.0;
  EXPECT_EQ(MatchFingerprint(other), match);
  EXPECT_NE(ReconstructFingerprint(other), mapper);
  other = o;
  other.mapper.global_adjust_screening = false;
  EXPECT_EQ(FingerprintChanges(mapper, ReconstructFingerprint(other)), "global_adjust_screening: true -> false");

  // Threads and progress shape nothing.
  other = o;
  other.num_threads = 1;
  other.matching.num_threads = 1;
  other.mapper.num_threads = 1;
  EXPECT_EQ(FeatureFingerprint(other), features);
  EXPECT_EQ(MatchFingerprint(other), match);
  EXPECT_EQ(ReconstructFingerprint(other), mapper);

  // An unrecorded product (a workspace from before fingerprints) reruns.
  EXPECT_NE(FingerprintChanges(nlohmann::json(), match).find("unrecorded"), std::string::npos);
}

// The photos' rolling shutters as ingest recorded what they say: a Sequoia's
// stated readout and IMU velocity, a DJI Phantom 4 Pro's flight speeds (x
// north, y east) with the known-camera table's 33 ms, a DJI camera the table
// lacks (readout 0, for --rolling-shutter estimate), and a photo that states
// no motion (a global shutter). Each source is said once.
TEST(IngestView, RollingShuttersFromWhatEachPhotoStates) {
  IngestView view;
  auto photo = [&](const std::string& name, const std::string& make, const std::string& model,
                   const nlohmann::json& says) {
    IngestedImage im;
    im.name = name;
    im.make = make;
    im.model = model;
    im.width = 5472;
    im.height = 3648;
    im.camera_says = says;
    view.record.images.push_back(im);
  };
  photo("sequoia.jpg", "Parrot", "Sequoia",
        {{"line_readout_time_s", 0.0475}, {"imu_linear_velocity_mps", {2.09, 12.59, 0.61}}});
  photo("p4p_a.jpg", "DJI", "FC6310", {{"flight_speed_mps", {9.8, -0.3, 0.1}}});
  photo("p4p_b.jpg", "DJI", "FC6310", {{"flight_speed_mps", {-9.7, 0.4, 0.0}}});
  photo("unknown.jpg", "DJI", "FC9999", {{"flight_speed_mps", {5.0, 5.0, 0.0}}});
  photo("still.jpg", "DJI", "FC6310", nlohmann::json::object());
  std::string source;
  const std::map<std::string, RollingShutterMotion> motion = view.RollingShutters(&source);
  ASSERT_EQ(motion.size(), 4u);
  EXPECT_DOUBLE_EQ(motion.at("sequoia.jpg").readout_time_s, 0.0475);
  EXPECT_EQ(motion.at("sequoia.jpg").velocity, Eigen::Vector3d(2.09, 12.59, 0.0));
  EXPECT_DOUBLE_EQ(motion.at("p4p_a.jpg").readout_time_s, 0.033);
  EXPECT_EQ(motion.at("p4p_a.jpg").velocity, Eigen::Vector3d(-0.3, 9.8, 0.0));
  EXPECT_EQ(motion.at("p4p_b.jpg").velocity, Eigen::Vector3d(0.4, -9.7, 0.0));
  EXPECT_EQ(motion.at("unknown.jpg").readout_time_s, 0.0);
  EXPECT_FALSE(motion.count("still.jpg"));
  // Three sources, each once: the Sequoia's tags, the P4P's speeds with the
  // table, the unknown camera's speeds without a readout.
  EXPECT_NE(source.find("Camera:LineReadoutTime"), std::string::npos) << source;
  EXPECT_NE(source.find("33 ms for the DJI FC6310"), std::string::npos) << source;
  EXPECT_NE(source.find("not in the known-camera table"), std::string::npos) << source;
  EXPECT_EQ(source.find("33 ms"), source.rfind("33 ms")) << source;
}

}  // namespace
}  // namespace aerotri
