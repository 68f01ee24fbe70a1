// SPDX-License-Identifier: BSD-3-Clause
// The three target kinds rendered by the simulator's own renderer (the
// photos `aerotri simulate` writes), seen from above at varied heading, tilt
// and scale: each found at its true projected centre, and nothing found
// on bare ground.
#include "libphoto/targets/targets.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include <Eigen/Geometry>

#include "libphoto/simulate/render.h"
#include "libphoto/simulate/synthetic_survey.h"

namespace aerotri {
namespace {

constexpr double kRelief = 6.0;

struct View {
  Camera camera;
  Pose pose;
  Eigen::Vector2d truth;
};

// A 320 x 240 Brown camera above the target at (e, n), looking down with the
// given heading and tilt, at a height that gives `gsd` metres per pixel.
View LookAt(const Eigen::Vector2d& en, double gsd, double heading_deg, double tilt_deg, const Eigen::Vector2d& shift_px) {
  View v;
  const double f = 1500.0;  // a 320 x 240 window of a 12 MP drone photo
  v.camera = Camera::Create(CameraModelId::kBrown, f, 320, 240);
  v.camera.params[3] = -0.05;  // k1: a little barrel distortion
  const Eigen::Vector3d ground(en.x(), en.y(), TerrainHeight(en.x(), en.y(), kRelief));
  const double height = gsd * f;
  // Nadir: camera x east, y south, z down; then heading about the vertical
  // and tilt about the camera's x axis.
  Eigen::Matrix3d nadir;
  nadir << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Matrix3d r = Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                            nadir * Eigen::AngleAxisd(heading_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  v.pose.cam_from_world = Eigen::Quaterniond(r);
  // The centre along the optical axis from the target, then moved so the
  // target lands shift_px off the image centre.
  const Eigen::Vector3d axis = r.transpose() * Eigen::Vector3d::UnitZ();
  v.pose.centre_in_world = ground - axis * height / std::abs(axis.z());
  const Eigen::Vector3d off = r.transpose() * Eigen::Vector3d(shift_px.x(), shift_px.y(), 0.0) * (height / f);
  v.pose.centre_in_world -= off;
  v.truth = v.camera.ImageFromCamera(v.pose.CamFromWorld(ground));
  return v;
}

struct Case {
  TargetPattern pattern;
  TargetKind kind;
};

class RenderedTargets : public ::testing::TestWithParam<Case> {};

TEST_P(RenderedTargets, FoundAtTheTrueCentreToATenthOfAPixel) {
  std::mt19937 rng(11);
  // GSD 1.2-3 cm: a 1 m target 33-83 px wide, a cross's bars (15 cm) 5-12 px.
  std::uniform_real_distribution<double> heading(0.0, 360.0), tilt(-8.0, 8.0), gsd(0.012, 0.03), shift(-40.0, 40.0);
  double worst = 0.0, sum = 0.0;
  int found = 0;
  const int trials = 12;
  for (int k = 0; k < trials; ++k) {
    const Eigen::Vector2d en(20.0 * k - 100.0, 7.0 * k);
    const View v = LookAt(en, gsd(rng), heading(rng), tilt(rng), {shift(rng), shift(rng)});
    RenderOptions render;
    render.relief_m = kRelief;
    render.targets = {{en, 1.0, GetParam().pattern}};
    render.seed = 5 + k;
    render.num_threads = 1;
    const cv::Mat image = RenderImage(v.camera, v.pose, render);
    TargetDetectionOptions options;
    options.kinds = {GetParam().kind};
    const std::vector<TargetDetection> d = DetectTargets(image, options);
    ASSERT_FALSE(d.empty()) << "trial " << k;
    // The target, and nothing else in the photo.
    EXPECT_EQ(d.size(), 1u) << "trial " << k << ": a second detection at " << d.back().centre_px.transpose();
    const double error = (d[0].centre_px - v.truth).norm();
    worst = std::max(worst, error);
    sum += error;
    ++found;
    EXPECT_GE(d[0].confidence, 0.5);
  }
  std::printf("%s: %d of %d found, mean error %.3f px, worst %.3f px\n", TargetKindName(GetParam().kind), found, trials,
              sum / found, worst);
  EXPECT_LT(worst, 0.15);
}

// Level and square to the photo's rows (a flight along the target's sides),
// at 2.9-3 cm GSD, where a cross's bars are 5 px: crosses a first detector
// missed (its second bar measured a pixel too thin). A checker's corner
// window carried onto a square's outer corner in a rendered survey
// (marking_test) but not in these views.
TEST_P(RenderedTargets, FoundSquareToTheRowsAtTheThinnestBars) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> turn(-1.5, 1.5), gsd(0.029, 0.030), shift(-40.0, 40.0);
  double worst = 0.0;
  const int trials = 8;
  for (int k = 0; k < trials; ++k) {
    const Eigen::Vector2d en(15.0 * k - 60.0, -9.0 * k);
    const View v = LookAt(en, gsd(rng), 90.0 * (k % 4) + turn(rng), 0.0, {shift(rng), shift(rng)});
    RenderOptions render;
    render.relief_m = kRelief;
    render.targets = {{en, 1.0, GetParam().pattern}};
    render.seed = 40 + k;
    render.num_threads = 1;
    TargetDetectionOptions options;
    options.kinds = {GetParam().kind};
    const std::vector<TargetDetection> d = DetectTargets(RenderImage(v.camera, v.pose, render), options);
    ASSERT_EQ(d.size(), 1u) << "trial " << k;
    worst = std::max(worst, (d[0].centre_px - v.truth).norm());
  }
  std::printf("%s, square to the rows: %d of %d found, worst %.3f px\n", TargetKindName(GetParam().kind), trials, trials,
              worst);
  EXPECT_LT(worst, 0.15);
}

INSTANTIATE_TEST_SUITE_P(Kinds, RenderedTargets,
                         ::testing::Values(Case{TargetPattern::kChecker, TargetKind::kChecker},
                                           Case{TargetPattern::kCross, TargetKind::kCross},
                                           Case{TargetPattern::kBullseye, TargetKind::kCircle}),
                         [](const auto& info) { return std::string(TargetKindName(info.param.kind)); });

TEST(RenderedTargets, NothingIsFoundOnBareGround) {
  for (GroundCover cover : {GroundCover::kMixed, GroundCover::kCropRows}) {
    for (int k = 0; k < 4; ++k) {
      const View v = LookAt({35.0 * k, -20.0 * k}, 0.02 + 0.01 * k, 30.0 * k, 0.0, {0, 0});
      RenderOptions render;
      render.relief_m = kRelief;
      render.cover = cover;
      render.num_threads = 1;
      const cv::Mat image = RenderImage(v.camera, v.pose, render);
      const std::vector<TargetDetection> d = DetectTargets(image);
      EXPECT_TRUE(d.empty()) << "cover " << static_cast<int>(cover) << " view " << k << ": "
                             << TargetKindName(d.empty() ? TargetKind::kChecker : d[0].kind) << " at "
                             << (d.empty() ? Eigen::Vector2d::Zero() : d[0].centre_px).transpose() << " confidence "
                             << (d.empty() ? 0.0 : d[0].confidence);
    }
  }
}

// A crop cut narrow by a photo's edge: a saddle a few rows from the cut is
// searched (and found wanting), not an exception from OpenCV's refinement,
// which needs an image 2 half + 5 pixels wide and high (seen when a cross
// target's predicted position fell at a photo's bottom edge).
TEST(RenderedTargets, ACropCutNarrowByAPhotosEdgeIsSearchedNotAnError) {
  for (int rows : {8, 10, 12}) {
    cv::Mat strip(rows, 60, CV_8UC1);
    for (int y = 0; y < rows; ++y) {
      for (int x = 0; x < 60; ++x) strip.at<uint8_t>(y, x) = ((y < rows / 2) == (x < 30)) ? 20 : 230;
    }
    EXPECT_NO_THROW(DetectTargets(strip)) << rows << " rows";
    EXPECT_NO_THROW(DetectTargets(strip.t())) << rows << " columns";
  }
}

TEST(TargetKinds, NamesRoundTrip) {
  for (TargetKind k : {TargetKind::kChecker, TargetKind::kCross, TargetKind::kCircle}) {
    EXPECT_EQ(TargetKindFromName(TargetKindName(k)), k);
  }
  EXPECT_FALSE(TargetKindFromName("square").has_value());
}

}  // namespace
}  // namespace aerotri
