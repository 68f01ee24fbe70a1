// SPDX-License-Identifier: BSD-3-Clause
// A rendered survey whose EXIF altitudes drift by 100 m over the flight
// (a consumer drone's barometric drift), through the whole pipeline with
// GPS only: the GPS alone would tilt the block by tens of degrees; the
// adjusted cameras stay within 1 degree of their true attitude and the drift
// is recovered within its sigma (issue 17).
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

TEST(GpsDrift, RenderedSurveyWithDriftingAltitudeKeepsItsAttitude) {
  testing::TempDir dir;
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
  sim.georef.seed = 11;
  sim.georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, 100.0);
  const fs::path survey = dir.path() / "survey";
  WriteSyntheticSurvey(sim, survey);

  PipelineOptions o;
  o.images_dir = survey / "images";
  o.workspace = dir.path() / "ws";
  o.georef.leave_one_out = false;
  o.log = [](const std::string&) {};
  ASSERT_NE(RunPipeline(o), "failed");
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const auto truth = nlohmann::json::parse(ReadTextFile(survey / "truth" / "truth.json"));
  const auto& drift = report["gps_drift"];
  SCOPED_TRACE(drift.dump(1));

  EXPECT_GT(drift["gps_fit_tilt_deg"].get<double>(), 10.0);
  ASSERT_TRUE(drift["estimated"].get<bool>());
  EXPECT_TRUE(drift["attitude_prior"].get<bool>());
  EXPECT_TRUE(drift["axes"]["u"].get<bool>());
  ASSERT_EQ(drift["flights"].size(), 1u);
  const double true_rate = truth["gps_drift_m_per_s"][2];
  const double rate = drift["flights"][0]["rate_m_per_s"]["u_m"];
  const double sigma = drift["flights"][0]["rate_sigma_m_per_s"]["u_m"];
  ASSERT_GT(sigma, 0.0);
  EXPECT_LT(std::abs(rate - true_rate), 3.0 * sigma);
  EXPECT_LT(sigma, 0.05 * true_rate);

  // Every adjusted camera within 1 degree of its true attitude.
  const SparseModel adjusted = ReadColmapText(o.workspace / "georeferenced");
  const SparseModel exact = ReadColmapText(survey / "truth" / "model");
  std::map<std::string, Eigen::Quaterniond> true_rotation;
  for (const Image& image : exact.images) true_rotation[image.name] = image.pose.cam_from_world;
  int compared = 0;
  double worst = 0.0;
  for (const Image& image : adjusted.images) {
    if (!image.registered || !true_rotation.count(image.name)) continue;
    const Eigen::AngleAxisd d(image.pose.cam_from_world * true_rotation[image.name].conjugate());
    worst = std::max(worst, d.angle() * 180.0 / M_PI);
    ++compared;
  }
  EXPECT_GE(compared, static_cast<int>(exact.images.size()) - 2);
  EXPECT_LT(worst, 1.0);
  EXPECT_LT(report["adjustment"]["attitude"]["mean_axis_tilt_deg"].get<double>(), 1.0);
}

}  // namespace
}  // namespace aerotri
