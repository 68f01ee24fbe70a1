// SPDX-License-Identifier: BSD-3-Clause
// aerotri adjust end to end, in-process: a simulated survey's exported model
// (arbitrary frame), GPS CSV, control and check files in; report.json and the
// ENU model out, with the keys the georeferencing issue names.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <algorithm>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/io/colmap_text.h"
#include "tests/test_util.h"
#include "tools/commands.h"

namespace aerotri {
namespace {

struct RunResult {
  int code;
  std::string out, err;
};

RunResult RunAdjustInProcess(const AdjustArgs& args) {
  std::ostringstream out, err;
  ToolContext ctx;
  ctx.out = &out;
  ctx.err = &err;
  const int code = RunAdjust(args, ctx);
  return {code, out.str(), err.str()};
}

class AdjustCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    SimulateArgs sim;
    sim.output = (dir_->path() / "sim").string();
    sim.no_images = true;
    sim.seed = 4;
    std::ostringstream out, err;
    ToolContext ctx;
    ctx.out = &out;
    ctx.err = &err;
    ctx.quiet = true;
    ASSERT_EQ(RunSimulate(sim, ctx), 0);
  }
  static void TearDownTestSuite() { delete dir_; }
  AdjustArgs Args(const std::string& out) const {
    AdjustArgs a;
    const auto sim = dir_->path() / "sim";
    a.model_dir = (sim / "model").string();
    a.gps_csv = (sim / "gps.csv").string();
    a.gcp = (sim / "gcp_list.txt").string();
    a.checkpoints = (sim / "checkpoints.txt").string();
    a.output = (dir_->path() / out).string();
    return a;
  }
  static testing::TempDir* dir_;
};
testing::TempDir* AdjustCommand::dir_ = nullptr;

TEST_F(AdjustCommand, WritesReportWithEveryKey) {
  const AdjustArgs args = Args("out");
  const RunResult run = RunAdjustInProcess(args);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(ReadTextFile(std::filesystem::path(args.output) / "report.json"));
  EXPECT_EQ(report["crs"], "EPSG:32632");
  EXPECT_NEAR(report["enu_origin"]["lat_deg"].get<double>(), 46.5, 0.01);
  for (const char* group : {"control_points", "check_points"}) {
    for (const char* key : {"count", "rmse_x_m", "rmse_y_m", "rmse_z_m", "rmse_h_m", "rmse_3d_m", "points"}) {
      EXPECT_TRUE(report[group].contains(key)) << group << "." << key;
    }
    for (const auto& p : report[group]["points"]) {
      for (const char* key : {"name", "dx_m", "dy_m", "dz_m", "reprojection_rms_px"}) {
        EXPECT_TRUE(p.contains(key)) << group << " point " << key;
      }
    }
  }
  EXPECT_EQ(report["control_points"]["count"], 8);
  EXPECT_EQ(report["check_points"]["count"], 6);
  // The simulation's GSD is 7.5 cm; check points within a few centimetres.
  const double rmse_h = report["check_points"]["rmse_h_m"];
  const double rmse_z = report["check_points"]["rmse_z_m"];
  EXPECT_GT(report["check_points"]["rmse_3d_m"].get<double>(), 0.002);
  EXPECT_LT(report["check_points"]["rmse_3d_m"].get<double>(), 0.08);
  EXPECT_NEAR(report["asprs"]["edition_2014"]["horizontal_accuracy_95_m"].get<double>(), 1.7308 * rmse_h, 1e-12);
  EXPECT_NEAR(report["asprs"]["edition_2014"]["nva_95_m"].get<double>(), 1.96 * rmse_z, 1e-12);
  EXPECT_NEAR(report["asprs"]["edition_2023"]["rmse_v_m"].get<double>(), rmse_z, 1e-12);
  ASSERT_EQ(report["cameras"].size(), 48u);
  EXPECT_TRUE(report["cameras"][0].contains("de_m"));
  for (const char* key : {"initial_rms_px", "final_rms_px", "iterations", "termination", "datum", "intrinsics"}) {
    EXPECT_TRUE(report["adjustment"].contains(key)) << key;
  }
  EXPECT_NE(report["adjustment"]["datum"].get<std::string>().find("datum from priors"), std::string::npos);
  // Variance components by default: the ties, stated 1 px, show the
  // simulation's 0.3 px and are weighed by it; the χ² test is of the stated
  // sigmas, the final σ0 of the estimated ones.
  const auto& vc = report["adjustment"]["variance_components"];
  EXPECT_TRUE(vc["estimated"].get<bool>());
  bool ties = false;
  // The groups' shares of the redundancy add up to the adjustment's.
  double shares = 0.0;
  for (const auto& g : vc["groups"]) shares += g["redundancy"].get<double>();
  EXPECT_NEAR(shares, report["adjustment"]["redundancy"].get<double>(), 1e-6 * shares);
  for (const auto& g : vc["groups"]) {
    if (g["group"] != "tie_points") continue;
    ties = true;
    EXPECT_EQ(g["stated_sigma"].get<double>(), 1.0);
    EXPECT_GT(g["estimated_sigma"].get<double>(), 0.27);
    EXPECT_LT(g["estimated_sigma"].get<double>(), 0.33);
    EXPECT_NEAR(g["sigma0"].get<double>(), 1.0, 0.05);
  }
  EXPECT_TRUE(ties);
  EXPECT_LT(report["adjustment"]["chi2_test"]["sigma0"].get<double>(), 0.4);
  EXPECT_FALSE(report["adjustment"]["chi2_test"]["consistent"].get<bool>());
  EXPECT_NEAR(report["adjustment"]["sigma0"].get<double>(), 1.0, 0.05);
  // The model is written in ENU: cameras ~60 m above the origin's ground.
  const SparseModel model = ReadColmapText(std::filesystem::path(args.output) / "model");
  EXPECT_EQ(model.images.size(), 48u);
  EXPECT_NEAR(model.images[0].pose.centre_in_world.z(), 0.0, 20.0);
  EXPECT_NE(run.out.find("check_count=6"), std::string::npos);
}

TEST_F(AdjustCommand, CompoundCrsGivesOrthometricCoordinates) {
  AdjustArgs args = Args("out_compound");
  args.crs = "EPSG:32632+5773";
  ASSERT_EQ(RunAdjustInProcess(args).code, 0);
  AdjustArgs plain = Args("out_plain");
  ASSERT_EQ(RunAdjustInProcess(plain).code, 0);
  const auto a = nlohmann::json::parse(ReadTextFile(std::filesystem::path(args.output) / "report.json"));
  const auto b = nlohmann::json::parse(ReadTextFile(std::filesystem::path(plain.output) / "report.json"));
  EXPECT_EQ(a["crs"], "EPSG:32632+5773");
  // Same surveyed point: orthometric = ellipsoidal - 50.09 m (EGM96 here).
  const double h_ortho = a["check_points"]["points"][0]["surveyed"][2];
  const double h_ell = b["check_points"]["points"][0]["surveyed"][2];
  EXPECT_NEAR(h_ell - h_ortho, 50.09, 0.02);
  // Residuals do not depend on the vertical datum.
  EXPECT_NEAR(a["check_points"]["rmse_z_m"].get<double>(), b["check_points"]["rmse_z_m"].get<double>(), 1e-3);
}

TEST_F(AdjustCommand, InputsAreNeverModified) {
  AdjustArgs args = Args("unused");
  args.output = args.model_dir;
  EXPECT_THROW(RunAdjustInProcess(args), InvalidArgument);
}


// Writes the simulation's GPS CSV with the positions handed out to the
// images in another order: order[k] is the row whose position image k gets.
std::string ScrambledGpsCsv(const std::string& path, const std::filesystem::path& out,
                            const std::function<std::vector<size_t>(size_t)>& order_of) {
  std::vector<std::string> lines;
  std::istringstream in(ReadTextFile(path));
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) lines.push_back(line);
  }
  const std::vector<size_t> order = order_of(lines.size() - 1);
  std::string csv = lines[0] + "\n";
  for (size_t k = 1; k < lines.size(); ++k) {
    const std::string& mine = lines[k];
    const std::string& other = lines[1 + order[k - 1]];
    csv += mine.substr(0, mine.find(',')) + other.substr(other.find(',')) + "\n";
  }
  WriteTextFileAtomically(out, csv);
  return out.string();
}

void ExpectFailedNamingItems(const RunResult& run, const std::string& output, const std::string& code,
                             const std::string& item_prefix) {
  EXPECT_EQ(run.code, 1) << run.out;
  EXPECT_NE(run.out.find("status=failed"), std::string::npos) << run.out;
  EXPECT_NE(run.err.find("survey failed: " + code), std::string::npos) << run.err;
  const auto report = nlohmann::json::parse(ReadTextFile(std::filesystem::path(output) / "report.json"));
  EXPECT_EQ(report["status"], "failed");
  bool found = false;
  for (const auto& e : report["errors"]) {
    if (e["code"] != code) continue;
    found = true;
    ASSERT_FALSE(e["items"].empty()) << e.dump();
    EXPECT_EQ(e["items"][0].get<std::string>().rfind(item_prefix, 0), 0u) << e.dump();
  }
  EXPECT_TRUE(found) << report["errors"].dump();
}

// GPS that does not belong to the model (positions shuffled among the
// images, as a mixed-up CSV or a wrong registration gives): not a
// clean-looking survey with exit 0, but status failed, the images named,
// exit 1.
TEST_F(AdjustCommand, GpsThatContradictsTheModelFailsTheSurvey) {
  AdjustArgs args = Args("shuffled");
  args.gcp.clear();
  args.gps_csv = ScrambledGpsCsv(args.gps_csv, dir_->path() / "shuffled_gps.csv", [](size_t n) {
    std::vector<size_t> order(n);
    for (size_t k = 0; k < n; ++k) order[k] = k;
    std::mt19937 rng(5);
    std::shuffle(order.begin(), order.end(), rng);
    return order;
  });
  const RunResult run = RunAdjustInProcess(args);
  ExpectFailedNamingItems(run, args.output, "GPS_MOSTLY_INCONSISTENT", "IMG_");
}

// GPS in reverse order: on this lawn-mower block the layout mirrored, which
// a similarity fits only upside down; levelled by the nadir photos, the GPS
// no longer follows the layout. Failed for that, the images named, and the
// check points, 40 m and more off, named too.
TEST_F(AdjustCommand, GpsInReverseOrderFailsTheSurveyAndTheCheckPointsSayIt) {
  AdjustArgs args = Args("reversed");
  args.gcp.clear();
  args.gps_csv = ScrambledGpsCsv(args.gps_csv, dir_->path() / "reversed_gps.csv", [](size_t n) {
    std::vector<size_t> order(n);
    for (size_t k = 0; k < n; ++k) order[k] = n - 1 - k;
    return order;
  });
  const RunResult run = RunAdjustInProcess(args);
  ExpectFailedNamingItems(run, args.output, "GPS_MOSTLY_INCONSISTENT", "IMG_");
  const auto report = nlohmann::json::parse(ReadTextFile(std::filesystem::path(args.output) / "report.json"));
  bool named = false;
  for (const auto& f : report["warnings"]) {
    if (f["code"] == "CHECK_POINTS_FAR") named = f["items"].size() == 6;
  }
  EXPECT_TRUE(named) << report["warnings"].dump();
}

// The clean simulation passes every gate.
TEST_F(AdjustCommand, ACleanSurveyIsOk) {
  const AdjustArgs args = Args("clean");
  const RunResult run = RunAdjustInProcess(args);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(ReadTextFile(std::filesystem::path(args.output) / "report.json"));
  EXPECT_EQ(report["status"], "ok") << report["warnings"].dump() << report["errors"].dump();
  EXPECT_TRUE(report["errors"].empty());
  EXPECT_NE(run.out.find("status=ok"), std::string::npos);
}

// A classic aerial triangulation: the same survey from its tie measurements
// and a certificate in millimetres (the simulated camera's 800 px focal
// length as 6.4 mm at 8 um pixels): the check points of the model's own
// adjustment, and the calibration stated in mm with the certificate's pitch.
TEST_F(AdjustCommand, MeasurementsAndAMillimetreCertificateGiveTheModelsAdjustment) {
  const auto sim = dir_->path() / "sim";
  const auto certificate = dir_->path() / "camera_mm.txt";
  WriteTextFileAtomically(certificate, "units mm\npixel_size_mm 0.008\nwidth 1000\nheight 750\nf 6.4\n");
  AdjustArgs from_model = Args("from_model");
  from_model.policy.camera_file = certificate.string();
  AdjustArgs from_measurements = Args("from_measurements");
  from_measurements.model_dir.clear();
  from_measurements.measurements = (sim / "measurements.txt").string();
  from_measurements.policy.camera_file = certificate.string();
  const RunResult a = RunAdjustInProcess(from_model);
  const RunResult b = RunAdjustInProcess(from_measurements);
  ASSERT_EQ(a.code, 0) << a.err;
  ASSERT_EQ(b.code, 0) << b.err;
  const auto ra = nlohmann::json::parse(ReadTextFile(std::filesystem::path(from_model.output) / "report.json"));
  const auto rb =
      nlohmann::json::parse(ReadTextFile(std::filesystem::path(from_measurements.output) / "report.json"));
  ASSERT_TRUE(rb.contains("initial_orientation"));
  EXPECT_FALSE(ra.contains("initial_orientation"));
  EXPECT_EQ(rb["initial_orientation"]["images_oriented"], rb["initial_orientation"]["images_measured"]);
  const auto& pa = ra["check_points"]["points"];
  const auto& pb = rb["check_points"]["points"];
  ASSERT_EQ(pa.size(), pb.size());
  for (size_t k = 0; k < pa.size(); ++k) {
    for (const char* axis : {"dx_m", "dy_m", "dz_m"}) {
      // measurements.txt leaves out the few marks the simulated noise pushed
      // off the image: 0.1-0.2 mm apart (the library test, same marks: 3e-6 m).
      EXPECT_NEAR(pa[k][axis].get<double>(), pb[k][axis].get<double>(), 5e-4) << pa[k]["name"] << " " << axis;
    }
  }
  for (const auto* r : {&ra, &rb}) {
    const auto& mm = (*r)["adjustment"]["intrinsics"][0]["mm"];
    EXPECT_EQ(mm["pixel_size_mm"].get<double>(), 0.008);
    EXPECT_EQ(mm["pixel_size_source"], "the camera file");
    EXPECT_NEAR(mm["c_mm"].get<double>(), 6.4, 0.05);  // refined from the start value
  }
}

}  // namespace
}  // namespace aerotri
