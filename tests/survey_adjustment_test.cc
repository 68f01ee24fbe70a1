// SPDX-License-Identifier: BSD-3-Clause
// The one georeferencing entry point of run and adjust: control files measure
// full-resolution pixels and must be brought to the model's, input warnings
// come first among the findings, and the camera products are written.
#include "libphoto/pipeline/survey_adjustment.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

#include "libphoto/survey/gnss_drift.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/simulate/survey_writer.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;

class SurveyAdjustment : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    SimulationOptions sim;
    sim.render_images = false;
    sim.survey.seed = 21;
    sim.survey.area_width_m = 120.0;
    sim.survey.area_height_m = 90.0;
    sim.survey.num_tie_points = 600;
    sim.georef.seed = 21;
    WriteSyntheticSurvey(sim, dir_->path());
  }
  static void TearDownTestSuite() { delete dir_; }

  static SurveyAdjustmentInputs Inputs() {
    SurveyAdjustmentInputs inputs;
    inputs.gps = ReadGpsFile(dir_->path() / "gps.csv", AltitudeReference::kEgm96, 3.0, 5.0);
    inputs.gcp = dir_->path() / "gcp_list.txt";
    inputs.checkpoints = dir_->path() / "checkpoints.txt";
    return inputs;
  }
  static SparseModel Model() { return ReadColmapText(dir_->path() / "model"); }

  static testing::TempDir* dir_;
};
testing::TempDir* SurveyAdjustment::dir_ = nullptr;

// The model at half the files' resolution, as the pipeline's working images:
// pixel centres at integers, so x_half = (x + 0.5) / 2 - 0.5.
SparseModel AtHalfResolution(SparseModel model) {
  const auto half = [](double x) { return (x + 0.5) / 2.0 - 0.5; };
  for (Camera& camera : model.cameras) {
    camera.width /= 2;
    camera.height /= 2;
    const CameraModelInfo& info = camera.info();
    for (int k : info.focal_params) camera.params[k] /= 2.0;
    for (int k : info.principal_point_params) camera.params[k] = half(camera.params[k]);
  }
  for (Observation& obs : model.observations) obs.xy = {half(obs.xy.x()), half(obs.xy.y())};
  return model;
}

TEST_F(SurveyAdjustment, ControlMarksAreBroughtToTheModelsPixels) {
  SparseModel full = Model();
  const GeoreferenceReport at_full = AdjustSurvey(&full, Inputs(), GeoreferenceOptions());
  ASSERT_EQ(at_full.control_stats.count, 8);
  ASSERT_EQ(at_full.check_stats.count, 6);
  // Marks clicked with 0.3 px noise on a 2 cm GSD: centimetres.
  EXPECT_LT(at_full.check_stats.rmse_3d_m, 0.10);
  EXPECT_GT(at_full.check_stats.rmse_3d_m, 0.002);

  // The same survey at half resolution, told so: the same answer to the
  // marks' noise (half the pixels, each worth twice the ground).
  SurveyAdjustmentInputs inputs = Inputs();
  SparseModel half = AtHalfResolution(Model());
  for (const Image& image : half.images) inputs.full_from_model[image.name] = 2.0;
  const GeoreferenceReport at_half = AdjustSurvey(&half, inputs, GeoreferenceOptions());
  ASSERT_EQ(at_half.check_stats.count, 6);
  EXPECT_LT(at_half.check_stats.rmse_3d_m, 2.0 * at_full.check_stats.rmse_3d_m + 0.01);
  EXPECT_LT(at_half.control_stats.rmse_3d_m, 2.0 * at_full.control_stats.rmse_3d_m + 0.01);

  // Not told: every mark lands twice as far from the image corner, and the
  // control no longer fits.
  SparseModel untold = AtHalfResolution(Model());
  const GeoreferenceReport wrong = AdjustSurvey(&untold, Inputs(), GeoreferenceOptions());
  EXPECT_GT(wrong.check_stats.rmse_3d_m, 10.0 * at_half.check_stats.rmse_3d_m);
}

TEST_F(SurveyAdjustment, InputWarningsComeFirstAndTheCameraProductsAreWritten) {
  SparseModel model = Model();
  SurveyAdjustmentInputs inputs = Inputs();
  inputs.input_warnings = {"first problem", "second problem"};
  const GeoreferenceReport report = AdjustSurvey(&model, inputs, GeoreferenceOptions());
  ASSERT_GE(report.findings.size(), 2u);
  EXPECT_EQ(report.findings[0].code, "INPUT");
  EXPECT_EQ(report.findings[0].message, "first problem");
  EXPECT_EQ(report.findings[1].message, "second problem");

  testing::TempDir out;
  WriteCameraProducts(report, model, out.path());
  for (const char* name : {"cameras.csv", "exterior_orientation.csv", "cameras.gpkg", "tie_points.csv"}) {
    EXPECT_TRUE(fs::exists(out.path() / name)) << name;
  }
  std::ifstream csv(out.path() / "cameras.csv");
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  // A 2D EPSG code without a geoid: the heights are ellipsoidal, and say so.
  EXPECT_EQ(header.rfind("name,x,y,z_", 0), 0u) << header;
  EXPECT_NE(header.find(",lat_deg,lon_deg,h_ellipsoidal_m,gps_de_m,gps_dn_m,gps_du_m"), std::string::npos);
  // The first camera's easting matches the report's.
  const std::string x = first.substr(first.find(',') + 1);
  EXPECT_NEAR(std::stod(x), report.cameras.front().position_crs.x(), 1e-3);
}

TEST_F(SurveyAdjustment, AdjustedAttitudesAreCheckedAgainstTheGimbals) {
  // Gimbal angles from the truth with half a degree of noise: a level block
  // agrees and nothing is said.
  const SparseModel truth = ReadColmapText(dir_->path() / "truth" / "model");
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 0.5);
  SurveyAdjustmentInputs inputs = Inputs();
  for (const Image& image : truth.images) {
    GimbalAttitude a = AttitudeOf(image.pose);
    a.pitch_deg += g(rng);
    a.yaw_deg += g(rng);
    inputs.gimbal[image.name] = a;
  }
  SparseModel model = Model();
  GeoreferenceReport report = AdjustSurvey(&model, inputs, GeoreferenceOptions());
  EXPECT_EQ(report.gimbal.images, static_cast<int>(truth.images.size()));
  EXPECT_LT(report.gimbal.pitch_median_deg, 1.0);
  EXPECT_LT(report.gimbal.yaw_median_deg, 1.5);
  for (const Finding& f : report.findings) EXPECT_NE(f.code, "GIMBAL_ATTITUDE_DISAGREES") << f.message;

  // Gimbals that say the whole block looks 15 degrees further north than the
  // adjustment has it (tilted across the east-west strips, as GPS heights
  // drifting strip by strip would tilt it): a contradiction, and an error.
  // (The images' tops point north or south: the tilt is their gimbals' pitch.)
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(15.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()));
  for (const Image& image : truth.images) {
    Pose tilted = image.pose;
    tilted.cam_from_world = image.pose.cam_from_world * tilt.conjugate();
    inputs.gimbal[image.name] = AttitudeOf(tilted);
  }
  model = Model();
  report = AdjustSurvey(&model, inputs, GeoreferenceOptions());
  EXPECT_NEAR(report.gimbal.pitch_median_deg, 15.0, 2.0);
  EXPECT_NEAR(report.gimbal.block_tilt_deg, 15.0, 1.0);
  bool error = false;
  for (const Finding& f : report.findings) {
    error |= f.code == "GIMBAL_ATTITUDE_DISAGREES" && f.severity == Severity::kError;
  }
  EXPECT_TRUE(error);
  EXPECT_EQ(SurveyStatus(report.findings), "failed");
}

TEST_F(SurveyAdjustment, AControlFileInAnUnknownCrsIsRefusedBeforeAnyAdjustment) {
  testing::TempDir dir;
  const fs::path bad = dir.path() / "gcp.txt";
  std::ofstream(bad) << "EPSG:999999\n500000 5000000 100 10 10 IMG_0001.JPG gcp1\n";
  SparseModel model = Model();
  const SparseModel before = model;
  SurveyAdjustmentInputs inputs = Inputs();
  inputs.gcp = bad;
  try {
    AdjustSurvey(&model, inputs, GeoreferenceOptions());
    FAIL() << "accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("gcp.txt"), std::string::npos) << e.what();
  }
  EXPECT_EQ(model.images[0].pose.centre_in_world, before.images[0].pose.centre_in_world);
}

// tie_points.csv: the adjusted tie points in the output CRS, their errors
// against the truth consistent with their posterior sigmas (noise and
// sigmas matching: 0.3 px marks, the GPS and control as simulated).
TEST(TiePointsCsv, PointsInTheCrsWithSigmasThatMatchTheirErrors) {
  SyntheticSurveyOptions so;
  so.seed = 22;
  so.area_width_m = 200.0;
  so.area_height_m = 150.0;
  so.num_tie_points = 800;
  so.pixel_noise_px = 0.3;
  SyntheticGeorefOptions go;
  go.seed = 22;
  const SyntheticGeoref scene = MakeSyntheticGeoref(so, go);
  GeoreferenceOptions options;
  options.output_crs = "EPSG:32632";
  options.gcp_sigma_h_m = go.gcp_noise_m;
  options.gcp_sigma_v_m = go.gcp_noise_m;
  options.bundle.loss = LossType::kNone;
  options.bundle.outlier_threshold_px = 0.0;
  options.bundle.observation_sigma_px = 0.3;
  SparseModel model = scene.tie_model;
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, nullptr, options);
  testing::TempDir out;
  WriteTiePointsCsv(report, model, out / "tie_points.csv");

  std::map<int, Eigen::Vector3d> truth;
  const LocalFrame truth_frame(go.origin);
  const Crs utm = Crs::FromString("EPSG:32632");
  for (const Point& p : scene.survey.truth.points) {
    if (p.role == PointRole::kTie) truth[p.id] = utm.FromGeodetic(truth_frame.GeodeticFromEnu(p.position));
  }
  std::ifstream in(out / "tie_points.csv");
  std::string line;
  int rows = 0, with_sigma = 0;
  Eigen::Vector3d sum_z2 = Eigen::Vector3d::Zero();
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("id,", 0) == 0) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    ASSERT_GE(f.size(), 6u) << line;
    ++rows;
    if (f.size() < 9 || f[6].empty()) continue;
    const auto it = truth.find(std::stoi(f[0]));
    ASSERT_NE(it, truth.end()) << line;
    const Eigen::Vector3d xyz(std::stod(f[2]), std::stod(f[3]), std::stod(f[4]));
    const Eigen::Vector3d sigma(std::stod(f[6]), std::stod(f[7]), std::stod(f[8]));
    sum_z2 += (xyz - it->second).cwiseQuotient(sigma).cwiseAbs2();
    ++with_sigma;
  }
  int expected = 0;
  const std::vector<int> views = model.ObservationsPerPoint();
  for (size_t k = 0; k < model.points.size(); ++k) expected += model.points[k].role == PointRole::kTie && views[k] >= 2;
  EXPECT_EQ(rows, expected);
  ASSERT_EQ(with_sigma, rows);
  const Eigen::Vector3d rms = (sum_z2 / with_sigma).cwiseSqrt();
  std::printf("tie points: %d; errors / posterior sigma RMS: x %.2f y %.2f z %.2f\n", rows, rms.x(), rms.y(), rms.z());
  for (int a = 0; a < 3; ++a) {
    EXPECT_GT(rms[a], 0.7) << "axis " << a;
    EXPECT_LT(rms[a], 1.4) << "axis " << a;
  }
}

}  // namespace
}  // namespace aerotri
