// SPDX-License-Identifier: BSD-3-Clause
// Rolling shutters: the projection of a moving camera's rows, and the bundle
// adjustment of a synthetic rolling-shutter survey with the motion modelled
// and without.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/model/sparse_model.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

SyntheticSurveyOptions RollingSurvey(double readout_s) {
  SyntheticSurveyOptions o;
  o.seed = 21;
  o.area_width_m = 160.0;
  o.area_height_m = 110.0;
  o.num_tie_points = 1200;
  o.pixel_noise_px = 0.5;
  o.readout_time_s = readout_s;
  o.flight_speed_mps = 12.0;
  return o;
}

// A point is seen at the row the camera exposed when it passed: projecting
// it from the pose at that row gives that very pixel. The camera moves 0.48 m
// over a 40 ms readout at 12 m/s; at 80 m and f = 3000 px that is 18 px
// between the first row and the last.
TEST(RollingShutter, APointIsSeenFromThePoseOfItsOwnRow) {
  const SyntheticSurvey survey = MakeSyntheticSurvey(RollingSurvey(0.040));
  const SparseModel& m = survey.truth;
  const Camera& camera = m.cameras[0];
  double largest_shift = 0.0;
  for (const Observation& obs : m.observations) {
    const Image& image = m.images[obs.image];
    ASSERT_TRUE(image.rolling_shutter);
    const Eigen::Vector3d& x = m.points[obs.point].position;
    const Eigen::Vector2d at_row = camera.ImageFromCamera(image.PoseAtRow(obs.xy.y(), camera.height).CamFromWorld(x));
    EXPECT_LT((at_row - obs.xy).norm(), 1e-6);
    Image global = image;
    global.rolling_shutter.reset();
    largest_shift = std::max(largest_shift, (ProjectIntoImage(camera, global, x) - obs.xy).norm());
  }
  // Half the 18 px at the top and bottom rows, more on higher ground.
  EXPECT_GT(largest_shift, 7.0);
  EXPECT_LT(largest_shift, 12.0);
  // A global shutter's rows are all the pose's.
  Image still = m.images[0];
  still.rolling_shutter->readout_time_s = 0.0;
  const Eigen::Vector3d x = m.points[m.observations[0].point].position;
  EXPECT_LT((ProjectIntoImage(camera, still, x) - camera.ImageFromCamera(still.pose.CamFromWorld(x))).norm(), 1e-12);
}

// The tie points' error against the truth (absolute: GPS holds the datum).
double PointRms(const SparseModel& adjusted, const SparseModel& truth) {
  double sum = 0.0;
  int n = 0;
  for (size_t p = 0; p < truth.points.size(); ++p) {
    if (truth.points[p].role != PointRole::kTie) continue;
    sum += (adjusted.points[p].position - truth.points[p].position).squaredNorm();
    ++n;
  }
  return std::sqrt(sum / n);
}

// Adjusted with GPS priors (5 cm / 10 cm) from a perturbed start, with every
// intrinsic refined. The same survey three ways: photographed with a global
// shutter; with a rolling shutter, its motion modelled; with a rolling
// shutter taken for a global one. Modelled, the points land as well as the
// global shutter's (within 1.3 times, the band); unmodelled, the
// 18 px shear between strips flown both ways bends the block, while the
// residuals hardly show it (the poses and intrinsics absorb most of it):
// why a rolling shutter must be modelled rather than noticed.
struct Adjusted {
  double rms_px = 0.0;
  double point_rms_m = 0.0;
};

Adjusted AdjustWithGps(const SyntheticSurvey& survey, bool model_motion) {
  SparseModel model = survey.observed;
  std::mt19937 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < model.images.size(); ++i) {
    PositionPrior prior;
    prior.position = survey.truth.images[i].pose.centre_in_world +
                     Eigen::Vector3d(0.05 * g(rng), 0.05 * g(rng), 0.1 * g(rng));
    prior.sigma_h_m = 0.05;
    prior.sigma_v_m = 0.1;
    model.images[i].gps_prior = prior;
    if (!model_motion) model.images[i].rolling_shutter.reset();
  }
  testing::Perturb(&model, rng, 0.5, 0.3, 0.3, 0.0);
  const BundleSummary summary = AdjustBundle(&model, BundleOptions{});
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_TRUE(summary.converged);
  return {summary.final_rms_px, PointRms(model, survey.truth)};
}

TEST(RollingShutter, AdjustmentWithTheMotionModelledIsAsGoodAsAGlobalShutter) {
  const SyntheticSurveyOptions o = RollingSurvey(0.040);
  const SyntheticSurvey rolling = MakeSyntheticSurvey(o);
  const Adjusted global = AdjustWithGps(MakeSyntheticSurvey(RollingSurvey(0.0)), true);
  const Adjusted modelled = AdjustWithGps(rolling, true);
  const Adjusted unmodelled = AdjustWithGps(rolling, false);
  std::printf("40 ms readout at 12 m/s: tie points %.4f m, %.3f px (modelled); %.4f m, %.3f px (taken for a global "
              "shutter); the same survey with a global shutter: %.4f m, %.3f px\n",
              modelled.point_rms_m, modelled.rms_px, unmodelled.point_rms_m, unmodelled.rms_px, global.point_rms_m,
              global.rms_px);
  const double expected_rms = o.pixel_noise_px * std::sqrt(2.0);
  for (const Adjusted& a : {global, modelled}) {
    EXPECT_GT(a.rms_px, 0.85 * expected_rms);
    EXPECT_LT(a.rms_px, 1.05 * expected_rms);
  }
  EXPECT_LT(modelled.point_rms_m, 1.3 * global.point_rms_m);
  EXPECT_GT(modelled.point_rms_m, global.point_rms_m / 1.3);
  EXPECT_GT(unmodelled.point_rms_m, 3.0 * modelled.point_rms_m);
}

}  // namespace
}  // namespace aerotri
