// SPDX-License-Identifier: BSD-3-Clause
// A rendered survey whose EXIF altitudes drift by 100 m over the flight
// (a consumer drone's barometric drift), through the whole pipeline with
// GPS only: the GPS alone would tilt the block by tens of degrees; the
// adjusted cameras stay within 1 degree of their true attitude and the drift
// is recovered within its sigma (issue 17), whether the block is nadir or
// oblique with gimbal tags in its photos.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "libphoto/base/atomic_file.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/simulate/survey_writer.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;

// A drifting survey rendered, then run through the pipeline with GPS only.
struct DriftRun {
  nlohmann::json report, truth;
  int registered = 0, photos = 0;
  double worst_attitude_deg = 0.0;  // adjusted against true, over the registered photos
};

DriftRun RunDriftingSurvey(const fs::path& dir, double gimbal_pitch_deg, bool gimbal_xmp) {
  SimulationOptions sim;
  sim.survey.seed = 11;
  sim.survey.width = 640;
  sim.survey.height = 480;
  sim.survey.brown_params = {520.0, 322.0, 238.0, -0.08, 0.05, -0.01, 0.0005, -0.0003};
  sim.survey.area_width_m = 110.0;
  sim.survey.area_height_m = 80.0;
  sim.survey.flight_height_m = 45.0;
  sim.survey.relief_m = 4.0;
  sim.survey.num_tie_points = 300;
  sim.survey.num_control_points = 0;
  sim.survey.num_check_points = 0;
  sim.survey.gimbal_pitch_deg = gimbal_pitch_deg;
  sim.write_gimbal_xmp = gimbal_xmp;
  sim.georef.seed = 11;
  sim.georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, 100.0);
  const fs::path survey = dir / "survey";
  WriteSyntheticSurvey(sim, survey);

  PipelineOptions o;
  o.images_dir = survey / "images";
  o.workspace = dir / "ws";
  o.georef.leave_one_out = false;
  o.log = [](const std::string&) {};
  DriftRun run;
  EXPECT_NE(RunPipeline(o), "failed");
  run.report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  run.truth = nlohmann::json::parse(ReadTextFile(survey / "truth" / "truth.json"));
  const SparseModel adjusted = ReadColmapText(o.workspace / "georeferenced");
  const SparseModel exact = ReadColmapText(survey / "truth" / "model");
  std::map<std::string, Eigen::Quaterniond> true_rotation;
  for (const Image& image : exact.images) true_rotation[image.name] = image.pose.cam_from_world;
  run.photos = static_cast<int>(exact.images.size());
  for (const Image& image : adjusted.images) {
    if (!image.registered || !true_rotation.count(image.name)) continue;
    const Eigen::AngleAxisd d(image.pose.cam_from_world * true_rotation[image.name].conjugate());
    run.worst_attitude_deg = std::max(run.worst_attitude_deg, d.angle() * 180.0 / M_PI);
    ++run.registered;
  }
  return run;
}

// The drift per flight recovered within 3 sigma, the sigma honest.
void ExpectDriftRecovered(const DriftRun& run) {
  const auto& drift = run.report["gps_drift"];
  EXPECT_GT(drift["gps_fit_tilt_deg"].get<double>(), 10.0);
  ASSERT_TRUE(drift["estimated"].get<bool>());
  EXPECT_TRUE(drift["attitude_prior"].get<bool>());
  EXPECT_TRUE(drift["axes"]["u"].get<bool>());
  ASSERT_EQ(drift["flights"].size(), 1u);
  const double true_rate = run.truth["gps_drift_m_per_s"][2];
  const double rate = drift["flights"][0]["rate_m_per_s"]["u_m"];
  const double sigma = drift["flights"][0]["rate_sigma_m_per_s"]["u_m"];
  ASSERT_GT(sigma, 0.0);
  EXPECT_LT(std::abs(rate - true_rate), 3.0 * sigma);
  EXPECT_LT(sigma, 0.05 * true_rate);
}

TEST(GpsDrift, RenderedSurveyWithDriftingAltitudeKeepsItsAttitude) {
  testing::TempDir dir;
  const DriftRun run = RunDriftingSurvey(dir.path(), -90.0, false);
  SCOPED_TRACE(run.report["gps_drift"].dump(1));
  EXPECT_EQ(run.report["gps_drift"]["vertical_source"], "nadir");
  ExpectDriftRecovered(run);
  // Every adjusted camera within 1 degree of its true attitude.
  EXPECT_GE(run.registered, run.photos - 2);
  EXPECT_LT(run.worst_attitude_deg, 1.0);
  EXPECT_LT(run.report["adjustment"]["attitude"]["mean_axis_tilt_deg"].get<double>(), 1.0);
}

// The same flight with the camera leaning 30 degrees towards the image's top
// (north, then south, strip by strip) and DJI gimbal tags in the photos: the
// optical axes spread too far for a nadir vertical; the gimbal pitches,
// read from the JPEGs' XMP, level the block instead.
TEST(GpsDrift, ObliqueRenderedSurveyIsLevelledByTheGimbalTagsInItsPhotos) {
  testing::TempDir dir;
  const DriftRun run = RunDriftingSurvey(dir.path(), -60.0, true);
  SCOPED_TRACE(run.report["gps_drift"].dump(1));
  const auto& attitude = run.report["adjustment"]["attitude"];
  SCOPED_TRACE(attitude.dump(1));
  EXPECT_FALSE(attitude["nadir_block"].get<bool>());
  EXPECT_EQ(run.report["gps_drift"]["vertical_source"], "gimbal");
  ExpectDriftRecovered(run);
  EXPECT_GE(run.registered, run.photos - 2);
  EXPECT_LT(run.worst_attitude_deg, 1.0);
  // The adjusted block against its gimbals: level within a degree, and
  // nothing flagged.
  ASSERT_TRUE(attitude.contains("gimbal"));
  EXPECT_EQ(attitude["gimbal"]["images"].get<int>(), run.registered);
  EXPECT_LT(attitude["gimbal"]["block_tilt_deg"].get<double>(), 1.0);
  for (const auto& w : run.report["warnings"]) EXPECT_NE(w["code"], "GIMBAL_ATTITUDE_DISAGREES");
  for (const auto& e : run.report["errors"]) EXPECT_NE(e["code"], "GIMBAL_ATTITUDE_DISAGREES");
}

}  // namespace
}  // namespace aerotri
