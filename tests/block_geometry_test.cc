// SPDX-License-Identifier: BSD-3-Clause
// Block geometry, the dome test and the refinement policy on synthetic blocks
// with known truth (46.5 N, 7.5 E; 4000 x 3000 px, f 3000 px, 80 m flying
// height: GSD 2.7 cm).
#include "libphoto/survey/block_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "libphoto/survey/georeferencing.h"
#include "libphoto/survey/gnss_drift.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

SyntheticSurveyOptions Block(std::uint32_t seed, double relief_m, double attitude_deg) {
  SyntheticSurveyOptions o;
  o.seed = seed;
  o.area_width_m = 200.0;
  o.area_height_m = 150.0;
  o.num_tie_points = 1500;
  o.relief_m = relief_m;
  o.attitude_sigma_deg = attitude_deg;
  return o;
}

// Georeferencing as the policy tests run it, with an EXIF focal prior.
GeoreferenceOptions PolicyOptions(double exif_focal_px) {
  GeoreferenceOptions options;
  options.output_crs = "EPSG:32632";
  options.bundle.loss = LossType::kHuber;
  options.bundle.loss_scale_px = 2.0;
  options.bundle.focal_prior_px = {exif_focal_px};
  return options;
}

bool HasFinding(const GeoreferenceReport& r, const std::string& code) {
  for (const Finding& f : r.findings) {
    if (f.code == code) return true;
  }
  return false;
}

TEST(BlockGeometry, TellsAFlatNadirBlockFromOneWithRelief) {
  const SyntheticSurvey flat = MakeSyntheticSurvey(Block(1, 0.0, 0.3));
  const BlockGeometry g = MeasureBlockGeometry(flat.truth);
  EXPECT_TRUE(g.nadir_flat_single_altitude);
  EXPECT_LT(g.relief_ratio, 0.02);
  EXPECT_LT(g.roughness_ratio, 0.2 * kPlanarRoughnessRatio);
  EXPECT_LT(g.tilt_p90_deg, 2.0);
  // 80 m above mean ground with a 3000 px focal length.
  EXPECT_NEAR(g.median_depth_m, 80.0, 2.0);
  EXPECT_NEAR(g.gsd_m, 80.0 / 3000.0, 0.002);

  const SyntheticSurvey hilly = MakeSyntheticSurvey(Block(1, 40.0, 0.3));
  const BlockGeometry h = MeasureBlockGeometry(hilly.truth);
  EXPECT_GT(h.relief_ratio, 0.05);
  EXPECT_GT(h.roughness_ratio, 2.0 * kPlanarRoughnessRatio);
  EXPECT_FALSE(h.nadir_flat_single_altitude);

  // Flat ground under cameras tilted up to 8 degrees: the depths spread
  // across each photo as over relief (relief_ratio), yet lie on a plane
  // (roughness_ratio): still a flat block.
  const SyntheticSurvey tilted = MakeSyntheticSurvey(Block(1, 0.0, 4.0));
  const BlockGeometry t = MeasureBlockGeometry(tilted.truth);
  EXPECT_GT(t.relief_ratio, g.relief_ratio + 0.01);
  EXPECT_LT(t.roughness_ratio, 0.2 * kPlanarRoughnessRatio);
  EXPECT_TRUE(t.nadir_flat_single_altitude);
}

// dz = a + amplitude r² / R² plus noise: the fit recovers the amplitude
// within 3 of its own sigmas, and that sigma is consistent with the noise.
// The block's vertical from its own geometry (gnss_drift.h), in an
// arbitrary frame: a nadir grid is nadir whatever the frame; one line of
// cameras (a strip, or a walk past a facade) is not taken for one; nor is a
// grid of photos all tilted 35 degrees one way.
TEST(ViewingGeometry, NadirGridYesOneLineNoObliqueNo) {
  const Eigen::Quaterniond frame(Eigen::AngleAxisd(1.3, Eigen::Vector3d(0.3, -0.8, 0.5).normalized()));
  auto block = [&](int rows, double tilt_deg) {
    SparseModel model;
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < 8; ++c) {
        Image image;
        image.registered = true;
        // Looking down (-z), tilted about the x axis, jittered by ~1 degree.
        const double jitter = 0.017 * std::sin(3.0 * c + r);
        const Eigen::Quaterniond world_from_cam =
            Eigen::AngleAxisd(tilt_deg * M_PI / 180.0 + jitter, Eigen::Vector3d::UnitX()) *
            Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
        image.pose.cam_from_world = (frame * world_from_cam).conjugate();
        image.pose.centre_in_world = frame * Eigen::Vector3d(20.0 * c, 25.0 * r, 80.0 + 0.3 * std::cos(c + r));
        model.images.push_back(image);
      }
    }
    return model;
  };
  const ViewingGeometry grid = MeasureViewingGeometry(block(4, 0.0));
  EXPECT_TRUE(grid.nadir) << grid.reason;
  EXPECT_LT(grid.axis_to_flight_plane_normal_deg, 2.0);
  const ViewingGeometry line = MeasureViewingGeometry(block(1, 0.0));
  EXPECT_FALSE(line.nadir) << line.reason;
  EXPECT_FALSE(line.plane_measured);
  const ViewingGeometry oblique = MeasureViewingGeometry(block(4, 35.0));
  EXPECT_FALSE(oblique.nadir) << oblique.reason;
  EXPECT_NEAR(oblique.axis_to_flight_plane_normal_deg, 35.0, 2.0);
}

// A camera's attitude as a gimbal states it: the optical axis's elevation and
// the heading of the image's top, in ENU.
TEST(GimbalAttitude, ElevationAndHeadingOfTheImagesTop) {
  const auto pose_from = [](const Eigen::Vector3d& axis, const Eigen::Vector3d& top) {
    // Rows of R (cam_from_world): the camera's x (right), y (down), z (axis) in the world.
    const Eigen::Vector3d z = axis.normalized();
    const Eigen::Vector3d y = (-top).normalized();
    Eigen::Matrix3d r;
    r.row(0) = y.cross(z).transpose();
    r.row(1) = y.transpose();
    r.row(2) = z.transpose();
    Pose pose;
    pose.cam_from_world = Eigen::Quaterniond(r);
    return pose;
  };
  const double s = std::sqrt(0.5);
  GimbalAttitude a = AttitudeOf(pose_from({0, 0, -1}, {0, 1, 0}));  // nadir, top north
  EXPECT_NEAR(a.pitch_deg, -90.0, 1e-9);
  EXPECT_NEAR(a.yaw_deg, 0.0, 1e-9);
  a = AttitudeOf(pose_from({0, 0, -1}, {s, s, 0}));  // nadir, top north-east
  EXPECT_NEAR(a.yaw_deg, 45.0, 1e-9);
  // Looking east 30 degrees below the horizon, the top up and east.
  const double c30 = std::cos(30.0 * M_PI / 180.0), s30 = std::sin(30.0 * M_PI / 180.0);
  a = AttitudeOf(pose_from({c30, 0, -s30}, {s30, 0, c30}));
  EXPECT_NEAR(a.pitch_deg, -30.0, 1e-9);
  EXPECT_NEAR(a.yaw_deg, 90.0, 1e-9);
  EXPECT_NEAR((GimbalAxis(a) - Eigen::Vector3d(c30, 0, -s30)).norm(), 0.0, 1e-12);
  // Leaning 10 degrees back, behind a top that points north: pitch -100.
  const double c10 = std::cos(10.0 * M_PI / 180.0), s10 = std::sin(10.0 * M_PI / 180.0);
  a = AttitudeOf(pose_from({0, -s10, -c10}, {0, c10, -s10}));
  EXPECT_NEAR(a.pitch_deg, -100.0, 1e-9);
  EXPECT_NEAR(a.yaw_deg, 0.0, 1e-9);
  EXPECT_NEAR((GimbalAxis(a) - Eigen::Vector3d(0, -s10, -c10)).norm(), 0.0, 1e-12);
}

TEST(GimbalAttitude, ALevelBlockAgreesWithItsGimbalsAndATiltedOneDoesNot) {
  SyntheticSurveyOptions o;
  o.seed = 12;
  o.num_tie_points = 50;
  SparseModel model = MakeSyntheticSurvey(o).truth;  // ENU, nadir with 2 degrees of jitter
  std::mt19937 rng(12);
  std::normal_distribution<double> g(0.0, 0.5);
  std::map<std::string, GimbalAttitude> gimbal;
  for (const Image& image : model.images) {
    GimbalAttitude a = AttitudeOf(image.pose);
    // A gimbal's report: half a degree of noise, and a compass 7 degrees off.
    a.pitch_deg += g(rng);
    a.yaw_deg += 7.0 + g(rng);
    gimbal[image.name] = a;
  }
  GimbalAgreement agreement = CompareWithGimbal(model, gimbal);
  EXPECT_EQ(agreement.images, static_cast<int>(model.images.size()));
  EXPECT_LT(agreement.pitch_median_deg, 1.0);
  EXPECT_GT(agreement.pitch_median_deg, 0.05);
  EXPECT_LT(agreement.block_tilt_deg, 0.5);  // the jitter averages out
  EXPECT_NEAR(agreement.yaw_bias_deg, -7.0, 0.5);
  EXPECT_LT(agreement.yaw_median_deg, 1.0);

  // The same block tilted 20 degrees across its east-west strips (as GPS
  // heights drifting strip by strip would tilt it): the images' tops point
  // north or south, so each photo's pitch shows it, and the block's axis.
  const auto tilted = [&](const Eigen::Vector3d& about) {
    SparseModel m = model;
    const Eigen::Quaterniond tilt(Eigen::AngleAxisd(20.0 * M_PI / 180.0, about));
    for (Image& image : m.images) {
      image.pose.cam_from_world = image.pose.cam_from_world * tilt.conjugate();
      image.pose.centre_in_world = tilt * image.pose.centre_in_world;
    }
    return m;
  };
  agreement = CompareWithGimbal(tilted(Eigen::Vector3d::UnitX()), gimbal);
  EXPECT_NEAR(agreement.pitch_median_deg, 20.0, 2.5);
  EXPECT_NEAR(agreement.block_tilt_deg, 20.0, 0.5);
  EXPECT_FALSE(agreement.pitch_worst_image.empty());
  // Tilted along the strips it is each photo's roll, which a gimbal's pitch
  // and yaw do not state: the block's axis still shows it.
  agreement = CompareWithGimbal(tilted(Eigen::Vector3d::UnitY()), gimbal);
  EXPECT_LT(agreement.pitch_median_deg, 1.5);
  EXPECT_NEAR(agreement.block_tilt_deg, 20.0, 0.5);

  // Images without gimbal angles are not compared.
  EXPECT_EQ(CompareWithGimbal(model, {}).images, 0);
}

TEST(DomeTest, RecoversAnInjectedDomeAndFindsNoneWhereThereIsNone) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  const double radius = 100.0 * std::sqrt(2.0);
  std::vector<Eigen::Vector2d> xy;
  std::vector<double> domed, flat;
  for (int k = 0; k < 40; ++k) {
    xy.emplace_back(u(rng), u(rng));
    const double s = xy.back().squaredNorm() / (radius * radius);
    flat.push_back(0.05 + noise(rng));
    domed.push_back(0.05 - 0.30 * s + noise(rng));
  }
  const DomeTest d = FitDome(xy, domed, Eigen::Vector2d::Zero(), radius, "check points");
  EXPECT_EQ(d.points, 40);
  EXPECT_NEAR(d.amplitude_m, -0.30, 3.0 * d.amplitude_sigma_m);
  EXPECT_GT(d.amplitude_sigma_m, 0.003);  // ~0.02 / sqrt(40) / spread of s
  EXPECT_LT(d.amplitude_sigma_m, 0.03);
  EXPECT_TRUE(d.significant);
  const DomeTest none = FitDome(xy, flat, Eigen::Vector2d::Zero(), radius, "check points");
  EXPECT_NEAR(none.amplitude_m, 0.0, 3.0 * none.amplitude_sigma_m);
  EXPECT_FALSE(none.significant);
  // Too few points: no test.
  const DomeTest few = FitDome({xy.begin(), xy.begin() + 3}, {0, 0, 0}, Eigen::Vector2d::Zero(), radius, "GPS");
  EXPECT_TRUE(few.source.empty());
}

// Student's t against its closed forms (1 degree of freedom: Cauchy,
// P = 1 - 2 atan(t) / pi; 2: P = 1 - t / sqrt(2 + t^2)) and the normal limit.
TEST(DomeTest, CriticalValuesAreStudentsT) {
  EXPECT_NEAR(StudentTCriticalValue(1, kDomeAlpha), std::tan(M_PI / 2 * (1 - kDomeAlpha)), 1e-3);
  const double p = 1 - kDomeAlpha;
  EXPECT_NEAR(StudentTCriticalValue(2, kDomeAlpha), std::sqrt(2 * p * p / (1 - p * p)), 1e-5);
  EXPECT_NEAR(StudentTCriticalValue(2, 0.05), 4.302653, 1e-5);  // the tables' t(0.975, 2)
  EXPECT_NEAR(StudentTCriticalValue(10000, kDomeAlpha), 3.0, 2e-3);
}

// Six check points in a ring near the centre of a wide block (the rendered
// 12 MP survey's): two degrees of freedom left, their scatter of a
// centimetre turns into a 0.4 m "dome" at |t| 4.4, which is no evidence.
TEST(DomeTest, SixPointsAreNotADomeAtTwoDegreesOfFreedom) {
  const std::vector<Eigen::Vector2d> xy = {{47.6, 20.1}, {0.6, 41.5}, {-47.2, 21.9},
                                           {-47.9, -19.1}, {-0.9, -40.5}, {46.8, -20.9}};
  const std::vector<double> dz = {0.0017, 0.0107, -0.0120, -0.0129, 0.0186, -0.0072};
  const DomeTest d = FitDome(xy, dz, Eigen::Vector2d::Zero(), 137.5, "check points");
  EXPECT_EQ(d.points, 6);
  EXPECT_GT(std::abs(d.t), 3.0);  // the old rule's false alarm
  EXPECT_NEAR(d.t_critical, 19.21, 0.01);
  EXPECT_FALSE(d.significant);
}

// A flat nadir block at one altitude with GPS alone does not determine the
// focal length: the policy holds it at the EXIF value and says so; refined
// as asked, it is flagged. The a-priori sigma is what says it.
TEST(RefinementPolicy, HoldsAFocalLengthTheBlockCannotDetermine) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Block(41, 0.0, 0.3), {});
  const double exif_focal = 3000.0 * 1.004;  // an EXIF value 0.4 % off
  const GeoreferenceOptions options = PolicyOptions(exif_focal);

  SparseModel model = scene.tie_model;
  model.cameras[0].params[0] *= 1.01;
  const GeoreferenceReport held = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, options);
  EXPECT_TRUE(held.geometry.nadir_flat_single_altitude);
  EXPECT_TRUE(HasFinding(held, "FOCAL_HELD")) << held.refinement_reason;
  EXPECT_DOUBLE_EQ(model.cameras[0].params[0], exif_focal);
  EXPECT_EQ(held.refined, "cx,cy,k1,k2,k3,p1,p2");

  GeoreferenceOptions asked = options;
  asked.auto_refine = false;
  asked.bundle.refine_intrinsics = IntrinsicsRefinement::kAll;
  SparseModel free_model = scene.tie_model;
  free_model.cameras[0].params[0] *= 1.01;
  const GeoreferenceReport free = GeoreferenceAndAdjust(&free_model, scene.gps, nullptr, &scene.checks, asked);
  EXPECT_TRUE(HasFinding(free, "FOCAL_WEAKLY_DETERMINED"));
  ASSERT_FALSE(free.bundle.intrinsics_precision.empty());
  EXPECT_GT(free.bundle.intrinsics_precision[0].sigmas[0] / 3000.0, 0.01);
}

// Where relief determines f, everything is refined, and the a-priori sigma
// of f is honest: the error is within 4 of them, and the sigma is a fraction
// of a percent, not a rubber stamp.
TEST(RefinementPolicy, RefinesEverythingWhereReliefDeterminesIt) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(Block(42, 30.0, 2.0), {});
  const GeoreferenceOptions options = PolicyOptions(3000.0 * 1.02);
  SparseModel model = scene.tie_model;
  model.cameras[0].params[0] *= 1.02;
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
  EXPECT_EQ(r.refined, "all") << r.refinement_reason;
  EXPECT_FALSE(HasFinding(r, "FOCAL_HELD"));
  ASSERT_EQ(r.bundle.intrinsics_precision.size(), 1u);
  const IntrinsicsPrecision& p = r.bundle.intrinsics_precision[0];
  ASSERT_EQ(p.names[0], "f");
  EXPECT_GT(p.sigmas[0], 0.3);    // px: 0.01 %
  EXPECT_LT(p.sigmas[0], 30.0);   // px: 1 %
  EXPECT_LT(std::abs(model.cameras[0].params[0] - 3000.0), 4.0 * p.sigmas[0]);
  // A correlation matrix: unit diagonal, symmetric.
  for (size_t a = 0; a < p.names.size(); ++a) {
    EXPECT_NEAR(p.correlation[a][a], 1.0, 1e-9);
    for (size_t b = 0; b < p.names.size(); ++b) EXPECT_NEAR(p.correlation[a][b], p.correlation[b][a], 1e-9);
  }
}

}  // namespace
}  // namespace aerotri
