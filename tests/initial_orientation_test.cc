// SPDX-License-Identifier: BSD-3-Clause
// A classic aerial triangulation from image measurements alone: space
// resection and forward intersection must start the bundle close enough that
// it ends where an adjustment of the reconstruction ends, and whatever cannot
// be oriented is named.
#include "libphoto/survey/initial_orientation.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>

#include "libphoto/adjust/camera_file.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

SyntheticSurveyOptions Survey(std::uint32_t seed, int control) {
  SyntheticSurveyOptions o;
  o.seed = seed;
  o.area_width_m = 200.0;
  o.area_height_m = 150.0;
  o.num_tie_points = 1200;
  o.pixel_noise_px = 0.3;
  o.num_control_points = control;
  o.num_check_points = 6;
  return o;
}

// The reconstruction's observations written as a measurement file would
// hold them.
TiePointFile TiesOf(const SparseModel& model) {
  TiePointFile file;
  file.path = "ties.txt";
  for (const Observation& obs : model.observations) {
    TieMeasurement m;
    m.image = model.images[obs.image].name;
    m.point = "t" + std::to_string(model.points[obs.point].id);
    m.xy_px = obs.xy;
    file.measurements.push_back(m);
  }
  return file;
}

GeoreferenceOptions Options() {
  GeoreferenceOptions o;
  o.output_crs = "EPSG:32632";
  o.gcp_sigma_h_m = 0.01;
  o.gcp_sigma_v_m = 0.01;
  o.bundle.loss = LossType::kHuber;
  o.bundle.loss_scale_px = 2.0;
  o.posterior_precision = false;
  return o;
}

// The largest difference between two adjustments' check points and camera
// centres (output CRS metres).
void ExpectSameAdjustment(const GeoreferenceReport& a, const GeoreferenceReport& b, double check_m,
                          double camera_m) {
  ASSERT_EQ(a.check.size(), b.check.size());
  double worst_check = 0.0;
  for (size_t k = 0; k < a.check.size(); ++k) {
    ASSERT_EQ(a.check[k].name, b.check[k].name);
    ASSERT_TRUE(a.check[k].solved && b.check[k].solved) << a.check[k].name;
    worst_check = std::max(worst_check, (a.check[k].adjusted_crs - b.check[k].adjusted_crs).cwiseAbs().maxCoeff());
  }
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  double worst_camera = 0.0;
  for (size_t k = 0; k < a.cameras.size(); ++k) {
    ASSERT_EQ(a.cameras[k].name, b.cameras[k].name);
    worst_camera =
        std::max(worst_camera, (a.cameras[k].position_crs - b.cameras[k].position_crs).cwiseAbs().maxCoeff());
  }
  std::printf("from measurements vs from the model: check points %.2e m, cameras %.2e m at most\n", worst_check,
              worst_camera);
  EXPECT_LT(worst_check, check_m);
  EXPECT_LT(worst_camera, camera_m);
}

// Dense control (every image sees four or more): the block starts by space
// resection in the control's frame, grows by intersection, and the bundle
// ends where the reconstruction's own adjustment ends.
TEST(InitialOrientation, ResectionOnControlThenIntersectionReachesTheSameAdjustment) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Survey(31, 40), {});
  const Camera& camera = scene.tie_model.cameras[0];
  InitialOrientationReport report;
  SparseModel model = OrientFromMeasurements(camera, TiesOf(scene.tie_model), &scene.control, {}, {}, &report);
  std::printf("seed: %s; %d of %zu images, %d of %d tie points, %d rounds\n", report.seed.c_str(), report.oriented,
              report.images.size(), report.tie_points_intersected, report.tie_points, report.rounds);
  EXPECT_TRUE(report.control_frame);
  EXPECT_EQ(report.oriented, static_cast<int>(scene.tie_model.images.size()));
  EXPECT_EQ(report.tie_points_intersected, static_cast<int>(scene.tie_model.points.size()));
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  int by_control = 0;
  for (const ImageOrientationResult& r : report.images) by_control += r.how.find("control") != std::string::npos;
  EXPECT_GT(by_control, 0);

  // The initial orientation alone is already close to the truth (ENU at the
  // first control point: compare shapes).
  std::vector<Eigen::Vector3d> initial, truth;
  for (size_t k = 0; k < model.images.size(); ++k) {
    ASSERT_EQ(model.images[k].name, scene.survey.truth.images[k].name);
    initial.push_back(model.images[k].pose.centre_in_world);
    truth.push_back(scene.survey.truth.images[k].pose.centre_in_world);
  }
  const double rms = testing::AlignedRms(initial, truth);
  std::printf("initial camera centres against the truth: %.3f m RMS\n", rms);
  EXPECT_LT(rms, 0.5);

  const std::map<std::string, GpsFix> no_gps;
  SparseModel reconstruction = scene.tie_model;
  const GeoreferenceReport a = GeoreferenceAndAdjust(&model, no_gps, &scene.control, &scene.checks, Options());
  const GeoreferenceReport b =
      GeoreferenceAndAdjust(&reconstruction, no_gps, &scene.control, &scene.checks, Options());
  EXPECT_TRUE(a.bundle.converged) << a.bundle.termination;
  ExpectSameAdjustment(a, b, 1e-4, 1e-3);
  EXPECT_LT(a.check_stats.rmse_3d_m, 0.05);
}

// GPS only: no image sees four control points, so the block starts from the
// pair sharing most points, scaled by GPS, and the GPS similarity of the
// adjustment brings it to the datum.
TEST(InitialOrientation, WithoutControlARelativePairSeedsAGpsBlock) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Survey(32, 8), {});
  const Camera& camera = scene.tie_model.cameras[0];
  InitialOrientationReport report;
  SparseModel model = OrientFromMeasurements(camera, TiesOf(scene.tie_model), nullptr, scene.gps, {}, &report);
  std::printf("seed: %s; %d of %zu images, %d of %d tie points\n", report.seed.c_str(), report.oriented,
              report.images.size(), report.tie_points_intersected, report.tie_points);
  EXPECT_FALSE(report.control_frame);
  EXPECT_NE(report.seed.find("relative orientation"), std::string::npos);
  EXPECT_NE(report.seed.find("scaled by GPS"), std::string::npos);
  EXPECT_EQ(report.oriented, static_cast<int>(scene.tie_model.images.size()));

  SparseModel reconstruction = scene.tie_model;
  const GeoreferenceReport a = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  const GeoreferenceReport b =
      GeoreferenceAndAdjust(&reconstruction, scene.gps, &scene.control, &scene.checks, Options());
  EXPECT_TRUE(a.bundle.converged) << a.bundle.termination;
  ExpectSameAdjustment(a, b, 1e-4, 1e-3);
}

// Blundered marks (2 % of them, 20-50 px off): their points are still
// intersected from the rays that agree, the marks are set aside and the
// adjustment rejects them, every one counted, and the check points are as
// good as without them.
TEST(InitialOrientation, BlunderedMarksAreSetAsideAndRejectedByTheAdjustment) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Survey(35, 8), {});
  const Camera& camera = scene.tie_model.cameras[0];
  TiePointFile ties = TiesOf(scene.tie_model);
  std::mt19937 rng(35);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int injected = 0;
  for (TieMeasurement& m : ties.measurements) {
    if (u(rng) >= 0.02) continue;
    const double d = 20.0 + 30.0 * u(rng);
    m.xy_px.x() += m.xy_px.x() + d < camera.width - 1 ? d : -d;
    ++injected;
  }
  InitialOrientationReport report;
  SparseModel model = OrientFromMeasurements(camera, ties, &scene.control, scene.gps, {}, &report);
  std::printf("%d blunders: %d marks set aside, %d of %d tie points intersected\n", injected, report.suspect_marks,
              report.tie_points_intersected, report.tie_points);
  EXPECT_EQ(report.oriented, static_cast<int>(scene.tie_model.images.size()));
  EXPECT_GE(report.tie_points_intersected, report.tie_points * 99 / 100);
  EXPECT_GE(report.suspect_marks, injected * 9 / 10);
  EXPECT_LE(report.suspect_marks, injected + injected / 10);

  SparseModel clean = scene.tie_model;
  const GeoreferenceReport a = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  const GeoreferenceReport b = GeoreferenceAndAdjust(&clean, scene.gps, &scene.control, &scene.checks, Options());
  std::printf("outliers removed %d; check RMSE %.4f m (clean %.4f m)\n", a.bundle.outliers_removed,
              a.check_stats.rmse_3d_m, b.check_stats.rmse_3d_m);
  EXPECT_GE(a.bundle.outliers_removed, injected * 95 / 100);
  EXPECT_LE(a.bundle.outliers_removed, injected + injected / 20 + b.bundle.outliers_removed);
  EXPECT_LT(a.check_stats.rmse_3d_m, 1.1 * b.check_stats.rmse_3d_m);
  EXPECT_GT(a.check_stats.rmse_3d_m, 0.9 * b.check_stats.rmse_3d_m);
}

// An image measured on too few points is left out by name, and the rest of
// the block is still oriented.
TEST(InitialOrientation, AnImageWithTooFewPointsIsNamedAndLeftOut) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Survey(33, 8), {});
  TiePointFile ties = TiesOf(scene.tie_model);
  const std::string starved = scene.tie_model.images[5].name;
  int kept = 0;
  std::vector<TieMeasurement> measurements;
  for (const TieMeasurement& m : ties.measurements) {
    if (m.image == starved && kept++ >= 3) continue;
    measurements.push_back(m);
  }
  ties.measurements = measurements;
  GcpFile control = scene.control;
  for (GroundPoint& g : control.points) {
    std::vector<GcpMeasurement> marks;
    for (const GcpMeasurement& m : g.measurements) {
      if (m.image != starved) marks.push_back(m);
    }
    g.measurements = marks;
  }
  InitialOrientationReport report;
  const SparseModel model =
      OrientFromMeasurements(scene.tie_model.cameras[0], ties, &control, scene.gps, {}, &report);
  EXPECT_EQ(report.oriented, static_cast<int>(scene.tie_model.images.size()) - 1);
  ASSERT_FALSE(report.warnings.empty());
  EXPECT_NE(report.warnings.front().find("image " + starved + " left out"), std::string::npos)
      << report.warnings.front();
  EXPECT_NE(report.warnings.front().find("3 known point(s), 4 needed"), std::string::npos) << report.warnings.front();
  for (const Image& image : model.images) EXPECT_NE(image.name, starved);
}

// Nothing to start from: one image, no control.
TEST(InitialOrientation, NothingToStartFromIsAnErrorThatSaysWhy) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Survey(34, 8), {});
  TiePointFile ties = TiesOf(scene.tie_model);
  std::vector<TieMeasurement> one_image;
  for (const TieMeasurement& m : ties.measurements) {
    if (m.image == scene.tie_model.images[0].name) one_image.push_back(m);
  }
  ties.measurements = one_image;
  InitialOrientationReport report;
  try {
    OrientFromMeasurements(scene.tie_model.cameras[0], ties, nullptr, {}, {}, &report);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("no image sees 4 or more control points"), std::string::npos) << e.what();
  }
}

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(TiePointFile, ReadsMeasurementsInEitherPixelConvention) {
  testing::TempDir dir;
  WriteFile(dir / "ties.txt", "# image point x y\nA.JPG p1 10.25 20.5\n\nB.JPG p1 +30 40 sigma_px=0.5\n");
  const TiePointFile centre = ReadTiePointFile(dir / "ties.txt", PixelOrigin::kCentre);
  ASSERT_EQ(centre.measurements.size(), 2u);
  EXPECT_EQ(centre.measurements[0].image, "A.JPG");
  EXPECT_EQ(centre.measurements[0].point, "p1");
  EXPECT_EQ(centre.measurements[0].xy_px, Eigen::Vector2d(10.25, 20.5));
  EXPECT_EQ(centre.measurements[0].line, 2);
  EXPECT_FALSE(centre.measurements[0].sigma_px);
  EXPECT_EQ(centre.measurements[1].sigma_px.value_or(0.0), 0.5);
  const TiePointFile corner = ReadTiePointFile(dir / "ties.txt", PixelOrigin::kCorner);
  EXPECT_EQ(corner.measurements[1].xy_px, Eigen::Vector2d(29.5, 39.5));
}

TEST(TiePointFile, ErrorsNameTheFileLineAndValue) {
  testing::TempDir dir;
  const auto error = [&](const std::string& text) {
    WriteFile(dir / "t.txt", text);
    try {
      ReadTiePointFile(dir / "t.txt");
    } catch (const ParseError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("A p 1 2\nA p 3 4\n").find("t.txt:2: point 'p' is measured twice in image 'A' (also on line 1)"),
            std::string::npos);
  EXPECT_NE(error("A p 1\n").find("t.txt:1: expected 'image_name point_name im_x im_y [sigma_px=S]', got 3"),
            std::string::npos);
  EXPECT_NE(error("A p x 2\n").find("t.txt:1: expected pixel coordinates im_x im_y (columns 3 and 4), got 'x' '2'"),
            std::string::npos);
  EXPECT_NE(error("A p 1 2 sigma_px=-1\n").find("t.txt:1: expected sigma_px=S"), std::string::npos);
  EXPECT_NE(error("A p -3 2\n").find("t.txt:1: expected pixel coordinates >= -0.5"), std::string::npos);
  EXPECT_NE(error("# nothing\n").find("expected tie-point measurements, found none"), std::string::npos);
}

TEST(CameraFileSize, TheCertificateAloneMakesACamera) {
  testing::TempDir dir;
  WriteFile(dir / "cam.txt",
            "units mm\npixel_size_mm 0.006\nwidth 1000\nheight 800\nf 30 fixed\nx0 0.06\ny0 -0.03\nk1 -0.01\n");
  const Camera camera = ReadCameraFile(dir / "cam.txt").ToCamera();
  EXPECT_EQ(camera.model, CameraModelId::kBrown);
  EXPECT_EQ(camera.width, 1000);
  EXPECT_EQ(camera.height, 800);
  EXPECT_DOUBLE_EQ(camera.focal_px(), 5000.0);
  EXPECT_NEAR(camera.principal_point_px().x(), 499.5 + 10.0, 1e-9);
  EXPECT_NEAR(camera.principal_point_px().y(), 399.5 + 5.0, 1e-9);  // y0 is up
  EXPECT_DOUBLE_EQ(camera.params[3], -0.01);

  WriteFile(dir / "nosize.txt", "f 3000\n");
  EXPECT_THROW(ReadCameraFile(dir / "nosize.txt").ToCamera(), InvalidArgument);
  WriteFile(dir / "half.txt", "width 100\nf 3000\n");
  EXPECT_THROW(ReadCameraFile(dir / "half.txt"), ParseError);

  // With a model the size is checked against its camera.
  SparseModel model;
  model.cameras.push_back(Camera::Create(CameraModelId::kBrown, 5000.0, 1200, 800, 1));
  BundleOptions options;
  try {
    ApplyCameraFile(ReadCameraFile(dir / "cam.txt"), &model, &options);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("cam.txt:3: the certificate is for 1000 x 800 px images; camera 1 is "
                                         "1200 x 800 px"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace aerotri
