// SPDX-License-Identifier: BSD-3-Clause
// Structure from motion on its own: tracks from matches, and the incremental
// mapper on features whose correspondences and truth are known, so that
// nothing of feature extraction or matching is under test here.
#include <gtest/gtest.h>

#include <map>
#include <random>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/sfm/incremental_mapper.h"
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

// Features and verified matches of a synthetic survey: one keypoint per
// observation at its noisy position, matched wherever two images see the
// same point.
struct SyntheticMatches {
  SparseModel truth;
  std::vector<std::string> names;
  std::vector<ImageFeatures> features;
  std::vector<PairMatches> matches;
};

SyntheticMatches MakeMatches(std::uint32_t seed, double pixel_noise_px) {
  SyntheticSurveyOptions o;
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

TEST(IncrementalMapper, RegistersEveryImageOfASyntheticBlockToTheNoiseLevel) {
  const double noise_px = 0.5;
  const SyntheticMatches s = MakeMatches(7, noise_px);
  ASSERT_GT(s.names.size(), 10u);
  // Start from a focal length 5 % off and no distortion, as from EXIF.
  Camera start = Camera::Create(CameraModelId::kBrown, 1260.0, 1600, 1200);
  const std::vector<int> camera_of_image(s.names.size(), 0);
  MapperOptions options;
  options.num_threads = 2;
  const MapperResult result =
      ReconstructIncremental(s.names, camera_of_image, {start}, s.features, s.matches, options);

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

}  // namespace
}  // namespace aerotri
