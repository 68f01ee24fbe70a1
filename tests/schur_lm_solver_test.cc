// SPDX-License-Identifier: BSD-3-Clause
// aerotri's Schur Levenberg–Marquardt (schur_lm_solver.h) against Ceres, the
// reference, on a survey's problem with every kind of residual it carries:
// the same optimum (cost, cameras, points, intrinsics), the same redundancy
// and precision, robust losses corrected as Ceres corrects them, and the
// solution within the injected noise of the truth (both bounds).
#include "libphoto/adjust/schur_lm_solver.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

// A small survey with GPS on every photo (5 / 10 cm), its control points
// surveyed (1 / 2 cm), one camera group, perturbed.
SparseModel SurveyWithPriors(std::uint32_t seed, SyntheticSurvey* out) {
  SyntheticSurveyOptions o;
  o.seed = seed;
  o.area_width_m = 160.0;
  o.area_height_m = 110.0;
  o.num_tie_points = 1200;
  o.pixel_noise_px = 0.5;
  *out = MakeSyntheticSurvey(o);
  SparseModel model = out->observed;
  std::mt19937 rng(seed);
  testing::AddGpsPriors(&model, out->truth, rng, 0.05, 0.1);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (size_t p = 0; p < model.points.size(); ++p) {
    if (model.points[p].role != PointRole::kControl) continue;
    const Eigen::Vector3d noise(0.01 * gauss(rng), 0.01 * gauss(rng), 0.02 * gauss(rng));
    model.points[p].prior = PositionPrior{out->truth.points[p].position + noise, 0.01, 0.02, std::nullopt};
  }
  testing::Perturb(&model, rng, 0.5, 0.3, 0.3, 0.005);
  return model;
}

BundleOptions Tight(BundleEngine engine) {
  BundleOptions o;
  o.engine = engine;
  o.function_tolerance = 1e-15;
  o.parameter_tolerance = 1e-15;
  o.gradient_tolerance = 1e-14;
  o.max_iterations = 200;
  o.num_threads = 2;
  return o;
}

double MaxCentreDifference(const SparseModel& a, const SparseModel& b) {
  double d = 0.0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    d = std::max(d, (a.images[i].pose.centre_in_world - b.images[i].pose.centre_in_world).norm());
  }
  return d;
}

double MaxPointDifference(const SparseModel& a, const SparseModel& b) {
  double d = 0.0;
  for (size_t p = 0; p < a.points.size(); ++p) d = std::max(d, (a.points[p].position - b.points[p].position).norm());
  return d;
}

// The same start solved by `options`' engine and by Ceres.
struct Both {
  SparseModel ours, ceres;
  BundleSummary a, b;
};
Both SolveBoth(const SparseModel& start, BundleOptions options) {
  Both r{start, start, {}, {}};
  r.a = AdjustBundle(&r.ours, options);
  options.engine = BundleEngine::kCeres;
  r.b = AdjustBundle(&r.ceres, options);
  return r;
}

// Screening (Huber), least squares, variance components and the precision
// pass, as the survey adjustment runs them: the same optimum to well under
// a micrometre and the same statistics.
TEST(SchurLmSolver, ReachesCeresOptimumOnASurveyWithPriors) {
  SyntheticSurvey survey;
  const SparseModel start = SurveyWithPriors(21, &survey);
  BundleOptions o = Tight(BundleEngine::kAuto);
  o.loss = LossType::kHuber;
  o.least_squares_after_screening = true;
  o.outlier_threshold_px = 4.0;
  o.estimate_variance_components = true;
  o.compute_precision = true;
  const Both r = SolveBoth(start, o);
  const SparseModel &ours = r.ours, &ceres = r.ceres;
  const BundleSummary &a = r.a, &b = r.b;
  SCOPED_TRACE(a.BriefReport() + "\n" + b.BriefReport());
  EXPECT_EQ(a.linear_solver, "aerotri_schur_lm");
  EXPECT_EQ(b.linear_solver, "dense_schur");
  ASSERT_TRUE(a.converged);
  ASSERT_TRUE(b.converged);
  EXPECT_GT(a.num_gcp_priors, 0);
  EXPECT_EQ(a.num_gps_priors, static_cast<int>(start.images.size()));
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-9 * b.final_cost);
  EXPECT_EQ(a.redundancy, b.redundancy);
  EXPECT_NEAR(a.sigma0, b.sigma0, 1e-8);
  EXPECT_LT(MaxCentreDifference(ours, ceres), 1e-6);
  EXPECT_LT(MaxPointDifference(ours, ceres), 1e-6);
  for (size_t k = 0; k < ours.cameras[0].params.size(); ++k) {
    EXPECT_NEAR(ours.cameras[0].params[k], ceres.cameras[0].params[k],
                1e-7 * (1.0 + std::abs(ceres.cameras[0].params[k])))
        << "intrinsic " << k;
  }
  ASSERT_TRUE(a.precision.computed);
  ASSERT_TRUE(b.precision.computed);
  ASSERT_EQ(a.variance_components.size(), b.variance_components.size());
  for (size_t g = 0; g < a.variance_components.size(); ++g) {
    EXPECT_NEAR(a.variance_components[g].scale, b.variance_components[g].scale, 1e-6) << "group " << g;
  }
  // Against the truth: the GPS (5 cm over dozens of photos) and the control
  // hold the datum; 0.5 px at ~2.7 cm a pixel puts the centres at a few mm
  // to a few cm, not at zero and not at the GPS noise.
  double sum = 0.0;
  for (size_t i = 0; i < ours.images.size(); ++i) {
    sum += (ours.images[i].pose.centre_in_world - survey.truth.images[i].pose.centre_in_world).squaredNorm();
  }
  const double rms = std::sqrt(sum / ours.images.size());
  EXPECT_GT(rms, 1e-3);
  EXPECT_LT(rms, 0.05);
}

// Huber throughout on data with gross blunders, nothing rejected: the loss's
// correction must be Ceres' for the two to meet.
TEST(SchurLmSolver, RobustLossCorrectedAsCeresCorrectsIt) {
  SyntheticSurvey survey;
  SparseModel start = SurveyWithPriors(22, &survey);
  std::mt19937 rng(22);
  std::uniform_int_distribution<size_t> pick(0, start.observations.size() - 1);
  int blunders = 0;
  for (int k = 0; k < 40; ++k) {
    Observation& obs = start.observations[pick(rng)];
    if (start.points[obs.point].role != PointRole::kTie) continue;
    obs.xy += Eigen::Vector2d(15.0, -12.0);
    ++blunders;
  }
  ASSERT_GT(blunders, 20);
  BundleOptions o = Tight(BundleEngine::kAerotri);
  o.loss = LossType::kHuber;
  o.outlier_threshold_px = 0.0;
  const Both r = SolveBoth(start, o);
  const SparseModel &ours = r.ours, &ceres = r.ceres;
  const BundleSummary &a = r.a, &b = r.b;
  SCOPED_TRACE(a.BriefReport() + "\n" + b.BriefReport());
  EXPECT_EQ(a.linear_solver, "aerotri_schur_lm");
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-9 * b.final_cost);
  EXPECT_LT(MaxCentreDifference(ours, ceres), 1e-6);
  EXPECT_LT(MaxPointDifference(ours, ceres), 1e-5);
  // The loss is what keeps the blunders from the cameras: least squares on
  // the same data moves them by centimetres.
  SparseModel plain = start;
  o.loss = LossType::kNone;
  AdjustBundle(&plain, o);
  EXPECT_GT(MaxCentreDifference(plain, ours), 1e-3);
}

}  // namespace
}  // namespace aerotri
