// SPDX-License-Identifier: BSD-3-Clause
// Structure from motion on its own: tracks from matches, and the incremental
// mapper on features whose correspondences and truth are known, so that
// nothing of feature extraction or matching is under test here.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <random>
#include <set>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/geometry/pose_estimation.h"
#include "libphoto/sfm/guided_matching.h"
#include "libphoto/sfm/incremental_mapper.h"
#include "georef/similarity.h"
#include "libphoto/sfm/tracks.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

TEST(Tracks, MatchesJoinIntoTracksAcrossImages) {
  // 0:0 - 1:0 - 2:5 is one track; 0:1 - 1:1 another; 1:2 stands alone.
  std::vector<PairMatches> matches(2);
  matches[0].i = 0;
  matches[0].j = 1;
  matches[0].inliers = {{0, 0}, {1, 1}};
  matches[1].i = 1;
  matches[1].j = 2;
  matches[1].inliers = {{0, 5}};
  const Tracks t = BuildTracks({3, 3, 6}, matches);
  ASSERT_EQ(t.tracks.size(), 2u);
  EXPECT_EQ(t.dropped_inconsistent, 0);
  const int a = t.track_of[0][0];
  ASSERT_GE(a, 0);
  EXPECT_EQ(t.track_of[1][0], a);
  EXPECT_EQ(t.track_of[2][5], a);
  EXPECT_EQ(t.tracks[a].size(), 3u);
  EXPECT_EQ(t.track_of[0][1], t.track_of[1][1]);
  EXPECT_NE(t.track_of[0][1], a);
  EXPECT_EQ(t.track_of[1][2], -1);
  EXPECT_EQ(t.track_of[2][0], -1);
}

TEST(Tracks, ATrackHoldingTwoFeaturesOfOneImageIsDroppedWhole) {
  // 0:0 - 1:0 - 2:0 and 0:0 - 2:1: image 2 would see one point twice.
  std::vector<PairMatches> matches(3);
  matches[0] = {0, 1, 0, 0, {{0, 0}}};
  matches[1] = {1, 2, 0, 0, {{0, 0}}};
  matches[2] = {0, 2, 0, 0, {{0, 1}, {2, 2}}};
  const Tracks t = BuildTracks({3, 3, 3}, matches);
  EXPECT_EQ(t.dropped_inconsistent, 1);
  ASSERT_EQ(t.tracks.size(), 1u);  // the good 0:2 - 2:2 is kept
  EXPECT_EQ(t.track_of[0][0], -1);
  EXPECT_EQ(t.track_of[2][1], -1);
  EXPECT_EQ(t.track_of[0][2], t.track_of[2][2]);
}

// One nadir image of scattered ground points with distinctive descriptors,
// plus clutter; a predicted pose off by a few metres and a degree.
TEST(GuidedMatching, FindsThePointsThroughAPoseThatIsOffByAShift) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255);
  std::normal_distribution<double> g(0.0, 1.0);
  const Camera camera = Camera::Create(CameraModelId::kPinhole, 1000.0, 1200, 900);
  Pose truth;  // 80 m above the origin, looking down (x east, y south)
  truth.cam_from_world = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  truth.centre_in_world = {0.0, 0.0, 80.0};

  ImageFeatures f;
  f.width = 1200;
  f.height = 900;
  std::vector<cv::Mat> rows;
  std::vector<GuidedPoint> points;
  std::vector<int> feature_of_point;
  auto add_keypoint = [&](const Eigen::Vector2d& xy, const cv::Mat& descriptor) {
    Keypoint k;
    k.x = static_cast<float>(xy.x());
    k.y = static_cast<float>(xy.y());
    f.keypoints.push_back(k);
    rows.push_back(descriptor);
  };
  auto random_descriptor = [&]() {
    cv::Mat d(1, 128, CV_8U);
    for (int c = 0; c < 128; ++c) d.at<std::uint8_t>(c) = static_cast<std::uint8_t>(byte(rng));
    return d;
  };
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d x(60.0 * u(rng), 45.0 * u(rng), 2.0 * u(rng));
    const Eigen::Vector2d xy = camera.ImageFromCamera(truth.CamFromWorld(x));
    const cv::Mat d = random_descriptor();
    cv::Mat d_float;
    d.convertTo(d_float, CV_32F, 1.0 / 512.0);
    points.push_back({i, x, d_float});
    if (xy.x() < 0 || xy.y() < 0 || xy.x() > 1199 || xy.y() > 899) {
      feature_of_point.push_back(-1);
      continue;
    }
    feature_of_point.push_back(static_cast<int>(f.keypoints.size()));
    cv::Mat seen = d.clone();  // the same texture seen again: a little noise
    for (int c = 0; c < 128; c += 16) seen.at<std::uint8_t>(c) = static_cast<std::uint8_t>(byte(rng));
    add_keypoint(xy + 0.5 * Eigen::Vector2d(g(rng), g(rng)), seen);
  }
  for (int i = 0; i < 600; ++i) {  // clutter: features of nothing in the model
    add_keypoint(Eigen::Vector2d(600.0 + 599.0 * u(rng), 450.0 + 449.0 * u(rng)), random_descriptor());
  }
  cv::vconcat(rows, f.descriptors);

  // GPS 3 m east and 2 m north off, heading 1 degree off.
  Pose predicted = truth;
  predicted.centre_in_world += Eigen::Vector3d(3.0, 2.0, 0.0);
  predicted.cam_from_world =
      Eigen::Quaterniond(Eigen::AngleAxisd(1.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())) * truth.cam_from_world;

  const GuidedMatcher matcher(f, camera, 250.0);
  const Eigen::Vector2d shift = matcher.VoteShift(predicted, points);
  // A prediction 3 m east puts every point 3 m * f / H = 37.5 px west of
  // where it is seen: the shift (seen - predicted) is +37.5 px in x; 2 m
  // north, -25 px in y (y points south). The heading adds up to 13 px at
  // the corners; the vote's bins are 8 px.
  EXPECT_NEAR(shift.x(), 37.5, 12.0);
  EXPECT_NEAR(shift.y(), -25.0, 12.0);

  int right = 0, wrong = 0, visible = 0;
  for (int id : feature_of_point) visible += id >= 0;
  for (const GuidedMatch& m : matcher.Match(predicted, shift, 40.0, points)) {
    (feature_of_point[m.point] == m.feature ? right : wrong) += 1;
  }
  EXPECT_GT(right, 0.85 * visible);
  // Points out of view can only meet clutter; the ratio test lets a few
  // through, for PnP's RANSAC to reject.
  EXPECT_LT(wrong, 0.05 * right);

  // Without the shift, the 40 px window misses most of them.
  int unshifted = 0;
  for (const GuidedMatch& m : matcher.Match(predicted, Eigen::Vector2d::Zero(), 40.0, points)) {
    unshifted += feature_of_point[m.point] == m.feature;
  }
  EXPECT_LT(unshifted, right);

  // From the true pose, a tight window finds them all; each keypoint once.
  const std::vector<GuidedMatch> exact = matcher.Match(truth, Eigen::Vector2d::Zero(), 4.0, points);
  std::set<int> features_used;
  right = 0;
  for (const GuidedMatch& m : exact) {
    right += feature_of_point[m.point] == m.feature;
    EXPECT_TRUE(features_used.insert(m.feature).second);
  }
  EXPECT_GE(right, visible - 2);
}

// The pose estimators on exact and noisy normalised coordinates of a known
// scene: relative pose to the truth's rotation and baseline direction,
// absolute pose to the truth, outliers set aside.
TEST(PoseEstimation, RelativeAndAbsolutePosesOfAKnownScene) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Pose b;  // 10 m to the side, turned 5 degrees
  b.cam_from_world = Eigen::Quaterniond(Eigen::AngleAxisd(5.0 * M_PI / 180.0, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()));
  b.centre_in_world = {10.0, 1.0, 0.5};
  const double noise = 0.5 / 1000.0;  // half a pixel at f = 1000 px
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> in_a, in_b;
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector3d x(30.0 * u(rng), 20.0 * u(rng), 60.0 + 10.0 * u(rng));
    const Eigen::Vector3d xb = b.CamFromWorld(x);
    world.push_back(x);
    in_a.push_back(x.head<2>() / x.z() + noise * Eigen::Vector2d(g(rng), g(rng)));
    in_b.push_back(xb.head<2>() / xb.z() + noise * Eigen::Vector2d(g(rng), g(rng)));
  }
  // A fifth of the matches wrong (the first and last 30 swapped).
  for (int k = 0; k < 30; ++k) std::swap(in_b[k], in_b[299 - k]);

  const auto relative = EstimateRelativePose(in_a, in_b, 2.0 / 1000.0);
  ASSERT_TRUE(relative.has_value());
  EXPECT_GT(relative->inliers, 220);
  EXPECT_LE(relative->inliers, 242);  // the 60 swapped ones are not (a lucky one or two may be)
  // Half a pixel on a 10 m baseline at 60 m: a few tenths of a degree.
  const double rotation_error = relative->b.cam_from_world.angularDistance(b.cam_from_world) * 180.0 / M_PI;
  EXPECT_LT(rotation_error, 0.6);
  EXPECT_GT(rotation_error, 1e-3);
  // The baseline's direction (its length is not observable).
  const double direction_error =
      std::acos(std::clamp(relative->b.centre_in_world.normalized().dot(b.centre_in_world.normalized()), -1.0, 1.0));
  EXPECT_LT(direction_error * 180.0 / M_PI, 3.0);
  EXPECT_NEAR(relative->b.centre_in_world.norm(), 1.0, 1e-9);

  std::vector<int> inliers;
  const auto absolute = EstimateAbsolutePose(world, in_b, 2.0 / 1000.0, &inliers);
  ASSERT_TRUE(absolute.has_value());
  EXPECT_GE(static_cast<int>(inliers.size()), 225);
  for (int k : inliers) EXPECT_TRUE(k >= 30 && k < 270) << k;  // no swapped one kept
  EXPECT_LT((absolute->centre_in_world - b.centre_in_world).norm(), 0.1);
  EXPECT_GT((absolute->centre_in_world - b.centre_in_world).norm(), 1e-4);  // noisy: never exact
  EXPECT_LT(absolute->cam_from_world.angularDistance(b.cam_from_world) * 180.0 / M_PI, 0.05);

  // Too few correspondences: no answer.
  EXPECT_FALSE(EstimateRelativePose({in_a.begin(), in_a.begin() + 4}, {in_b.begin(), in_b.begin() + 4}, 0.002));
  EXPECT_FALSE(EstimateAbsolutePose({world.begin(), world.begin() + 3}, {in_b.begin(), in_b.begin() + 3}, 0.002,
                                    &inliers));
}

// Two photos of a plane (a flat field from 60 m, the second 15 m along the
// strip, both within a few degrees of nadir): the five-point solution is
// two-fold and RANSAC used to keep either; the one whose plane faces the
// cameras is returned, at the noise level, whatever the draw.
TEST(PoseEstimation, TwoPhotosOfAPlaneGiveTheSolutionThatFacesThem) {
  int wrong = 0;
  for (std::uint32_t seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::normal_distribution<double> g(0.0, 1.0);
    auto nadir = [&](const Eigen::Vector3d& centre) {
      Pose p;
      Eigen::Matrix3d down;  // x east, y south, z down
      down << 1, 0, 0, 0, -1, 0, 0, 0, -1;
      const Eigen::Quaterniond tilt(Eigen::AngleAxisd(3.0 * M_PI / 180.0 * u(rng), Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(3.0 * M_PI / 180.0 * u(rng), Eigen::Vector3d::UnitY()));
      p.cam_from_world = tilt * Eigen::Quaterniond(down);
      p.centre_in_world = centre;
      return p;
    };
    const Pose a = nadir({0.0, 0.0, 60.0}), b = nadir({15.0, 0.5 * u(rng), 60.0 + 0.3 * u(rng)});
    const double noise = 0.3 / 1200.0;
    std::vector<Eigen::Vector2d> in_a, in_b;
    for (int k = 0; k < 400; ++k) {
      const Eigen::Vector3d x(7.5 + 30.0 * u(rng), 20.0 * u(rng), 0.0);
      const Eigen::Vector3d xa = a.CamFromWorld(x), xb = b.CamFromWorld(x);
      in_a.push_back(xa.head<2>() / xa.z() + noise * Eigen::Vector2d(g(rng), g(rng)));
      in_b.push_back(xb.head<2>() / xb.z() + noise * Eigen::Vector2d(g(rng), g(rng)));
    }
    const auto relative = EstimateRelativePose(in_a, in_b, 1.0 / 1200.0);
    ASSERT_TRUE(relative.has_value());
    EXPECT_GT(relative->inliers, 240);
    // b relative to a, and its baseline's direction in a's frame.
    const Eigen::Quaterniond truth = b.cam_from_world * a.cam_from_world.conjugate();
    const Eigen::Vector3d baseline = (a.cam_from_world * (b.centre_in_world - a.centre_in_world)).normalized();
    const double rotation_deg = relative->b.cam_from_world.angularDistance(truth) * 180.0 / M_PI;
    const double direction_deg =
        std::acos(std::clamp(relative->b.centre_in_world.normalized().dot(baseline), -1.0, 1.0)) * 180.0 / M_PI;
    if (rotation_deg > 0.5 || direction_deg > 2.0) ++wrong;
    EXPECT_LT(rotation_deg, 0.5) << "seed " << seed;
    EXPECT_LT(direction_deg, 2.0) << "seed " << seed;
  }
  EXPECT_EQ(wrong, 0);
}

// Features and verified matches of a synthetic survey: one keypoint per
// observation at its noisy position, matched wherever two images see the
// same point.
struct SyntheticMatches {
  SparseModel truth;
  std::vector<std::string> names;
  std::vector<ImageFeatures> features;
  std::vector<PairMatches> matches;
};

SyntheticMatches MakeMatches(std::uint32_t seed, double pixel_noise_px, double gimbal_pitch_deg = -90.0,
                             double relief_m = SyntheticSurveyOptions().relief_m) {
  SyntheticSurveyOptions o;
  o.gimbal_pitch_deg = gimbal_pitch_deg;
  o.relief_m = relief_m;
  o.seed = seed;
  o.width = 1600;
  o.height = 1200;
  o.brown_params = {1200.0, 801.0, 598.0, -0.05, 0.02, 0.0, 0.0003, -0.0002};
  o.area_width_m = 120.0;
  o.area_height_m = 80.0;
  o.flight_height_m = 60.0;
  o.num_tie_points = 1500;
  o.num_control_points = 0;
  o.num_check_points = 0;
  o.pixel_noise_px = pixel_noise_px;
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SyntheticMatches out;
  out.truth = survey.truth;
  const SparseModel& observed = survey.observed;
  const size_t n = observed.images.size();
  out.features.resize(n);
  std::vector<std::map<int, int>> feature_of_point(n);
  for (size_t i = 0; i < n; ++i) {
    out.names.push_back(observed.images[i].name);
    out.features[i].width = o.width;
    out.features[i].height = o.height;
  }
  for (const Observation& obs : observed.observations) {
    if (observed.points[obs.point].role != PointRole::kTie) continue;
    Keypoint k;
    k.x = static_cast<float>(obs.xy.x());
    k.y = static_cast<float>(obs.xy.y());
    k.size = 4.0f;
    feature_of_point[obs.image][obs.point] = static_cast<int>(out.features[obs.image].keypoints.size());
    out.features[obs.image].keypoints.push_back(k);
  }
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      PairMatches m;
      m.i = static_cast<int>(i);
      m.j = static_cast<int>(j);
      for (const auto& [point, fi] : feature_of_point[i]) {
        const auto it = feature_of_point[j].find(point);
        if (it != feature_of_point[j].end()) m.inliers.push_back({fi, it->second});
      }
      m.putative = static_cast<int>(m.inliers.size());
      if (m.inliers.size() >= 30) out.matches.push_back(m);
    }
  }
  return out;
}

// The mapper's schedules of adjustment, each of which must reach the noise:
// the default (a global adjustment every 25 % of growth, exact); with local
// adjustments between; rare global ones with intermediate ones solved
// iteratively (the large-block path, here from 8 images); Huber in every
// global solve instead of screening, then least squares.
struct AdjustmentSchedule {
  const char* name;
  int local_adjust_images;
  double global_adjust_growth;
  int iterative_above_images;
  bool global_adjust_screening = true;
};

class MapperSchedules : public ::testing::TestWithParam<AdjustmentSchedule> {};

INSTANTIATE_TEST_SUITE_P(IncrementalMapper, MapperSchedules,
                         ::testing::Values(AdjustmentSchedule{"default", 0, 0.25, 0},
                                           AdjustmentSchedule{"local", 6, 0.25, 0},
                                           AdjustmentSchedule{"local_iterative", 6, 1.0, 8},
                                           AdjustmentSchedule{"huber", 0, 0.25, 0, false}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST_P(MapperSchedules, RegistersEveryImageOfASyntheticBlockToTheNoiseLevel) {
  const double noise_px = 0.5;
  const SyntheticMatches s = MakeMatches(7, noise_px);
  ASSERT_GT(s.names.size(), 10u);
  // Start from a focal length 5 % off and no distortion, as from EXIF.
  Camera start = Camera::Create(CameraModelId::kBrown, 1260.0, 1600, 1200);
  const std::vector<int> camera_of_image(s.names.size(), 0);
  MapperOptions options;
  options.num_threads = 2;
  options.local_adjust_images = GetParam().local_adjust_images;
  options.global_adjust_growth = GetParam().global_adjust_growth;
  options.iterative_above_images = GetParam().iterative_above_images;
  options.global_adjust_screening = GetParam().global_adjust_screening;
  const MapperResult result =
      ReconstructIncremental(s.names, camera_of_image, {start}, s.features, s.matches, options);
  // Local adjustments run between the global ones (from the ninth image on)
  // exactly when asked for.
  if (options.local_adjust_images > 0) {
    EXPECT_GT(result.local_adjustments, 0);
  } else {
    EXPECT_EQ(result.local_adjustments, 0);
  }

  int registered = 0;
  for (const ImageRegistration& r : result.images) registered += r.registered;
  EXPECT_EQ(registered, static_cast<int>(s.names.size()));
  EXPECT_FALSE(result.initial_pair.empty());
  EXPECT_GT(result.num_tracks, 1000);

  // The reprojection RMS is the noise (2D: σ√2), within what the adjusted
  // parameters absorb -- never far below it (overfitting) nor above it.
  const std::vector<double> errors = ReprojectionErrors(result.model);
  double sum = 0.0;
  int count = 0;
  for (double e : errors) {
    if (!std::isfinite(e)) continue;
    sum += e * e;
    ++count;
  }
  const double rms = std::sqrt(sum / count);
  EXPECT_GT(rms, 0.8 * noise_px * std::sqrt(2.0));
  EXPECT_LT(rms, 1.2 * noise_px * std::sqrt(2.0));

  // Self-calibrated: the focal length back within 0.5 % of the truth.
  EXPECT_NEAR(result.model.cameras[0].focal_px(), 1200.0, 6.0);

  // The cameras, up to the similarity SfM cannot know: the truth's shape to
  // within a small fraction of the flight height (60 m) -- 0.5 px of noise
  // at 5 cm GSD is centimetres, a wrong reconstruction metres.
  std::vector<Eigen::Vector3d> estimated, truth;
  for (size_t i = 0; i < s.names.size(); ++i) {
    estimated.push_back(result.model.images[i].pose.centre_in_world);
    truth.push_back(s.truth.images[i].pose.centre_in_world);
  }
  const double centre_rms = testing::AlignedRms(estimated, truth);
  EXPECT_LT(centre_rms, 0.15);
  EXPECT_GT(centre_rms, 0.003);  // noisy data cannot give the truth exactly
}

// Screened global adjustments end where least squares ends (the estimator
// the georeference stage's statistics assume); Huber in every solve stops
// short of it, along the block's weak directions. Measured by what a
// least-squares polish of the mapper's model still gains.
TEST(IncrementalMapper, ScreenedGlobalAdjustmentsEndAtTheLeastSquaresOptimum) {
  const SyntheticMatches s = MakeMatches(7, 0.5);
  const Camera start = Camera::Create(CameraModelId::kBrown, 1260.0, 1600, 1200);
  const std::vector<int> camera_of_image(s.names.size(), 0);
  auto polish_gain = [&](bool screening) {
    MapperOptions options;
    options.num_threads = 2;
    options.global_adjust_screening = screening;
    SparseModel model =
        ReconstructIncremental(s.names, camera_of_image, {start}, s.features, s.matches, options).model;
    BundleOptions polish;
    polish.refine_intrinsics = IntrinsicsRefinement::kAll;
    polish.max_iterations = 50;
    polish.function_tolerance = 1e-12;
    polish.parameter_tolerance = 1e-12;
    polish.num_threads = 2;
    const BundleSummary summary = AdjustBundle(&model, polish);
    return (summary.solves.front().initial_cost - summary.solves.back().final_cost) / summary.solves.front().initial_cost;
  };
  const double screened = polish_gain(true);
  const double huber = polish_gain(false);
  // Measured: 3e-7 of the cost (the last solve's 1e-6 tolerance) against
  // 2.3e-3 for Huber throughout.
  EXPECT_LT(screened, 1e-5);
  EXPECT_GT(huber, 1e-4);
}

// Nadir photos of flat ground at one altitude cannot tell the focal length
// from the depth: the mapper holds it at its EXIF value there (refined, it
// wandered on a rendered crop-row survey from 520 to 982 px, and the DSM
// came out 40 m low), and still refines the distortion; over relief the
// photos determine f, and it is refined as before (MapperSchedules).
TEST(IncrementalMapper, HoldsTheFocalLengthOfAFlatNadirBlockAtItsExifValue) {
  // 2 m of relief under a 60 m flight (a 0.3 m one starts the model wrong:
  // the initial pair of photos of a plane, noticed and left).
  const SyntheticMatches s = MakeMatches(7, 0.5, -90.0, /*relief_m=*/0.3);
  const Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  const std::vector<int> camera_of_image(s.names.size(), 0);
  MapperOptions options;
  options.num_threads = 2;
  options.focal_prior_px = {1212.0};  // EXIF, 1 % off
  const MapperResult flat = ReconstructIncremental(s.names, camera_of_image, {start}, s.features, s.matches, options);
  EXPECT_TRUE(flat.focal_held);
  EXPECT_EQ(flat.model.cameras[0].focal_px(), 1212.0);
  // The distortion is still refined (the truth's k1 is -0.05).
  EXPECT_NEAR(flat.model.cameras[0].params[3], -0.05, 0.02);
  int registered = 0;
  for (const ImageRegistration& r : flat.images) registered += r.registered;
  EXPECT_EQ(registered, static_cast<int>(s.names.size()));

  // Over 12 m of relief under a 60 m flight the same prior does not hold f:
  // it comes back to the truth.
  const SyntheticMatches hilly = MakeMatches(7, 0.5);
  const MapperResult refined =
      ReconstructIncremental(hilly.names, camera_of_image, {start}, hilly.features, hilly.matches, options);
  EXPECT_FALSE(refined.focal_held);
  EXPECT_NEAR(refined.model.cameras[0].focal_px(), 1200.0, 6.0);
}

TEST(IncrementalMapper, AnImageWithoutMatchesIsLeftOutAndSaysWhy) {
  SyntheticMatches s = MakeMatches(8, 0.3);
  const int lonely = static_cast<int>(s.names.size()) / 2;
  std::vector<PairMatches> kept;
  for (const PairMatches& m : s.matches) {
    if (m.i != lonely && m.j != lonely) kept.push_back(m);
  }
  Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  MapperOptions options;
  options.num_threads = 2;
  const MapperResult result = ReconstructIncremental(s.names, std::vector<int>(s.names.size(), 0), {start},
                                                     s.features, kept, options);
  EXPECT_FALSE(result.images[lonely].registered);
  EXPECT_FALSE(result.images[lonely].why_not.empty());
  EXPECT_FALSE(result.model.images[lonely].registered);
  int registered = 0;
  for (const ImageRegistration& r : result.images) registered += r.registered;
  EXPECT_EQ(registered, static_cast<int>(s.names.size()) - 1);
}

// A false registration staged on a block: image X carries the features and
// matches of the image Y farthest from it, while its GPS (2 m / 4 m noise)
// says where it was.
struct FalseRegistration {
  int x = 0, y = 0;
  double apart_m = 0.0;
  std::vector<std::optional<Eigen::Vector3d>> gps;
  std::vector<ImageFeatures> features;
  std::vector<PairMatches> matches;
};

FalseRegistration StageFalseRegistration(const SyntheticMatches& s, std::uint32_t seed) {
  FalseRegistration f;
  const int n = static_cast<int>(s.names.size());
  f.gps.resize(n);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 2.0);
  for (int i = 0; i < n; ++i) {
    f.gps[i] = s.truth.images[i].pose.centre_in_world + Eigen::Vector3d(noise(rng), noise(rng), 2.0 * noise(rng));
  }
  f.x = n / 2;
  auto centre = [&](int i) { return s.truth.images[i].pose.centre_in_world; };
  for (int i = 0; i < n; ++i) {
    if ((centre(i) - centre(f.x)).norm() > (centre(f.y) - centre(f.x)).norm()) f.y = i;
  }
  f.apart_m = (centre(f.y) - centre(f.x)).norm();
  f.features = s.features;
  f.features[f.x] = s.features[f.y];
  for (const PairMatches& m : s.matches) {
    if (m.i == f.x || m.j == f.x) continue;
    f.matches.push_back(m);
    if (m.i != f.y && m.j != f.y) continue;
    PairMatches copy = m;  // Y's pair, as X's
    if (copy.i == f.y) copy.i = f.x;
    if (copy.j == f.y) copy.j = f.x;
    if (copy.i > copy.j) {
      std::swap(copy.i, copy.j);
      for (auto& in : copy.inliers) std::swap(in[0], in[1]);
    }
    f.matches.push_back(copy);
  }
  return f;
}

// A false registration on repetitive texture, caught when it happens: one
// image (X) carries another's features and matches (Y's, 2 strips away), so
// PnP places it where Y is, while its GPS says where it was. The check
// against the GPS de-registers it and names it; every other image stays
// registered. Its GPS fixes agree with their neighbours': the fix is right.
// The same block with a third of its GPS fixes 50 m off (blunders that jump
// away from their neighbours) keeps every image: the fixes are the errors.
TEST(IncrementalMapper, AFalseRegistrationIsCaughtByTheGpsWhenItHappens) {
  SyntheticMatches s = MakeMatches(9, 0.3);
  const int n = static_cast<int>(s.names.size());
  const FalseRegistration staged = StageFalseRegistration(s, 9);
  const int x = staged.x, y = staged.y;
  const double apart = staged.apart_m;
  ASSERT_GT(apart, 60.0);
  const std::vector<std::optional<Eigen::Vector3d>>& gps = staged.gps;
  const std::vector<ImageFeatures>& features = staged.features;
  const std::vector<PairMatches>& matches = staged.matches;
  Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  MapperOptions options;
  options.num_threads = 2;
  options.gps_rescue = false;  // these keypoints carry no descriptors to match from
  const std::vector<int> camera_of_image(n, 0);
  {
    MapperOptions unchecked = options;
    unchecked.gps_check_m = 0.0;
    const MapperResult r = ReconstructIncremental(s.names, camera_of_image, {start}, features, matches, unchecked, gps);
    EXPECT_TRUE(r.images[x].registered) << "the false registration this test is about did not happen";
  }
  const MapperResult r = ReconstructIncremental(s.names, camera_of_image, {start}, features, matches, options, gps);
  EXPECT_FALSE(r.images[x].registered);
  EXPECT_NE(r.images[x].why_not.find("m from its GPS position"), std::string::npos) << r.images[x].why_not;
  EXPECT_EQ(r.gps_deregistered, std::vector<std::string>{s.names[x]});
  std::printf("%s (truly %.0f m from %s): %s\n", s.names[x].c_str(), apart, s.names[y].c_str(), r.images[x].why_not.c_str());
  for (int i = 0; i < n; ++i) {
    if (i != x) { EXPECT_TRUE(r.images[i].registered) << s.names[i] << ": " << r.images[i].why_not; }
  }

  // GPS blunders on every third image of the untouched block.
  std::vector<std::optional<Eigen::Vector3d>> blundered = gps;
  for (int i = 0; i < n; i += 3) *blundered[i] += Eigen::Vector3d(50.0, 0.0, 0.0);
  const MapperResult b = ReconstructIncremental(s.names, camera_of_image, {start}, s.features, s.matches, options,
                                                blundered);
  EXPECT_TRUE(b.gps_deregistered.empty());
  for (int i = 0; i < n; ++i) EXPECT_TRUE(b.images[i].registered) << s.names[i] << ": " << b.images[i].why_not;
}

// Started from the photos' GPS (1 m noise) and attitudes (each turned by 5
// degrees about a random axis): every photo registered in the GPS frame
// from the start, to the noise, without an image pair's relative pose; the
// focal length held by the adjustments where the block is flat and nadir.
TEST(IncrementalMapper, StartsFromThePhotosGpsAndAttitude) {
  const double noise_px = 0.5;
  const SyntheticMatches s = MakeMatches(7, noise_px);
  const int n = static_cast<int>(s.names.size());
  std::mt19937 rng(21);
  std::normal_distribution<double> metre(0.0, 1.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<std::optional<Eigen::Vector3d>> gps(n);
  MapperPriors priors;
  for (int i = 0; i < n; ++i) {
    const Pose& truth = s.truth.images[i].pose;
    gps[i] = truth.centre_in_world + Eigen::Vector3d(metre(rng), metre(rng), metre(rng));
    priors.gps_sigma_h_m.push_back(1.0);
    priors.gps_sigma_v_m.push_back(1.0);
    const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    priors.attitude.push_back(Eigen::Quaterniond(Eigen::AngleAxisd(5.0 * M_PI / 180.0, axis)) * truth.cam_from_world);
  }
  MapperOptions options;
  options.num_threads = 2;
  options.gps_rescue = false;  // these keypoints carry no descriptors to match from
  options.gps_priors = true;
  Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  const MapperResult r = ReconstructIncremental(s.names, std::vector<int>(n, 0), {start}, s.features, s.matches,
                                                options, gps, {}, priors);
  EXPECT_EQ(r.initial_pair, "from the photos' GPS and attitude");
  EXPECT_EQ(r.gps_anchored_at_images, n);
  int registered = 0;
  for (const ImageRegistration& im : r.images) registered += im.registered;
  EXPECT_EQ(registered, n);
  const std::vector<double> errors = ReprojectionErrors(r.model);
  double sum = 0.0;
  int count = 0;
  for (double e : errors) {
    if (std::isfinite(e)) sum += e * e, ++count;
  }
  const double rms = std::sqrt(sum / count);
  EXPECT_GT(rms, 0.8 * noise_px * std::sqrt(2.0));
  EXPECT_LT(rms, 1.2 * noise_px * std::sqrt(2.0));
  // In the GPS frame as it stands: the centres within the GPS noise of the
  // truth (1 m per axis, averaged down by the block); its shape to a
  // fraction of that noise, which bends it a little (measured 0.16 m).
  // A wrong start is metres off.
  std::vector<Eigen::Vector3d> estimated, truth;
  double sq = 0.0;
  for (int i = 0; i < n; ++i) {
    estimated.push_back(r.model.images[i].pose.centre_in_world);
    truth.push_back(s.truth.images[i].pose.centre_in_world);
    sq += (estimated.back() - truth.back()).squaredNorm();
  }
  const double absolute_rms = std::sqrt(sq / n);
  EXPECT_LT(absolute_rms, 1.0);
  EXPECT_GT(absolute_rms, 0.05);  // noisy fixes cannot give the truth exactly
  EXPECT_LT(testing::AlignedRms(estimated, truth), 0.3);
  std::printf("from priors: %d of %d registered, %.3f px, centres %.3f m from the truth (%.3f m up to a similarity)\n",
              registered, n, rms, absolute_rms, testing::AlignedRms(estimated, truth));
}

// The same false registration in an oblique block (cameras 30 degrees off
// nadir, north and south strip by strip): its optical axes give no
// vertical, so without gimbal angles the check cannot level the model and X
// stays; with the photos' gimbal pitches (0.5 degrees of noise) X is caught
// and named, and every other image stays.
TEST(IncrementalMapper, AFalseRegistrationInAnObliqueBlockIsCaughtThroughItsGimbals) {
  const SyntheticMatches s = MakeMatches(12, 0.3, -60.0);
  const int n = static_cast<int>(s.names.size());
  const FalseRegistration staged = StageFalseRegistration(s, 12);
  ASSERT_GT(staged.apart_m, 60.0);
  std::map<std::string, GimbalAttitude> gimbal;
  std::mt19937 rng(12);
  std::normal_distribution<double> noise(0.0, 0.5);
  for (const Image& image : s.truth.images) {
    GimbalAttitude a = AttitudeOf(image.pose);
    a.pitch_deg += noise(rng);
    a.yaw_deg += noise(rng);
    gimbal[image.name] = a;
  }
  Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  MapperOptions options;
  options.num_threads = 2;
  options.gps_rescue = false;
  const std::vector<int> camera_of_image(n, 0);
  const MapperResult blind =
      ReconstructIncremental(s.names, camera_of_image, {start}, staged.features, staged.matches, options, staged.gps);
  EXPECT_TRUE(blind.images[staged.x].registered) << "an oblique block without gimbals has no vertical to check by";
  const MapperResult r = ReconstructIncremental(s.names, camera_of_image, {start}, staged.features, staged.matches,
                                                options, staged.gps, gimbal);
  EXPECT_FALSE(r.images[staged.x].registered);
  EXPECT_NE(r.images[staged.x].why_not.find("m from its GPS position"), std::string::npos) << r.images[staged.x].why_not;
  EXPECT_EQ(r.gps_deregistered, std::vector<std::string>{s.names[staged.x]});
  for (int i = 0; i < n; ++i) {
    if (i != staged.x) { EXPECT_TRUE(r.images[i].registered) << s.names[i] << ": " << r.images[i].why_not; }
  }
}

// A block whose two halves share no tie point (a field bare of texture
// between them): the half the main model leaves out is reconstructed on its
// own and placed by its GPS, its seam with the main model held by GPS alone;
// without GPS it cannot be placed and each of its photos says why.
TEST(IncrementalMapper, PhotosWithNoTiesToTheMainModelFormAComponentPlacedByTheGps) {
  const SyntheticMatches s = MakeMatches(11, 0.3);
  const int n = static_cast<int>(s.names.size());
  double mid = 0.0;
  for (int i = 0; i < n; ++i) mid += s.truth.images[i].pose.centre_in_world.x() / n;
  std::vector<int> east(n);
  for (int i = 0; i < n; ++i) east[i] = s.truth.images[i].pose.centre_in_world.x() > mid;
  std::vector<PairMatches> matches;
  for (const PairMatches& m : s.matches) {
    if (east[m.i] == east[m.j]) matches.push_back(m);
  }
  ASSERT_LT(matches.size(), s.matches.size());
  std::vector<std::optional<Eigen::Vector3d>> gps(n);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 2.0);
  for (int i = 0; i < n; ++i) {
    gps[i] = s.truth.images[i].pose.centre_in_world + Eigen::Vector3d(noise(rng), noise(rng), 2.0 * noise(rng));
  }
  Camera start = Camera::Create(CameraModelId::kBrown, 1200.0, 1600, 1200);
  MapperOptions options;
  options.num_threads = 2;
  options.gps_rescue = false;  // these keypoints carry no descriptors to match from
  const std::vector<int> camera_of_image(n, 0);
  const MapperResult r = ReconstructIncremental(s.names, camera_of_image, {start}, s.features, matches, options, gps);
  ASSERT_EQ(r.component_images.size(), 2u);
  EXPECT_EQ(r.component_images[0] + r.component_images[1], n);
  std::vector<Eigen::Vector3d> main_model, main_truth;
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(r.images[i].registered) << s.names[i] << ": " << r.images[i].why_not;
    // Each component is one half of the block.
    EXPECT_EQ(east[i] == east[0], r.component[i] == r.component[0]) << s.names[i];
    if (r.component[i] == 0) {
      main_model.push_back(r.model.images[i].pose.centre_in_world);
      main_truth.push_back(s.truth.images[i].pose.centre_in_world);
    }
  }
  // The main model in the truth frame; the other half, placed by 2 m / 4 m
  // GPS on its own photos, lies where its GPS says: within a few metres,
  // not metres-perfect and not tens of metres off.
  const auto truth_from_main = FitSimilarity(main_model, main_truth);
  ASSERT_TRUE(truth_from_main.has_value());
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < n; ++i) {
    if (r.component[i] != 1) continue;
    sum += (truth_from_main->Apply(r.model.images[i].pose.centre_in_world) -
            s.truth.images[i].pose.centre_in_world).squaredNorm();
    ++count;
  }
  const double rms = std::sqrt(sum / count);
  std::printf("components of %d and %d photos; the second placed by GPS within %.2f m RMS\n",
              r.component_images[0], r.component_images[1], rms);
  EXPECT_LT(rms, 6.0);
  // Its points came along, in the same frame: they reproject into its photos.
  int observed_in_second = 0;
  for (const Observation& obs : r.model.observations) {
    if (r.component[obs.image] != 1) continue;
    const Image& image = r.model.images[obs.image];
    const Eigen::Vector2d xy =
        r.model.cameras[image.camera].ImageFromCamera(image.pose.CamFromWorld(r.model.points[obs.point].position));
    EXPECT_LT((xy - obs.xy).norm(), 10.0);
    ++observed_in_second;
  }
  EXPECT_GT(observed_in_second, 1000);

  // Without GPS the second half cannot be placed: left out, saying why.
  const MapperResult alone = ReconstructIncremental(s.names, camera_of_image, {start}, s.features, matches, options);
  ASSERT_EQ(alone.component_images.size(), 1u);
  int left_out = 0;
  for (int i = 0; i < n; ++i) {
    if (alone.images[i].registered) continue;
    ++left_out;
    EXPECT_NE(alone.images[i].why_not.find("none with the main model"), std::string::npos) << alone.images[i].why_not;
  }
  EXPECT_EQ(left_out + alone.component_images[0], n);
  EXPECT_GE(left_out, kMinComponentImages);
}

}  // namespace
}  // namespace aerotri
