// SPDX-License-Identifier: BSD-3-Clause
// Rolling shutters: the projection of a moving camera's rows, and the bundle
// adjustment of a synthetic rolling-shutter survey with the motion modelled
// and without.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/adjust/reprojection_cost.h"
#include "libphoto/model/sparse_model.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "libphoto/survey/survey_phases.h"
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
  testing::AddGpsPriors(&model, survey.truth, rng, 0.05, 0.1);
  for (Image& image : model.images) {
    if (!model_motion) image.rolling_shutter.reset();
  }
  testing::Perturb(&model, rng, 0.5, 0.3, 0.3, 0.0);
  const BundleSummary summary = AdjustBundle(&model, BundleOptions{});
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_TRUE(summary.converged);
  return {summary.final_rms_px, PointRms(model, survey.truth)};
}

// The same adjustment with the readout time unknown: every photo's velocity
// as known, its readout started at zero and estimated for the camera group,
// with the posterior precision for its sigma.
Adjusted AdjustEstimatingReadout(const SyntheticSurvey& survey, BundleSummary::Readout* readout,
                                 bool velocity_from_track = false) {
  SparseModel model = survey.observed;
  std::mt19937 rng(21);
  testing::AddGpsPriors(&model, survey.truth, rng, 0.05, 0.1);
  for (Image& image : model.images) image.rolling_shutter->readout_time_s = 0.0;
  if (velocity_from_track) {
    // The photos state no velocity: it comes from their GPS positions and
    // capture times (each strip flown at the survey's speed, a minute's
    // turn between strips).
    std::vector<TrackFix> fixes;
    double t = 0.0;
    for (size_t i = 0; i < model.images.size(); ++i) {
      const Eigen::Vector3d& v = survey.truth.images[i].rolling_shutter->velocity;
      if (i > 0) {
        const Eigen::Vector3d step = survey.truth.images[i].pose.centre_in_world -
                                     survey.truth.images[i - 1].pose.centre_in_world;
        const bool same_strip = (v - survey.truth.images[i - 1].rolling_shutter->velocity).norm() < 1e-6;
        t += same_strip ? step.norm() / v.norm() : 60.0;
      }
      fixes.push_back({model.images[i].name, model.images[i].gps_prior->position, t});
    }
    const std::map<std::string, Eigen::Vector3d> track = VelocitiesFromTrack(fixes, 3.0);
    for (Image& image : model.images) {
      const auto it = track.find(image.name);
      if (it == track.end()) {
        image.rolling_shutter.reset();
      } else {
        image.rolling_shutter->velocity = it->second;
      }
    }
  }
  testing::Perturb(&model, rng, 0.5, 0.3, 0.3, 0.0);
  BundleOptions options;
  options.estimate_readout = true;
  options.compute_precision = true;
  const BundleSummary summary = AdjustBundle(&model, options);
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_TRUE(summary.converged);
  EXPECT_TRUE(summary.precision.computed) << summary.precision.note;
  EXPECT_EQ(summary.readouts.size(), 1u);
  if (!summary.readouts.empty()) *readout = summary.readouts[0];
  return {summary.final_rms_px, PointRms(model, survey.truth)};
}

// The readout's Jacobian is the centre's along the row's share of the
// motion: checked against central differences of the residual.
TEST(RollingShutter, ReadoutJacobianMatchesCentralDifferences) {
  const SyntheticSurvey survey = MakeSyntheticSurvey(RollingSurvey(0.040));
  const SparseModel& m = survey.truth;
  const Camera& camera = m.cameras[0];
  for (int k : {0, 57, 311}) {
    const Observation& obs = m.observations[k];
    const Image& image = m.images[obs.image];
    const double fraction = (obs.xy.y() - 0.5 * (camera.height - 1)) / camera.height;
    const RollingShutterReprojectionCost<BrownModel> cost(obs.xy, 0.7, fraction, image.rolling_shutter->velocity);
    const Eigen::Quaterniond q = image.pose.cam_from_world;
    const double rotation[4] = {q.w(), q.x(), q.y(), q.z()};
    Eigen::Vector3d centre = image.pose.centre_in_world;
    Eigen::Vector3d point = m.points[obs.point].position;
    std::vector<double> intrinsics = camera.params;
    double readout = 0.031;
    double* jacobians[5] = {nullptr, nullptr, nullptr, nullptr, nullptr};
    double j_r[2];
    jacobians[4] = j_r;
    const double* parameters[5] = {rotation, centre.data(), point.data(), intrinsics.data(), &readout};
    double residual[2], plus[2], minus[2];
    ASSERT_TRUE(cost.Evaluate(parameters, residual, jacobians));
    const double h = 1e-5;
    double r_plus = readout + h, r_minus = readout - h;
    parameters[4] = &r_plus;
    ASSERT_TRUE(cost.Evaluate(parameters, plus, nullptr));
    parameters[4] = &r_minus;
    ASSERT_TRUE(cost.Evaluate(parameters, minus, nullptr));
    for (int a = 0; a < 2; ++a) {
      const double numeric = (plus[a] - minus[a]) / (2.0 * h);
      EXPECT_NEAR(j_r[a], numeric, 1e-6 * std::max(1.0, std::abs(numeric)));
    }
    // And at the true readout, the residual is the observation's noise-free zero.
    readout = 0.040;
    parameters[4] = &readout;
    ASSERT_TRUE(cost.Evaluate(parameters, residual, nullptr));
    EXPECT_LT(std::hypot(residual[0], residual[1]), 1e-6);
  }
}

// The readout estimated from the photos' velocities alone: within 10 % of
// the truth (the band) and within 4 of its own sigmas, and the
// points as good as with the readout given.
TEST(RollingShutter, ReadoutIsEstimatedWithItsSigmaWhenOnlyTheVelocityIsKnown) {
  const SyntheticSurvey rolling = MakeSyntheticSurvey(RollingSurvey(0.040));
  const Adjusted known = AdjustWithGps(rolling, true);
  BundleSummary::Readout readout;
  const Adjusted estimated = AdjustEstimatingReadout(rolling, &readout);
  std::printf("readout estimated %.2f +- %.2f ms (truth 40 ms) over %d photos; tie points %.4f m (estimated), "
              "%.4f m (given)\n",
              1000.0 * readout.readout_time_s, 1000.0 * readout.sigma_s, readout.images, estimated.point_rms_m,
              known.point_rms_m);
  EXPECT_EQ(readout.images, static_cast<int>(rolling.truth.images.size()));
  EXPECT_NEAR(readout.readout_time_s, 0.040, 0.004);
  EXPECT_GT(readout.sigma_s, 0.0);
  EXPECT_LT(readout.sigma_s, 0.004);
  EXPECT_LT(std::abs(readout.readout_time_s - 0.040), 4.0 * readout.sigma_s);
  EXPECT_LT(estimated.point_rms_m, 1.3 * known.point_rms_m);
  EXPECT_GT(estimated.point_rms_m, known.point_rms_m / 1.3);

  // The velocities from the GPS track instead (5 cm noise): the same readout
  // within the 10 %.
  BundleSummary::Readout tracked;
  const Adjusted from_track = AdjustEstimatingReadout(rolling, &tracked, true);
  std::printf("with velocities from the GPS track: readout %.2f +- %.2f ms over %d photos; tie points %.4f m\n",
              1000.0 * tracked.readout_time_s, 1000.0 * tracked.sigma_s, tracked.images, from_track.point_rms_m);
  EXPECT_GT(tracked.images, static_cast<int>(rolling.truth.images.size()) / 2);
  EXPECT_NEAR(tracked.readout_time_s, 0.040, 0.004);
  EXPECT_LT(from_track.point_rms_m, 1.3 * known.point_rms_m);
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
