// SPDX-License-Identifier: BSD-3-Clause
// aerotri's Schur Levenberg–Marquardt (schur_lm_solver.h) against Ceres, the
// reference, on a survey's problem with every kind of residual it carries:
// the same optimum (cost, cameras, points, intrinsics), the same redundancy
// and precision, robust losses corrected as Ceres corrects them, and the
// solution within the injected noise of the truth (both bounds).
#include "libphoto/adjust/schur_lm_solver.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <utility>

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

// A problem built directly: nadir cameras (a quaternion each, on Ceres'
// manifold; a centre each, held by a GPS prior) sharing one focal length and
// a held principal point, points seen by the cameras they fall in, half the
// reprojections under Huber.
struct Reprojection {
  Reprojection(double x, double y) : x(x), y(y) {}
  template <typename T>
  bool operator()(const T* q, const T* c, const T* f, const T* pp, const T* X, T* r) const {
    const T d[3] = {X[0] - c[0], X[1] - c[1], X[2] - c[2]};
    T p[3];
    ceres::QuaternionRotatePoint(q, d, p);
    r[0] = f[0] * p[0] / p[2] + pp[0] - x;
    r[1] = f[0] * p[1] / p[2] + pp[1] - y;
    return true;
  }
  double x, y;
};
struct CentrePrior {
  template <typename T>
  bool operator()(const T* c, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = (c[i] - at[i]) / sigma;
    return true;
  }
  Eigen::Vector3d at;
  double sigma;
};

struct DirectProblem {
  std::vector<std::array<double, 4>> q;
  std::vector<Eigen::Vector3d> c;
  std::vector<Eigen::Vector3d> x;
  double f = 990.0;
  double pp[2] = {0.0, 0.0};
};

DirectProblem MakeDirect(int nx, int ny, int points, std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  DirectProblem p;
  for (int i = 0; i < nx * ny; ++i) {
    // Nadir: the camera's z down, x east, y south (a half turn about x).
    p.q.push_back({0.02 * g(rng), 1.0, 0.02 * g(rng), 0.02 * g(rng)});
    p.c.emplace_back(20.0 * (i % nx), 20.0 * (i / nx), 50.0);
  }
  for (int k = 0; k < points; ++k) {
    p.x.emplace_back(-20.0 + (20.0 * nx + 20.0) * u(rng), -20.0 + (20.0 * ny + 20.0) * u(rng), 2.0 * g(rng));
  }
  return p;
}

// The problem over `p`'s values as observed from `truth` (0.5 px noise),
// GPS on the centres at 5 cm.
void BuildDirect(const DirectProblem& truth, DirectProblem* p, std::mt19937& rng, ceres::Problem* problem,
                 std::vector<double*>* points, double noise = 1.0) {
  std::normal_distribution<double> normal(0.0, 1.0);
  auto g = [&](std::mt19937& r) { return noise * normal(r); };
  for (size_t i = 0; i < p->q.size(); ++i) {
    problem->AddParameterBlock(p->q[i].data(), 4, new ceres::QuaternionManifold);
    auto* prior = new ceres::AutoDiffCostFunction<CentrePrior, 3, 3>(
        new CentrePrior{truth.c[i] + 0.05 * Eigen::Vector3d(g(rng), g(rng), g(rng)), 0.05});
    problem->AddResidualBlock(prior, nullptr, p->c[i].data());
  }
  problem->AddParameterBlock(p->pp, 2);
  problem->SetParameterBlockConstant(p->pp);
  int k = 0;
  for (size_t j = 0; j < p->x.size(); ++j) {
    std::vector<std::pair<size_t, Eigen::Vector2d>> seen;  // points seen twice or more
    for (size_t i = 0; i < p->q.size(); ++i) {
      const Eigen::Vector3d d = truth.x[j] - truth.c[i];
      double cam[3];
      ceres::QuaternionRotatePoint(truth.q[i].data(), d.data(), cam);
      if (cam[2] <= 0.0) continue;
      const Eigen::Vector2d uv(truth.f * cam[0] / cam[2], truth.f * cam[1] / cam[2]);
      if (std::abs(uv.x()) < 600.0 && std::abs(uv.y()) < 450.0) seen.emplace_back(i, uv);
    }
    if (seen.size() < 2) continue;
    for (const auto& [i, uv] : seen) {
      auto* cost = new ceres::AutoDiffCostFunction<Reprojection, 2, 4, 3, 1, 2, 3>(
          new Reprojection(uv.x() + 0.5 * g(rng), uv.y() + 0.5 * g(rng)));
      problem->AddResidualBlock(cost, (k++ % 2 == 0) ? new ceres::HuberLoss(1.0) : nullptr, p->q[i].data(),
                                p->c[i].data(), &p->f, p->pp, p->x[j].data());
    }
    points->push_back(p->x[j].data());
  }
}

// The reduced system held sparse (CHOLMOD, as beyond the dense size) and
// held dense: the same steps, so the same optimum to rounding.
TEST(SchurLmSolver, SparseReducedSystemTakesTheSameStepsAsTheDenseOne) {
  std::mt19937 rng(5);
  // Normalised quaternions for the truth.
  DirectProblem truth = MakeDirect(7, 5, 600, rng);
  for (auto& q : truth.q) Eigen::Map<Eigen::Vector4d>(q.data()).normalize();
  DirectProblem start = truth;
  std::normal_distribution<double> g(0.0, 1.0);
  for (auto& c : start.c) c += 0.3 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  for (auto& x : start.x) x += 0.3 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  for (auto& q : start.q) {
    for (double& e : q) e += 0.002 * g(rng);
    Eigen::Map<Eigen::Vector4d>(q.data()).normalize();
  }
  start.f = 1010.0;

  struct Solved {
    DirectProblem p;
    ceres::Solver::Summary summary;
  };
  const auto solve = [&](ReducedStorage storage) {
    Solved s{start, {}};
    std::mt19937 noise(9);  // the same observations both times
    ceres::Problem problem;
    std::vector<double*> points;
    BuildDirect(truth, &s.p, noise, &problem, &points);
    ceres::Solver::Options options;
    options.max_num_iterations = 50;
    options.function_tolerance = 1e-14;
    options.parameter_tolerance = 1e-14;
    options.gradient_tolerance = 1e-14;
    options.num_threads = 2;
    std::string why_not;
    EXPECT_TRUE(SolveSchurLm(options, &problem, points, &s.summary, &why_not, storage)) << why_not;
    return s;
  };
  const Solved dense = solve(ReducedStorage::kDense), sparse = solve(ReducedStorage::kSparse);
  EXPECT_EQ(dense.summary.linear_solver_type_used, ceres::DENSE_SCHUR);
  EXPECT_EQ(sparse.summary.linear_solver_type_used, ceres::SPARSE_SCHUR);
  ASSERT_TRUE(dense.summary.IsSolutionUsable()) << dense.summary.message;
  ASSERT_TRUE(sparse.summary.IsSolutionUsable()) << sparse.summary.message;
  EXPECT_LT(sparse.summary.final_cost, 0.01 * sparse.summary.initial_cost);
  // Step by step: the same damped systems, the same costs to rounding (the
  // last steps, within 1e-14 of the cost, may stop the two a step apart).
  const size_t steps = std::min(dense.summary.iterations.size(), sparse.summary.iterations.size());
  EXPECT_GT(steps, 5u);
  EXPECT_LE(std::max(dense.summary.iterations.size(), sparse.summary.iterations.size()) - steps, 2u);
  for (size_t k = 0; k < steps; ++k) {
    const ceres::IterationSummary &a = sparse.summary.iterations[k], &b = dense.summary.iterations[k];
    EXPECT_EQ(a.step_is_successful, b.step_is_successful) << "iteration " << k;
    EXPECT_NEAR(a.cost, b.cost, 1e-10 * b.cost) << "iteration " << k;
  }
  EXPECT_NEAR(sparse.summary.final_cost, dense.summary.final_cost, 1e-10 * dense.summary.final_cost);
  EXPECT_NEAR(sparse.p.f, dense.p.f, 1e-7);
  double centres = 0.0, points = 0.0, truth_rms = 0.0;
  for (size_t i = 0; i < start.c.size(); ++i) {
    centres = std::max(centres, (sparse.p.c[i] - dense.p.c[i]).norm());
    truth_rms += (sparse.p.c[i] - truth.c[i]).squaredNorm();
  }
  for (size_t j = 0; j < start.x.size(); ++j) points = std::max(points, (sparse.p.x[j] - dense.p.x[j]).norm());
  EXPECT_LT(centres, 1e-7);
  EXPECT_LT(points, 1e-6);
  // Against the truth: the 5 cm GPS (8.7 cm in 3D) and 0.5 px (2.5 cm on the
  // ground) hold the centres to centimetres, not to nothing.
  truth_rms = std::sqrt(truth_rms / start.c.size());
  EXPECT_GT(truth_rms, 1e-3);
  EXPECT_LT(truth_rms, 0.1);
  EXPECT_NEAR(sparse.p.f, truth.f, 5.0);
}

// Solved again from its own optimum: the trials differ from the cost by
// rounding alone, and a rejected one ends the solve by the function
// tolerance as Ceres ends it, where rejections alone would shrink the region
// step by step down to its minimum.
TEST(SchurLmSolver, RejectedStepWithinTheFunctionToleranceConverges) {
  std::mt19937 rng(6);
  DirectProblem truth = MakeDirect(5, 4, 400, rng);
  for (auto& q : truth.q) Eigen::Map<Eigen::Vector4d>(q.data()).normalize();
  DirectProblem p = truth;
  std::mt19937 noise(8);
  ceres::Problem problem;
  std::vector<double*> points;
  BuildDirect(truth, &p, noise, &problem, &points);
  ceres::Solver::Options options;
  options.max_num_iterations = 100;
  options.function_tolerance = 0.0;
  options.parameter_tolerance = 0.0;
  options.gradient_tolerance = 0.0;
  ceres::Solver::Summary optimum;
  std::string why_not;
  ASSERT_TRUE(SolveSchurLm(options, &problem, points, &optimum, &why_not, ReducedStorage::kDense)) << why_not;
  int rejected = 0;
  for (int round = 0; round < 5; ++round) {
    options.function_tolerance = 1e-12;
    options.max_num_iterations = 50;
    ceres::Solver::Summary again;
    ASSERT_TRUE(SolveSchurLm(options, &problem, points, &again, &why_not, ReducedStorage::kDense)) << why_not;
    SCOPED_TRACE(again.FullReport());
    EXPECT_EQ(again.termination_type, ceres::CONVERGENCE) << again.message;
    EXPECT_NE(again.message.find("Function tolerance"), std::string::npos) << again.message;
    EXPECT_LE(again.iterations.size(), 3u);
    EXPECT_NEAR(again.final_cost, optimum.final_cost, 1e-11 * optimum.final_cost);
    for (const ceres::IterationSummary& it : again.iterations) rejected += it.step_is_successful ? 0 : 1;
  }
  EXPECT_GE(rejected, 1);  // the case this is about
}

// The survey adjustment's solves after the first start from the optimum of
// the one before (least squares after screening, each variance-component
// round after the last) and from the trust region it ended at. Restarted
// at Ceres' default radius each time, the region grew threefold a step to
// free the block's weakest directions again: here 3, 5 and 4 iterations for
// the least squares and two variance-component rounds (2, 3 and 2 warm),
// on the 513-photo bench survey 9 and 8 (5 and 4 warm).
TEST(SchurLmSolver, WarmStartedSolvesKeepTheTrustRegion) {
  SyntheticSurvey survey;
  const SparseModel start = SurveyWithPriors(23, &survey);
  BundleOptions o;  // the survey's tolerances (georeferencing.cc)
  o.engine = BundleEngine::kAerotri;
  o.cost_change_tolerance = 1e-6;
  o.function_tolerance = 1e-12;
  o.parameter_tolerance = 1e-12;
  o.gradient_tolerance = 1e-10;
  o.num_threads = 2;
  o.loss = LossType::kHuber;
  o.least_squares_after_screening = true;
  o.outlier_threshold_px = 4.0;
  o.estimate_variance_components = true;
  o.compute_precision = true;
  SparseModel warm = start;
  const BundleSummary a = AdjustBundle(&warm, o);
  ASSERT_TRUE(a.converged) << a.termination;
  std::string solves;
  for (const BundleSummary::Solve& s : a.solves) solves += s.kind + ": " + std::to_string(s.iterations) + "\n";
  SCOPED_TRACE(solves);
  ASSERT_GE(a.solves.size(), 3u);
  for (size_t k = 1; k < a.solves.size(); ++k) EXPECT_LE(a.solves[k].iterations, 3) << a.solves[k].kind;
  // The same optimum as Ceres' solver from the same start.
  o.engine = BundleEngine::kCeres;
  SparseModel ceres = start;
  const BundleSummary b = AdjustBundle(&ceres, o);
  EXPECT_NEAR(a.sigma0, b.sigma0, 1e-6);
  EXPECT_LT(MaxCentreDifference(warm, ceres), 1e-4);
}

}  // namespace
}  // namespace aerotri
