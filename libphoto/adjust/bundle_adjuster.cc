// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/bundle_adjuster.h"

#include <ceres/ceres.h>
#include <ceres/product_manifold.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <thread>
#include <unordered_map>

#include "libphoto/adjust/bundle_config.h"
#include "libphoto/adjust/bundle_precision.h"
#include "libphoto/adjust/dense_schur_solver.h"
#include "libphoto/adjust/schur_lm_solver.h"
#include "libphoto/adjust/position_prior_cost.h"
#include "libphoto/adjust/reprojection_cost.h"
#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The shift of the camera centre at an observation's row: zero for a
// global shutter.
Eigen::Vector3d CentreShiftOf(const Image& image, const Camera& camera, const Observation& obs) {
  if (!image.rolling_shutter) return Eigen::Vector3d::Zero();
  return image.rolling_shutter->CentreShift(obs.xy.y(), camera.height);
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return s;
}

// Forwards Ceres iterations to the user's callback and applies the
// optimality-gap stopping rule (BundleStopRule) to the accepted steps.
class IterationForwarder final : public ceres::IterationCallback {
 public:
  IterationForwarder(const std::function<void(const IterationReport&)>& fn, int round, double optimality_gap,
                     double cost_change_tolerance)
      : fn_(fn), round_(round), stop_(optimality_gap), cost_change_tolerance_(cost_change_tolerance) {}
  ceres::CallbackReturnType operator()(
      const ceres::IterationSummary& summary) override {
    if (fn_) {
      IterationReport report;
      report.iteration = summary.iteration;
      report.cost = summary.cost;
      report.time_s = summary.cumulative_time_in_seconds;
      report.round = round_;
      fn_(report);
    }
    if ((summary.iteration == 0 || summary.step_is_successful) && stop_.Accepted(summary.cost)) {
      reason_ = "the cost is within the optimality gap of its estimated optimum";
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    if (cost_change_tolerance_ > 0.0 && summary.iteration > 0 && summary.step_is_successful &&
        summary.cost_change < cost_change_tolerance_) {
      char text[160];
      std::snprintf(text, sizeof text, "a step lowered the cost by %.3g < %.3g (cost_change_tolerance)",
                    summary.cost_change, cost_change_tolerance_);
      reason_ = text;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }

  const std::string& Reason() const { return reason_; }

 private:
  const std::function<void(const IterationReport&)>& fn_;
  int round_;
  BundleStopRule stop_;
  double cost_change_tolerance_ = 0.0;
  std::string reason_;
};

std::unique_ptr<ceres::LossFunction> MakeLoss(const BundleOptions& options, double sigma_px) {
  // Residuals are divided by sigma_px, so a scale in pixels becomes scale/sigma.
  const double a = options.loss_scale_px / sigma_px;
  switch (options.loss) {
    case LossType::kNone:
      return nullptr;
    case LossType::kHuber:
      return std::make_unique<ceres::HuberLoss>(a);
    case LossType::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(a);
    case LossType::kTukey:
      return std::make_unique<ceres::TukeyLoss>(a);
  }
  return nullptr;
}

struct RoundResult {
  ceres::Solver::Summary ceres;
  std::string gauge;
  std::string solver;
  int num_observations = 0;
  int num_points = 0;
  int num_images = 0;
  int num_gps = 0;
  int num_gcp = 0;
  int skipped_points = 0;
  bool offset_estimated = false;
  bool drift_estimated = false;
  int num_attitude = 0;
  double setup_s = 0.0;
  std::vector<IntrinsicsPrecision> precision;
  std::string covariance_note;
  BundlePrecision posterior;  // a priori (unit weight) until AdjustBundle scales it
  // The precision pass's share of each observation group (index:
  // ObservationGroup; rows 0 where the group is absent).
  std::array<internal::GroupRedundancy, kNumObservationGroups> groups;
  std::string report;         // the aerotri engine's report (keep_solver_report)
  std::vector<std::vector<int>> refined_params;  // per camera group, as configured (BundleConfig::refined)
};

// Whether the intrinsics' covariance is computed for this problem; false
// with the reason in result->covariance_note where it is not.
bool IntrinsicsCovarianceApplies(ceres::Problem* problem, const SparseModel& model,
                                 const std::vector<std::vector<int>>& refined, const BundleOptions& options,
                                 RoundResult* result) {
  if (problem->NumResiduals() > options.max_covariance_residuals) {
    result->covariance_note = "not computed: " + std::to_string(problem->NumResiduals()) +
                              " residuals, above the limit of " + std::to_string(options.max_covariance_residuals);
    return false;
  }
  bool any_refined = false;
  for (size_t c = 0; c < model.cameras.size(); ++c) {
    const double* params = model.cameras[c].params.data();
    any_refined = any_refined || (!refined[c].empty() && problem->HasParameterBlock(params) &&
                                  !problem->IsParameterBlockConstant(params));
  }
  if (!any_refined) result->covariance_note = "no refined intrinsics in blocks of their own";
  return any_refined;
}

// The covariance of two reduced blocks of a precision solution (tangent
// coordinates, row-major); false where either is not a reduced block.
using BlockCovariance = std::function<bool(const double*, const double*, std::vector<double>*)>;

BlockCovariance BlockCovarianceOf(ceres::Problem* problem, const std::vector<double*>& reduced,
                                  const internal::PrecisionSolution& solution) {
  auto slot = std::make_shared<std::unordered_map<const double*, int>>();
  for (size_t k = 0; k < reduced.size(); ++k) slot->emplace(reduced[k], static_cast<int>(k));
  return [problem, slot, &solution](const double* a, const double* b, std::vector<double>* out) {
    const auto ia = slot->find(a), ib = slot->find(b);
    if (ia == slot->end() || ib == slot->end()) return false;
    const int oa = solution.reduced_offset[ia->second], ob = solution.reduced_offset[ib->second];
    const int na = problem->ParameterBlockTangentSize(const_cast<double*>(a));
    const int nb = problem->ParameterBlockTangentSize(const_cast<double*>(b));
    out->assign(static_cast<size_t>(na) * nb, 0.0);
    for (int r = 0; r < na; ++r) {
      for (int c = 0; c < nb; ++c) (*out)[r * nb + c] = solution.reduced_cov(oa + r, ob + c);
    }
    return true;
  };
}

// Each refined intrinsics block's sigmas and correlations, and its focal
// length's correlation with the camera heights, from the covariance.
void IntrinsicsPrecisionOf(ceres::Problem* problem, const SparseModel* model, const std::vector<char>& image_used,
                           const std::vector<std::vector<int>>& refined, const BlockCovariance& block_cov,
                           RoundResult* result) {
  for (size_t c = 0; c < model->cameras.size(); ++c) {
    const Camera& camera = model->cameras[c];
    const double* params = camera.params.data();
    if (refined[c].empty() || !problem->HasParameterBlock(params) || problem->IsParameterBlockConstant(params)) {
      continue;
    }
    const int n = static_cast<int>(refined[c].size());
    std::vector<double> cov;
    if (!block_cov(params, params, &cov) || static_cast<int>(cov.size()) != n * n) continue;
    IntrinsicsPrecision p;
    p.camera = static_cast<int>(c);
    for (int a = 0; a < n; ++a) {
      p.names.push_back(camera.info().param_names[refined[c][a]]);
      p.values.push_back(camera.params[refined[c][a]]);
      p.sigmas.push_back(std::sqrt(std::max(0.0, cov[a * n + a])));
    }
    p.correlation.assign(n, std::vector<double>(n, 0.0));
    for (int a = 0; a < n; ++a) {
      for (int b = 0; b < n; ++b) {
        const double d = p.sigmas[a] * p.sigmas[b];
        p.correlation[a][b] = d > 0.0 ? cov[a * n + b] / d : 0.0;
      }
    }
    // f against each camera height.
    const auto f_it = std::find(refined[c].begin(), refined[c].end(), camera.info().focal_params.at(0));
    if (f_it != refined[c].end()) {
      const int fi = static_cast<int>(f_it - refined[c].begin());
      std::vector<double> rho;
      for (size_t i = 0; i < model->images.size(); ++i) {
        const double* centre = model->images[i].pose.centre_in_world.data();
        if (!image_used[i] || model->images[i].camera != static_cast<int>(c) ||
            !problem->HasParameterBlock(centre) || problem->IsParameterBlockConstant(centre)) {
          continue;
        }
        std::vector<double> cross, cc;
        if (!block_cov(params, centre, &cross) || !block_cov(centre, centre, &cc) || cc.size() != 9u) continue;
        const double d = p.sigmas[fi] * std::sqrt(std::max(0.0, cc[8]));
        if (d > 0.0) rho.push_back(std::abs(cross[fi * 3 + 2]) / d);
      }
      if (!rho.empty()) {
        p.focal_height_correlation_max = *std::max_element(rho.begin(), rho.end());
        std::nth_element(rho.begin(), rho.begin() + rho.size() / 2, rho.end());
        p.focal_height_correlation_median = rho[rho.size() / 2];
      }
    }
    result->precision.push_back(p);
  }
}

// The a-priori covariance of every refined intrinsics block and its
// correlation with the camera heights (BundleOptions::
// compute_intrinsics_covariance), in a pass of its own: where the posterior
// precision pass runs, it computes them from its own solution instead.
void IntrinsicsCovariance(ceres::Problem* problem, SparseModel* model, const std::vector<char>& image_used,
                          const std::vector<std::vector<int>>& refined, const BundleOptions& options,
                          RoundResult* result) {
  if (!IntrinsicsCovarianceApplies(problem, *model, refined, options, result)) return;
  // Through the reduced camera system (bundle_precision.h): the points'
  // 3x3 blocks eliminated, the dense inverse over cameras, intrinsics and
  // offsets. Ceres' Covariance (a sparse QR of the whole Jacobian, points
  // included) took 954 s and 3.2 GB on a 131-photo block.
  auto varying = [&](const double* block) {
    return problem->HasParameterBlock(block) && !problem->IsParameterBlockConstant(block);
  };
  internal::PrecisionProblem pp;
  pp.problem = problem;
  pp.num_threads = options.num_threads > 0 ? options.num_threads
                                           : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  problem->GetResidualBlocks(&pp.adjusted);
  std::set<const double*> point_blocks;
  for (Point& point : model->points) {
    double* position = point.position.data();
    if (varying(position)) {
      pp.points.push_back(position);
      point_blocks.insert(position);
    }
  }
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  for (double* block : all) {
    if (point_blocks.count(block) || !varying(block)) continue;
    pp.reduced.push_back(block);
  }
  const internal::PrecisionSolution solution = internal::SolvePrecision(pp);
  if (!solution.ok) {
    result->covariance_note = "not computed: the normal equations are rank deficient (datum or intrinsics "
                              "not determined)" + (solution.note.empty() ? "" : ": " + solution.note);
    return;
  }
  IntrinsicsPrecisionOf(problem, model, image_used, refined, BlockCovarianceOf(problem, pp.reduced, solution), result);
}

// The gauge of a model without enough priors (BundleGauge other than
// kPriors): image A's pose before the solve and the length of the baseline
// from A to the farthest image B. Reprojection error is invariant under
// scale, so the solve leaves scale free (LM damping handles that
// one-dimensional null space) and this rescales about A exactly; holding a
// baseline coordinate fixed through a SubsetManifold instead costs Ceres its
// specialised Schur eliminator and, on the BAL problems, about twice the
// iterations. Applies Y = s Q (X − C_A') + C_A to every adjusted centre and
// point so that image A gets back its pose (free network) and |C_B − C_A|
// its length (BundleConfig::restore_scale).
void RestoreGauge(const BundleConfig& config, const Pose& pose_a, SparseModel* model) {
  if (config.image_a < 0) return;
  const bool restore_rotation = config.gauge == BundleGauge::kFreeNetwork;
  const Pose now = model->images[config.image_a].pose;
  const Eigen::Quaterniond q = restore_rotation ? pose_a.cam_from_world.conjugate() * now.cam_from_world
                                                : Eigen::Quaterniond::Identity();
  double s = 1.0;
  if (config.restore_scale && config.image_b >= 0) {
    const double len = (model->images[config.image_b].pose.centre_in_world - now.centre_in_world).norm();
    if (len > 0.0) s = config.baseline_m / len;
  }
  const Eigen::Vector3d c_new = now.centre_in_world;
  const Eigen::Vector3d c_old = restore_rotation ? pose_a.centre_in_world : c_new;
  auto map = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return s * (q * (x - c_new)) + c_old; };
  for (size_t i = 0; i < model->images.size(); ++i) {
    if (!config.image_used[i]) continue;
    Pose& pose = model->images[i].pose;
    pose.centre_in_world = map(pose.centre_in_world);
    pose.cam_from_world = (pose.cam_from_world * q.conjugate()).normalized();
  }
  for (size_t p = 0; p < model->points.size(); ++p) {
    if (config.point_used[p]) model->points[p].position = map(model->points[p].position);
  }
}

// The posterior precision of a solved problem (BundleOptions::
// compute_precision): the reduced camera system of bundle_precision.h over
// the problem's varying blocks, plus the independent check points,
// triangulated here with the cameras held, whose rows are added to the
// problem for their Jacobian only. A priori (unit weight); AdjustBundle
// scales it by σ0².
// Independent check points: triangulated from the adjusted cameras, their
// rays added to the problem as rows of the precision pass (not solved);
// the model points so placed.
std::vector<int> AddIndependentCheckPoints(ceres::Problem* problem, SparseModel* model,
                                           const std::vector<char>& image_used,
                                           std::vector<std::array<double, 4>>& rotations,
                                           const std::function<ceres::LossFunction*(double)>& loss_for,
                                           double mark_sigma, double mark_scale, internal::PrecisionProblem* pp) {
  std::vector<int> check_points;
  std::vector<std::vector<int>> obs_of_point(model->points.size());
  for (size_t k = 0; k < model->observations.size(); ++k) {
    const Observation& obs = model->observations[k];
    if (model->points[obs.point].role == PointRole::kCheck && image_used[obs.image]) {
      obs_of_point[obs.point].push_back(static_cast<int>(k));
    }
  }
  for (size_t p = 0; p < model->points.size(); ++p) {
    if (obs_of_point[p].size() < 2) continue;
    std::vector<View> views;
    for (int k : obs_of_point[p]) {
      const Observation& obs = model->observations[k];
      const Image& image = model->images[obs.image];
      const Camera& camera = model->cameras[image.camera];
      views.push_back({&camera, image.PoseAtRow(obs.xy.y(), camera.height), obs.xy});
    }
    const auto t = TriangulatePoint(views);
    if (!t) continue;
    Point& point = model->points[p];
    point.position = t->position;
    internal::PrecisionProblem::Rows rows;
    rows.position = point.position.data();
    for (int k : obs_of_point[p]) {
      const Observation& obs = model->observations[k];
      Image& image = model->images[obs.image];
      Camera& camera = model->cameras[image.camera];
      const double sigma = obs.sigma_px > 0.0 ? obs.sigma_px * mark_scale : mark_sigma;
      const Eigen::Vector3d shift = CentreShiftOf(image, camera, obs);
      ceres::CostFunction* cost = VisitCameraModel(camera.model, [&](auto m) -> ceres::CostFunction* {
        return new ReprojectionCost<decltype(m)>(obs.xy, sigma, shift);
      });
      rows.ids.push_back(problem->AddResidualBlock(cost, loss_for(sigma), rotations[obs.image].data(),
                                                   image.pose.centre_in_world.data(), rows.position,
                                                   camera.params.data()));
    }
    pp->checks.push_back(rows);
    check_points.push_back(static_cast<int>(p));
  }
  return check_points;
}

// θ of Exp(θ) R against Ceres' tangent δ of a quaternion: numerically,
// whatever the manifold's convention.
Eigen::Matrix3d ThetaFromTangent(const double* q) {
  const ceres::QuaternionManifold manifold;
  const Eigen::Quaterniond q0(q[0], q[1], q[2], q[3]);
  Eigen::Matrix3d d_theta;
  const double eps = 1e-6;
  for (int k = 0; k < 3; ++k) {
    double delta[3] = {0, 0, 0}, plus[4], minus[4];
    delta[k] = eps;
    manifold.Plus(q, delta, plus);
    delta[k] = -eps;
    manifold.Plus(q, delta, minus);
    const Eigen::AngleAxisd a(Eigen::Quaterniond(plus[0], plus[1], plus[2], plus[3]) * q0.conjugate());
    const Eigen::AngleAxisd b(Eigen::Quaterniond(minus[0], minus[1], minus[2], minus[3]) * q0.conjugate());
    d_theta.col(k) = (a.angle() * a.axis() - b.angle() * b.axis()) / (2.0 * eps);
  }
  return d_theta;
}

// A drift's covariance on E, N, U: held axes have no tangent, their rows
// and columns stay zero.
Eigen::Matrix3d DriftCovariance(const internal::PrecisionSolution& solution, int slot,
                                const std::array<bool, 3>& drift_axes) {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  if (slot < 0) return cov;
  const int o = solution.reduced_offset[slot];
  std::vector<int> axes;
  for (int a = 0; a < 3; ++a) {
    if (drift_axes[a]) axes.push_back(a);
  }
  for (size_t r = 0; r < axes.size(); ++r) {
    for (size_t c = 0; c < axes.size(); ++c) cov(axes[r], axes[c]) = solution.reduced_cov(o + r, o + c);
  }
  return cov;
}

// Baarda's w-test of each mark from its cofactor.
std::vector<MarkTest> MarkTests(const internal::PrecisionSolution& solution, const SparseModel& model,
                                const std::vector<int>& mark_observation, const std::vector<double>& mark_sigma_of) {
  std::vector<MarkTest> tests;
  for (size_t m = 0; m < solution.marks.size(); ++m) {
    const internal::MarkCofactor& c = solution.marks[m];
    MarkTest t;
    t.observation = mark_observation[m];
    t.point = model.observations[t.observation].point;
    t.image = model.observations[t.observation].image;
    t.residual_px = c.residual * mark_sigma_of[m];
    t.redundancy = c.qvv;
    for (int a = 0; a < 2; ++a) t.w[a] = c.qvv[a] > 1e-6 ? c.residual[a] / std::sqrt(c.qvv[a]) : 0.0;
    tests.push_back(t);
  }
  return tests;
}

// A withheld point's update applied: the new values of the blocks it
// touches, through their manifolds, as poses and intrinsics.
WithheldPoint WithheldOf(ceres::Problem* problem, const internal::PrecisionProblem& pp,
                         const internal::PrecisionSolution& solution, const internal::WithheldUpdate& u,
                         const SparseModel& model, int point, const std::vector<int>& rotation_slot,
                         const std::vector<int>& centre_slot, const std::vector<int>& camera_slot) {
  WithheldPoint w;
  w.point = point;
  w.position = model.points[point].position;
  if (!u.ok) {
    w.note = u.note;
    return w;
  }
  // The step of each touched block, and its value after it.
  std::map<int, std::vector<double>> stepped;  // reduced slot -> new value
  for (size_t c = 0; c < u.cols.size();) {
    const int slot = static_cast<int>(std::upper_bound(solution.reduced_offset.begin(),
                                                       solution.reduced_offset.end(), u.cols[c]) -
                                      solution.reduced_offset.begin()) - 1;
    double* block = pp.reduced[slot];
    const int tangent = problem->ParameterBlockTangentSize(block);
    const int size = problem->ParameterBlockSize(block);
    std::vector<double> delta(tangent), value(size);
    for (int k = 0; k < tangent; ++k) delta[k] = u.delta(static_cast<Eigen::Index>(c) + k);
    const ceres::Manifold* manifold = problem->GetManifold(block);
    if (manifold != nullptr) {
      manifold->Plus(block, delta.data(), value.data());
    } else {
      for (int k = 0; k < size; ++k) value[k] = block[k] + delta[k];
    }
    stepped.emplace(slot, std::move(value));
    c += static_cast<size_t>(tangent);
  }
  for (size_t i = 0; i < rotation_slot.size(); ++i) {
    const auto r = stepped.find(rotation_slot[i]);
    const auto t = stepped.find(centre_slot[i]);
    if (r == stepped.end() && t == stepped.end()) continue;
    Pose pose = model.images[i].pose;
    if (r != stepped.end() && rotation_slot[i] >= 0) {
      const std::vector<double>& q = r->second;
      pose.cam_from_world = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
    }
    if (t != stepped.end() && centre_slot[i] >= 0) pose.centre_in_world = Eigen::Vector3d(t->second.data());
    w.images.emplace_back(static_cast<int>(i), pose);
  }
  for (size_t c = 0; c < camera_slot.size(); ++c) {
    const auto it = camera_slot[c] >= 0 ? stepped.find(camera_slot[c]) : stepped.end();
    if (it != stepped.end()) w.cameras.emplace_back(static_cast<int>(c), it->second);
  }
  w.position += u.point_delta;
  w.computed = true;
  return w;
}

BundlePrecision PosteriorPrecision(ceres::Problem* problem, SparseModel* model, const std::vector<char>& image_used,
                                   const std::vector<char>& point_used,
                                   std::vector<std::array<double, 4>>& rotations, std::vector<double>* readout,
                                   const std::vector<std::pair<ceres::ResidualBlockId, int>>& mark_blocks,
                                   const std::function<ceres::LossFunction*(double)>& loss_for, double mark_sigma,
                                   const BundleOptions& options, std::vector<Eigen::Vector3d>* gps_offsets,
                                   std::vector<Eigen::Vector3d>* gps_drift,
                                   const std::array<internal::PrecisionProblem::Group, kNumObservationGroups>& groups,
                                   const std::vector<std::vector<int>>* intrinsics_refined, RoundResult* result) {
  const auto start = Clock::now();
  BundlePrecision out;
  internal::PrecisionProblem pp;
  pp.problem = problem;
  pp.num_threads = options.num_threads > 0 ? options.num_threads
                                           : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  problem->GetResidualBlocks(&pp.adjusted);
  auto varying = [&](double* block) {
    return problem->HasParameterBlock(block) && !problem->IsParameterBlockConstant(block);
  };
  std::vector<int> point_slot(model->points.size(), -1);
  for (size_t p = 0; p < model->points.size(); ++p) {
    double* position = model->points[p].position.data();
    if (!point_used[p] || !varying(position)) continue;
    point_slot[p] = static_cast<int>(pp.points.size());
    pp.points.push_back(position);
  }
  auto add_reduced = [&](double* block) {
    if (!varying(block)) return -1;
    pp.reduced.push_back(block);
    return static_cast<int>(pp.reduced.size()) - 1;
  };
  const size_t num_images = model->images.size();
  std::vector<int> rotation_slot(num_images, -1), centre_slot(num_images, -1);
  for (size_t i = 0; i < num_images; ++i) {
    if (!image_used[i]) continue;
    rotation_slot[i] = add_reduced(rotations[i].data());
    centre_slot[i] = add_reduced(model->images[i].pose.centre_in_world.data());
  }
  std::vector<int> camera_slot;
  for (Camera& camera : model->cameras) camera_slot.push_back(add_reduced(camera.params.data()));
  std::vector<int> offset_slot;
  for (Eigen::Vector3d& o : *gps_offsets) offset_slot.push_back(add_reduced(o.data()));
  std::vector<int> drift_slot;
  for (Eigen::Vector3d& d : *gps_drift) drift_slot.push_back(add_reduced(d.data()));
  std::vector<int> readout_slot;
  for (double& r : *readout) readout_slot.push_back(add_reduced(&r));

  std::vector<int> mark_observation;
  std::vector<double> mark_sigma_of;
  const double mark_scale = options.sigma_scale[static_cast<int>(ObservationGroup::kMarks)];
  for (const auto& [id, k] : mark_blocks) {
    const Observation& obs = model->observations[k];
    if (point_slot[obs.point] < 0) continue;
    internal::PrecisionProblem::Rows rows;
    rows.ids = {id};
    rows.point = point_slot[obs.point];
    pp.marks.push_back(rows);
    mark_observation.push_back(k);
    mark_sigma_of.push_back(obs.sigma_px > 0.0 ? obs.sigma_px * mark_scale : mark_sigma);
  }

  // The intrinsics' covariance from this pass's own solution, checked
  // before the check points join the problem.
  const bool intrinsics = intrinsics_refined != nullptr &&
                          IntrinsicsCovarianceApplies(problem, *model, *intrinsics_refined, options, result);
  // Independent check points: triangulated from the adjusted cameras.
  const std::vector<int> check_points =
      options.check_points_in_bundle
          ? std::vector<int>()
          : AddIndependentCheckPoints(problem, model, image_used, rotations, loss_for, mark_sigma, mark_scale, &pp);

  pp.groups.assign(groups.begin(), groups.end());
  std::vector<int> withheld_points;
  for (int p : options.withhold_points) {
    if (p < 0 || p >= static_cast<int>(model->points.size()) || point_slot[p] < 0) continue;
    withheld_points.push_back(p);
    pp.withheld.push_back(point_slot[p]);
  }
  pp.withhold_marks = !options.check_points_in_bundle;
  const internal::PrecisionSolution solution = internal::SolvePrecision(pp);
  if (!solution.ok) {
    out.note = "not computed: " + solution.note;
    return out;
  }
  auto block = [&](int slot) -> Eigen::Matrix3d {
    const int o = solution.reduced_offset[slot];
    return solution.reduced_cov.block<3, 3>(o, o);
  };
  for (size_t i = 0; i < num_images; ++i) {
    if (!image_used[i]) continue;
    ImagePrecision ip;
    ip.image = static_cast<int>(i);
    if (centre_slot[i] >= 0) ip.centre_cov = block(centre_slot[i]);
    if (rotation_slot[i] >= 0) {
      const Eigen::Matrix3d d_theta = ThetaFromTangent(rotations[i].data());
      ip.rotation_cov = d_theta * block(rotation_slot[i]) * d_theta.transpose();
    }
    out.images.push_back(ip);
  }
  for (size_t p = 0; p < model->points.size(); ++p) {
    if (point_slot[p] >= 0 && !solution.point_undetermined[point_slot[p]]) {
      out.points.push_back({static_cast<int>(p), solution.point_cov[point_slot[p]]});
    }
  }
  for (size_t k = 0; k < check_points.size(); ++k) out.points.push_back({check_points[k], solution.check_cov[k]});
  out.undetermined_points = solution.undetermined_points;
  if (!offset_slot.empty() && offset_slot[0] >= 0) {
    out.has_gps_offset = true;
    out.gps_offset_cov = block(offset_slot[0]);
  }
  if (options.gps_offset_per_flight) {
    for (int slot : offset_slot) {
      out.gps_flight_offset_cov.push_back(slot >= 0 ? Eigen::Matrix3d(block(slot)) : Eigen::Matrix3d::Zero());
    }
  }
  for (int slot : drift_slot) out.gps_drift_cov.push_back(DriftCovariance(solution, slot, options.gps_drift_axes));
  out.readout_var.assign(model->cameras.size(), 0.0);
  for (size_t c = 0; c < readout_slot.size(); ++c) {
    if (readout_slot[c] >= 0) {
      const int o = solution.reduced_offset[readout_slot[c]];
      out.readout_var[c] = solution.reduced_cov(o, o);
    }
  }
  out.marks = MarkTests(solution, *model, mark_observation, mark_sigma_of);
  for (size_t k = 0; k < solution.withheld.size(); ++k) {
    out.withheld.push_back(WithheldOf(problem, pp, solution, solution.withheld[k], *model, withheld_points[k],
                                      rotation_slot, centre_slot, camera_slot));
  }
  for (size_t g = 0; g < solution.groups.size() && g < result->groups.size(); ++g) {
    result->groups[g] = solution.groups[g];
  }
  if (intrinsics) {
    IntrinsicsPrecisionOf(problem, model, image_used, *intrinsics_refined,
                          BlockCovarianceOf(problem, pp.reduced, solution), result);
  }
  out.computed = true;
  out.time_s = SecondsSince(start);
  return out;
}

// precision_pass: no solve; the problem at the current values gives
// RoundResult::posterior (BundleOptions::compute_precision).

// The problem for aerotri's dense-Schur solver (BundleOptions::engine), when
// it applies: a free network (no priors) of reprojection residuals without a
// robust loss, every adjusted image in a merged block [q, C, intrinsics] of
// its own and a global shutter, one camera model, a reduced camera system of at most
// kMaxDenseSchurSize rows. Otherwise false with the reason.
bool MakeDenseSchurProblem(SparseModel* model, const BundleOptions& options, const std::vector<char>& image_used,
                           const std::vector<char>& point_used, const std::vector<std::vector<int>>& refined,
                           bool free_network, std::vector<std::vector<double>>* merged, DenseSchurProblem* problem,
                           std::string* why_not) {
  auto no = [&](const std::string& reason) {
    *why_not = reason;
    return false;
  };
  if (options.engine == BundleEngine::kCeres) return no("Ceres was asked for");
  if (options.linear_solver != LinearSolverChoice::kAuto && options.linear_solver != LinearSolverChoice::kDenseSchur) {
    return no("the linear solver " + ToString(options.linear_solver) + " was asked for");
  }
  if (options.loss != LossType::kNone) return no("a robust loss (" + ToString(options.loss) + ") is set");
  if (!free_network) return no("GPS or control priors hold the datum");
  if (!options.intrinsics_priors.empty()) return no("intrinsics priors are set");
  std::vector<int> camera_of_image(model->images.size(), -1);
  int size = 0;
  for (size_t i = 0; i < model->images.size(); ++i) {
    if (!image_used[i]) continue;
    const int c = model->images[i].camera;
    const Camera& camera = model->cameras[c];
    if ((*merged)[i].empty()) return no("image '" + model->images[i].name + "' shares its camera group or is held");
    if (model->images[i].rolling_shutter) return no("image '" + model->images[i].name + "' has a rolling shutter");
    if (problem->cameras.empty()) problem->model = camera.model;
    if (camera.model != problem->model) return no("the images use more than one camera model");
    if (c < static_cast<int>(options.focal_prior_px.size()) && options.focal_prior_px[c] > 0.0) {
      return no("a focal-length prior is set");
    }
    camera_of_image[i] = static_cast<int>(problem->cameras.size());
    problem->cameras.push_back((*merged)[i].data());
    std::vector<char> mask(camera.info().num_params(), 0);
    for (int k : refined[c]) mask[k] = 1;
    problem->refined.push_back(std::move(mask));
    size += 6 + camera.info().num_params();
  }
  if (problem->cameras.empty()) return no("no image to adjust");
  if (size > kMaxDenseSchurSize) {
    return no("the reduced camera system has " + std::to_string(size) + " rows, above " +
              std::to_string(kMaxDenseSchurSize));
  }
  std::vector<int> index_of_point(model->points.size(), -1);
  for (size_t p = 0; p < model->points.size(); ++p) {
    if (!point_used[p]) continue;
    index_of_point[p] = static_cast<int>(problem->points.size());
    problem->points.push_back(model->points[p].position.data());
  }
  const double mark_sigma = options.mark_sigma_px > 0.0 ? options.mark_sigma_px : options.observation_sigma_px;
  for (const Observation& obs : model->observations) {
    if (!image_used[obs.image] || !point_used[obs.point]) continue;
    const bool is_mark = model->points[obs.point].role != PointRole::kTie;
    const double sigma = obs.sigma_px > 0.0 ? obs.sigma_px : is_mark ? mark_sigma : options.observation_sigma_px;
    problem->observations.push_back(
        {camera_of_image[obs.image], index_of_point[obs.point], obs.xy.x(), obs.xy.y(), 1.0 / sigma});
  }
  return true;
}

// The aerotri engine's summary in the fields of Ceres' that AdjustBundle reads.
void FillCeresSummary(const DenseSchurSummary& s, ceres::Solver::Summary* out) {
  out->initial_cost = s.initial_cost;
  out->final_cost = s.final_cost;
  out->iterations.assign(s.iterations + 1, ceres::IterationSummary());
  out->termination_type = s.termination == "CONVERGENCE"      ? ceres::CONVERGENCE
                          : s.termination == "NO_CONVERGENCE" ? ceres::NO_CONVERGENCE
                                                              : ceres::FAILURE;
  out->message = s.message;
  out->total_time_in_seconds = s.time_s;
  out->num_residuals_reduced = s.num_residuals;
  out->num_effective_parameters_reduced = s.num_parameters;
}

// The parameter blocks of one solve that are not the model's own buffers:
// rotations in Ceres' order (w, x, y, z), and the merged blocks
// [q(4), C(3), intrinsics(N)] of BundleConfig::merged images.
struct ProblemBlocks {
  std::vector<std::array<double, 4>> rotations;
  std::vector<std::vector<double>> merged;
  // Per camera group, its rolling shutter's readout time when estimated
  // (BundleOptions::estimate_readout); empty otherwise.
  std::vector<double> readout;
  // Whether the group has such a block (it times a separate-block image).
  std::vector<char> readout_used;
};

// The photos the readout block of their group times: rolling shutters of
// their own camera blocks (a merged block keeps its stated readout).
bool TimedByReadout(const Image& image, const BundleConfig& config, size_t i) {
  return image.rolling_shutter.has_value() && config.image_used[i] && !config.merged[i];
}

ProblemBlocks MakeProblemBlocks(const SparseModel& model, const BundleConfig& config, bool estimate_readout) {
  ProblemBlocks blocks;
  blocks.rotations.resize(model.images.size());
  blocks.merged.resize(model.images.size());
  if (estimate_readout) {
    // The start: the median of the group's stated readouts (zero when none
    // is stated; the residuals are linear in it).
    std::vector<std::vector<double>> stated(model.cameras.size());
    for (size_t i = 0; i < model.images.size(); ++i) {
      const Image& image = model.images[i];
      if (TimedByReadout(image, config, i)) stated[image.camera].push_back(image.rolling_shutter->readout_time_s);
    }
    blocks.readout.assign(model.cameras.size(), 0.0);
    blocks.readout_used.assign(model.cameras.size(), 0);
    for (size_t c = 0; c < stated.size(); ++c) {
      if (stated[c].empty()) continue;
      std::nth_element(stated[c].begin(), stated[c].begin() + stated[c].size() / 2, stated[c].end());
      blocks.readout[c] = stated[c][stated[c].size() / 2];
      blocks.readout_used[c] = 1;
    }
  }
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (!config.image_used[i]) continue;
    const Image& image = model.images[i];
    const Eigen::Quaterniond q = image.pose.cam_from_world.normalized();
    blocks.rotations[i] = {q.w(), q.x(), q.y(), q.z()};
    if (config.merged[i]) {
      const Camera& camera = model.cameras[image.camera];
      std::vector<double>& m = blocks.merged[i];
      m = {q.w(), q.x(), q.y(), q.z()};
      for (int k = 0; k < 3; ++k) m.push_back(image.pose.centre_in_world[k]);
      m.insert(m.end(), camera.params.begin(), camera.params.end());
    }
  }
  return blocks;
}

// The solved blocks back into the model, and the gauge restored.
void WriteBack(const ProblemBlocks& blocks, const BundleConfig& config, const Pose& pose_a, SparseModel* model) {
  for (size_t i = 0; i < model->images.size(); ++i) {
    if (!config.image_used[i]) continue;
    Image& image = model->images[i];
    const bool merged = !blocks.merged[i].empty();
    const double* q = merged ? blocks.merged[i].data() : blocks.rotations[i].data();
    image.pose.cam_from_world = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
    if (!blocks.readout.empty() && TimedByReadout(image, config, i)) {
      image.rolling_shutter->readout_time_s = blocks.readout[image.camera];
    }
    if (merged) {
      for (int k = 0; k < 3; ++k) image.pose.centre_in_world[k] = blocks.merged[i][4 + k];
      Camera& camera = model->cameras[image.camera];
      std::copy(blocks.merged[i].begin() + 7, blocks.merged[i].end(), camera.params.begin());
    }
  }
  if (config.gauge != BundleGauge::kPriors) RestoreGauge(config, pose_a, model);
}

// One Ceres problem built from a BundleConfig: each kind of residual and
// constraint added by its own method, in the order SolveOnce calls them.
class CeresBundleProblem {
 public:
  CeresBundleProblem(SparseModel* model, const BundleOptions& options, const BundleConfig& config,
                     ProblemBlocks* blocks, RoundResult* result)
      : model_(model), options_(options), config_(config), blocks_(blocks), result_(result),
        problem_(ProblemOptions()) {
    mark_sigma_ = options.mark_sigma_px > 0.0 ? options.mark_sigma_px : options.observation_sigma_px;
    mark_sigma_ *= Scale(ObservationGroup::kMarks);
  }

  // The factor on a group's stated sigmas (variance components).
  double Scale(ObservationGroup g) const { return options_.sigma_scale[static_cast<int>(g)]; }
  // The adjustment's rows by observation group (bundle_precision.h).
  const std::array<internal::PrecisionProblem::Group, kNumObservationGroups>& groups() const { return groups_; }

  ceres::Problem& problem() { return problem_; }
  double mark_sigma() const { return mark_sigma_; }
  const std::vector<std::pair<ceres::ResidualBlockId, int>>& mark_blocks() const { return mark_blocks_; }

  // One loss per image sigma (its scale is in pixels, the residual in sigmas).
  ceres::LossFunction* LossFor(double sigma) {
    auto it = losses_.find(sigma);
    if (it == losses_.end()) it = losses_.emplace(sigma, MakeLoss(options_, sigma)).first;
    return it->second.get();
  }

  // Reprojection of every observation of a used point in a used image;
  // target marks (control and check points) have their own image sigma, and
  // any measurement may state its own.
  void AddReprojections() {
    for (size_t k = 0; k < model_->observations.size(); ++k) {
      const Observation& obs = model_->observations[k];
      if (!config_.image_used[obs.image] || !config_.point_used[obs.point]) continue;
      Image& image = model_->images[obs.image];
      Camera& camera = model_->cameras[image.camera];
      double* point = model_->points[obs.point].position.data();
      const bool is_merged = config_.merged[obs.image];
      const bool is_mark = model_->points[obs.point].role != PointRole::kTie;
      const double sigma =
          obs.sigma_px > 0.0 ? obs.sigma_px * Scale(is_mark ? ObservationGroup::kMarks : ObservationGroup::kTies)
          : is_mark          ? mark_sigma_
                             : options_.observation_sigma_px * Scale(ObservationGroup::kTies);
      const Eigen::Vector3d shift = CentreShiftOf(image, camera, obs);
      const bool timed = !blocks_->readout.empty() && TimedByReadout(image, config_, obs.image);
      ceres::CostFunction* cost = VisitCameraModel(camera.model, [&](auto m) -> ceres::CostFunction* {
        using Model = decltype(m);
        if (is_merged) return new ReprojectionCostMergedCamera<Model>(obs.xy, sigma, shift);
        if (timed) {
          const double fraction = (obs.xy.y() - 0.5 * (camera.height - 1)) / std::max(1, camera.height);
          return new RollingShutterReprojectionCost<Model>(obs.xy, sigma, fraction, image.rolling_shutter->velocity);
        }
        return new ReprojectionCost<Model>(obs.xy, sigma, shift);
      });
      ceres::ResidualBlockId id;
      if (is_merged) {
        id = problem_.AddResidualBlock(cost, LossFor(sigma), blocks_->merged[obs.image].data(), point);
      } else if (timed) {
        id = problem_.AddResidualBlock(cost, LossFor(sigma), blocks_->rotations[obs.image].data(),
                                       image.pose.centre_in_world.data(), point, camera.params.data(),
                                       &blocks_->readout[image.camera]);
      } else {
        id = problem_.AddResidualBlock(cost, LossFor(sigma), blocks_->rotations[obs.image].data(),
                                       image.pose.centre_in_world.data(), point, camera.params.data());
      }
      if (is_mark) mark_blocks_.emplace_back(id, static_cast<int>(k));
      AddToGroup(is_mark ? ObservationGroup::kMarks : ObservationGroup::kTies, id, 0b11);
    }
  }

  // GPS priors, through the shared offset block when it is estimated and the
  // flight's drift rate when drift is. Without a control prior the offset
  // and the block's translation are one freedom: the offset then stays where
  // it is.
  void AddGpsPriors(std::vector<Eigen::Vector3d>* gps_offsets, std::vector<Eigen::Vector3d>* gps_drift) {
    if (!options_.use_gps_priors) return;
    std::set<int> drifting_flights;
    const bool lever_arm = !options_.gnss_lever_arm_m.isZero();
    for (size_t i = 0; i < model_->images.size(); ++i) {
      Image& image = model_->images[i];
      if (!config_.image_used[i] || !image.gps_prior) continue;
      PositionPrior p = *image.gps_prior;
      p.sigma_h_m *= Scale(ObservationGroup::kGpsHorizontal);
      p.sigma_v_m *= Scale(ObservationGroup::kGpsVertical);
      ceres::ResidualBlockId id = nullptr;
      double* centre = image.pose.centre_in_world.data();
      double* rotation = blocks_->rotations[i].data();
      // The shared offset, or the flight's own.
      const int offset_index = gps_offsets->size() > 1 && p.flight >= 0 &&
                                       p.flight < static_cast<int>(gps_offsets->size())
                                   ? p.flight
                                   : 0;
      double* gps_offset = (*gps_offsets)[offset_index].data();
      const bool drift =
          options_.estimate_gps_drift && p.flight >= 0 && p.flight < static_cast<int>(gps_drift->size());
      if (drift) {
        // The offset block is always present (held below unless estimated).
        double* rate = (*gps_drift)[p.flight].data();
        if (lever_arm) {
          id = problem_.AddResidualBlock(MakeDriftLeverArmPriorCost(p.position, p.sigma_h_m, p.sigma_v_m,
                                                               options_.gnss_lever_arm_m, p.time_from_flight_s),
                                    nullptr, rotation, centre, gps_offset, rate);
        } else {
          id = problem_.AddResidualBlock(
              new DriftPositionPriorCost(p.position, p.sigma_h_m, p.sigma_v_m, p.time_from_flight_s), nullptr,
              centre, gps_offset, rate);
        }
        drifting_flights.insert(p.flight);
      } else if (lever_arm) {
        ceres::CostFunction* cost = MakeLeverArmPriorCost(p.position, p.sigma_h_m, p.sigma_v_m,
                                                          options_.gnss_lever_arm_m, options_.estimate_gps_offset);
        if (options_.estimate_gps_offset) {
          id = problem_.AddResidualBlock(cost, nullptr, rotation, centre, gps_offset);
        } else {
          id = problem_.AddResidualBlock(cost, nullptr, rotation, centre);
        }
      } else if (options_.estimate_gps_offset) {
        id = problem_.AddResidualBlock(new OffsetPositionPriorCost(p.position, p.sigma_h_m, p.sigma_v_m), nullptr,
                                       centre, gps_offset);
      } else {
        id = problem_.AddResidualBlock(new PositionPriorCost(p.position, p.sigma_h_m, p.sigma_v_m), nullptr, centre);
      }
      // Residuals (E, N) / σh and U / σv.
      AddToGroup(ObservationGroup::kGpsHorizontal, id, 0b011);
      AddToGroup(ObservationGroup::kGpsVertical, id, 0b100);
      ++result_->num_gps;
    }
    for (Eigen::Vector3d& offset : *gps_offsets) {
      if (!problem_.HasParameterBlock(offset.data())) continue;
      if (options_.estimate_gps_offset && NumControlPriors() > 0) {
        result_->offset_estimated = true;
      } else {
        problem_.SetParameterBlockConstant(offset.data());
      }
    }
    // Each drifting flight's rate varies on the chosen axes only.
    std::vector<int> held_axes;
    for (int a = 0; a < 3; ++a) {
      if (!options_.gps_drift_axes[a]) held_axes.push_back(a);
    }
    for (int f : drifting_flights) {
      double* rate = (*gps_drift)[f].data();
      if (held_axes.size() == 3) {
        problem_.SetParameterBlockConstant(rate);
        continue;
      }
      if (!held_axes.empty()) {
        owned_manifolds_.push_back(std::make_unique<ceres::SubsetManifold>(3, held_axes));
        problem_.SetManifold(rate, owned_manifolds_.back().get());
      }
      result_->drift_estimated = true;
    }
  }

  // The attitude prior: in every adjusted image the world's down where the
  // options say (a nadir block's optical axis, an oblique photo's gimbal).
  void AddAttitudePriors() {
    if (!(options_.attitude_prior_sigma_deg > 0.0)) return;
    const double inv_sigma = 1.0 / (options_.attitude_prior_sigma_deg * M_PI / 180.0);
    const std::vector<Eigen::Vector3d>& down = options_.attitude_prior_down_in_camera;
    for (size_t i = 0; i < model_->images.size(); ++i) {
      if (!config_.image_used[i] || config_.merged[i]) continue;
      const Eigen::Vector3d d = down.empty() ? Eigen::Vector3d::UnitZ() : i < down.size() ? down[i]
                                                                                          : Eigen::Vector3d::Zero();
      if (!(d.norm() > 0.0)) continue;
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<AttitudePrior, 2, 4>(
                                    new AttitudePrior{d.normalized(), inv_sigma}),
                                nullptr, blocks_->rotations[i].data());
      ++result_->num_attitude;
    }
  }

  // Focal-length priors from EXIF and a calibration certificate's priors on
  // single parameters (only on parameters that vary).
  void AddIntrinsicsPriors() {
    for (size_t c = 0; c < model_->cameras.size() && c < options_.focal_prior_px.size(); ++c) {
      Camera& camera = model_->cameras[c];
      const double f0 = options_.focal_prior_px[c];
      if (!(f0 > 0) || !config_.camera_used[c] || !problem_.HasParameterBlock(camera.params.data())) continue;
      const int index = camera.info().focal_params.at(0);
      problem_.AddResidualBlock(
          new ParameterPriorCost(camera.info().num_params(), index, f0, options_.focal_prior_sigma_rel * f0), nullptr,
          camera.params.data());
    }
    for (const BundleOptions::IntrinsicPrior& prior : options_.intrinsics_priors) {
      if (prior.camera < 0 || prior.camera >= static_cast<int>(model_->cameras.size())) continue;
      const std::vector<int>& refined = config_.refined[prior.camera];
      if (!config_.camera_used[prior.camera] || !std::binary_search(refined.begin(), refined.end(), prior.param)) {
        continue;  // held or not adjusted: a prior has nothing to weigh
      }
      Camera& camera = model_->cameras[prior.camera];
      problem_.AddResidualBlock(
          new ParameterPriorCost(camera.info().num_params(), prior.param, prior.value, prior.sigma), nullptr,
          camera.params.data());
    }
  }

  // Surveyed positions of control points (full covariance when given).
  void AddControlPriors() {
    if (!options_.use_gcp_priors) return;
    for (size_t p = 0; p < model_->points.size(); ++p) {
      Point& point = model_->points[p];
      if (!config_.point_used[p] || point.role != PointRole::kControl || !point.prior) continue;
      const PositionPrior& prior = *point.prior;
      const double f = Scale(ObservationGroup::kControl);
      const ceres::ResidualBlockId id = problem_.AddResidualBlock(
          prior.covariance ? new PositionPriorCost(prior.position, f * f * *prior.covariance)
                           : new PositionPriorCost(prior.position, f * prior.sigma_h_m, f * prior.sigma_v_m),
          nullptr, point.position.data());
      AddToGroup(ObservationGroup::kControl, id, 0b111);
      ++result_->num_gcp;
    }
  }

  // Manifolds (quaternions, merged blocks, intrinsics held in part) and the
  // blocks the gauge holds.
  void SetManifoldsAndHeldBlocks() {
    for (size_t i = 0; i < model_->images.size(); ++i) {
      if (!config_.image_used[i]) continue;
      const int c = model_->images[i].camera;
      if (config_.merged[i]) {
        owned_manifolds_.push_back(
            std::make_unique<ceres::ProductManifold<ceres::QuaternionManifold, ceres::EuclideanManifold<3>,
                                                    ceres::SubsetManifold>>(
                ceres::QuaternionManifold{}, ceres::EuclideanManifold<3>{},
                ceres::SubsetManifold(model_->cameras[c].info().num_params(), config_.ConstantParams(*model_, c))));
        problem_.SetManifold(blocks_->merged[i].data(), owned_manifolds_.back().get());
        continue;
      }
      problem_.SetManifold(blocks_->rotations[i].data(), &quaternion_manifold_);
      if (config_.HoldsRotationOf(static_cast<int>(i))) {
        problem_.SetParameterBlockConstant(blocks_->rotations[i].data());
      }
      if (config_.HoldsCentreOf(static_cast<int>(i))) {
        problem_.SetParameterBlockConstant(model_->images[i].pose.centre_in_world.data());
      }
    }
    for (size_t c = 0; c < model_->cameras.size(); ++c) {
      Camera& camera = model_->cameras[c];
      if (!config_.camera_used[c] || !problem_.HasParameterBlock(camera.params.data())) continue;
      const int n = camera.info().num_params();
      if (config_.refined[c].empty()) {
        problem_.SetParameterBlockConstant(camera.params.data());
      } else if (static_cast<int>(config_.refined[c].size()) < n) {
        owned_manifolds_.push_back(std::make_unique<ceres::SubsetManifold>(n, config_.ConstantParams(*model_, c)));
        problem_.SetManifold(camera.params.data(), owned_manifolds_.back().get());
      }
    }
  }

  // The points the Schur elimination takes first (SchurOrdering's group 0).
  std::vector<double*> EliminatedPoints() const {
    std::vector<double*> points;
    for (size_t p = 0; p < model_->points.size(); ++p) {
      if (config_.point_used[p] && !HasControlPrior(p)) points.push_back(model_->points[p].position.data());
    }
    return points;
  }

  // Schur elimination order: points first, then everything else.
  std::shared_ptr<ceres::ParameterBlockOrdering> SchurOrdering(std::vector<Eigen::Vector3d>* gps_offsets,
                                                               std::vector<Eigen::Vector3d>* gps_drift) {
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (size_t p = 0; p < model_->points.size(); ++p) {
      if (!config_.point_used[p]) continue;
      ordering->AddElementToGroup(model_->points[p].position.data(), HasControlPrior(p) ? 1 : 0);
    }
    for (size_t i = 0; i < model_->images.size(); ++i) {
      if (!config_.image_used[i]) continue;
      if (config_.merged[i]) {
        ordering->AddElementToGroup(blocks_->merged[i].data(), 1);
      } else {
        ordering->AddElementToGroup(blocks_->rotations[i].data(), 1);
        ordering->AddElementToGroup(model_->images[i].pose.centre_in_world.data(), 1);
      }
    }
    for (size_t c = 0; c < model_->cameras.size(); ++c) {
      if (config_.camera_used[c] && problem_.HasParameterBlock(model_->cameras[c].params.data())) {
        ordering->AddElementToGroup(model_->cameras[c].params.data(), 1);
      }
    }
    for (Eigen::Vector3d& o : *gps_offsets) {
      if (problem_.HasParameterBlock(o.data())) ordering->AddElementToGroup(o.data(), 1);
    }
    for (Eigen::Vector3d& d : *gps_drift) {
      if (problem_.HasParameterBlock(d.data())) ordering->AddElementToGroup(d.data(), 1);
    }
    for (double& r : blocks_->readout) {
      if (problem_.HasParameterBlock(&r)) ordering->AddElementToGroup(&r, 1);
    }
    return ordering;
  }

 private:
  static ceres::Problem::Options ProblemOptions() {
    ceres::Problem::Options o;
    o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    // Blocks are distinct buffers by construction and the model was validated.
    o.disable_all_safety_checks = true;
    return o;
  }

  // A control point with its surveyed position as a prior (AddControlPriors).
  bool HasControlPrior(size_t p) const {
    const Point& point = model_->points[p];
    return options_.use_gcp_priors && config_.point_used[p] && point.role == PointRole::kControl &&
           point.prior.has_value();
  }

  int NumControlPriors() const {
    int n = 0;
    for (size_t p = 0; p < model_->points.size(); ++p) n += HasControlPrior(p);
    return n;
  }

  SparseModel* model_;
  const BundleOptions& options_;
  const BundleConfig& config_;
  ProblemBlocks* blocks_;
  RoundResult* result_;
  // Owned here, outliving the problem (declared before it).
  std::map<double, std::unique_ptr<ceres::LossFunction>> losses_;
  ceres::QuaternionManifold quaternion_manifold_;
  std::vector<std::unique_ptr<ceres::Manifold>> owned_manifolds_;
  ceres::Problem problem_;
  double mark_sigma_ = 1.0;
  std::vector<std::pair<ceres::ResidualBlockId, int>> mark_blocks_;
  std::array<internal::PrecisionProblem::Group, kNumObservationGroups> groups_;

  void AddToGroup(ObservationGroup g, ceres::ResidualBlockId id, unsigned mask) {
    if (options_.compute_precision) groups_[static_cast<int>(g)].rows.emplace_back(id, mask);
  }
};

ceres::Solver::Options SolverOptions(const BundleOptions& options, int num_images, std::string* solver_name) {
  ceres::Solver::Options solver_options;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  if (options.max_time_s > 0.0) solver_options.max_solver_time_in_seconds = options.max_time_s;
  solver_options.num_threads =
      options.num_threads > 0 ? options.num_threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  solver_options.logging_type = ceres::SILENT;

  LinearSolverChoice solver = options.linear_solver;
  if (solver == LinearSolverChoice::kAuto) {
    solver = num_images <= 250    ? LinearSolverChoice::kDenseSchur
             : num_images <= 3000 ? LinearSolverChoice::kSparseSchur
                                  : LinearSolverChoice::kIterativeSchur;
  }
  switch (solver) {
    case LinearSolverChoice::kAuto:
    case LinearSolverChoice::kDenseSchur:
      solver_options.linear_solver_type = ceres::DENSE_SCHUR;
      break;
    case LinearSolverChoice::kSparseSchur:
      solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
      break;
    case LinearSolverChoice::kIterativeSchur:
      solver_options.linear_solver_type = ceres::ITERATIVE_SCHUR;
      solver_options.preconditioner_type = ceres::SCHUR_JACOBI;
      solver_options.use_explicit_schur_complement = true;
      break;
  }
  *solver_name = ToString(solver);
  return solver_options;
}

// aerotri's own dense-Schur solver, when the configuration allows it
// (BundleOptions::engine); false (with *why_not) when it does not.
bool SolveWithDenseSchur(SparseModel* model, const BundleOptions& options, const BundleConfig& config, int round,
                         ProblemBlocks* blocks, RoundResult* result, std::string* why_not) {
  DenseSchurProblem schur;
  if (!MakeDenseSchurProblem(model, options, config.image_used, config.point_used, config.refined,
                             config.gauge == BundleGauge::kFreeNetwork, &blocks->merged, &schur, why_not)) {
    return false;
  }
  DenseSchurOptions so;
  so.max_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.optimality_gap = options.optimality_gap;
  so.max_time_s = options.max_time_s;
  so.num_threads = options.num_threads;
  if (options.iteration_callback) {
    so.iteration_callback = [&](int iteration, double cost, double time_s) {
      options.iteration_callback(IterationReport{iteration, cost, time_s, round});
    };
  }
  const DenseSchurSummary summary = SolveDenseSchur(schur, so);
  result->solver = "aerotri_dense_schur";
  FillCeresSummary(summary, &result->ceres);
  if (options.keep_solver_report) result->report = summary.Report();
  if (options.compute_intrinsics_covariance) {
    result->covariance_note = "not computed: images with a camera group of their own";
  }
  return true;
}

// The solve: aerotri's Schur Levenberg–Marquardt where it takes the problem
// (BundleOptions::engine auto or aerotri, the linear solver auto or dense
// Schur), else Ceres.
void SolveProblem(const BundleOptions& options, const ceres::Solver::Options& solver_options,
                  const std::vector<double*>& points, ceres::Problem* problem, RoundResult* result) {
  std::string why_not;
  const bool dense = options.linear_solver == LinearSolverChoice::kAuto ||
                     options.linear_solver == LinearSolverChoice::kDenseSchur;
  if (!dense) why_not = "the linear solver " + ToString(options.linear_solver) + " was asked for";
  const bool ours = options.engine != BundleEngine::kCeres && dense;
  if (ours && SolveSchurLm(solver_options, problem, points, &result->ceres, &why_not, options.reduced_storage)) {
    result->solver =
        result->ceres.linear_solver_type_used == ceres::SPARSE_SCHUR ? "aerotri_schur_lm_sparse" : "aerotri_schur_lm";
    return;
  }
  if (options.engine == BundleEngine::kAerotri) {
    throw InvalidArgument("bundle adjustment: the aerotri engine does not apply: " + why_not);
  }
  ceres::Solve(solver_options, problem, &result->ceres);
}

// A solve's problem, kept for the precision pass that follows it at the
// same weights (BundleRun::kept): the pass evaluates the problem the solve
// left at its optimum instead of building it again (at 513 photos a build
// is several seconds on one thread: 2.2 million residual blocks through
// Ceres' maps). The bundle refers to the members, so the whole is held by
// pointer.
struct BuiltProblem {
  BundleOptions options;
  BundleConfig config;
  ProblemBlocks blocks;
  RoundResult counts;  // what the build counted (priors, offsets, drift)
  Pose pose_a;
  int round = -1;           // the solve that built it
  size_t observations = 0;  // the model's then: nothing may have left since
  std::unique_ptr<CeresBundleProblem> bundle;
};

// Whether `kept` is the problem a precision pass at `options` in `round`
// would build: the solve just before, at the same weights and loss, on the
// same observations.
bool ServesPass(const BuiltProblem& kept, const BundleOptions& options, int round, const SparseModel& model) {
  return kept.bundle && kept.round == round - 1 && kept.options.sigma_scale == options.sigma_scale &&
         kept.options.loss == options.loss && kept.options.loss_scale_px == options.loss_scale_px &&
         kept.observations == model.observations.size();
}

// One solve (or, with precision_pass, the posterior precision of the
// current state; with covariance_pass, the intrinsics' covariance of it):
// configure, build, solve, write back. gps_offsets (one shared, or one per
// flight) and gps_drift (per flight) are the GPS offsets and drift rates,
// in and out. start_radius > 0: the solve starts from that trust region
// (a warm start, BundleRun::trust_radius) instead of Ceres' default.
RoundResult SolveOnce(SparseModel* model, const BundleOptions& options, int round,
                      std::vector<Eigen::Vector3d>* gps_offsets, std::vector<Eigen::Vector3d>* gps_drift,
                      bool precision_pass = false, bool covariance_pass = false, double start_radius = 0.0,
                      std::unique_ptr<BuiltProblem>* keep = nullptr) {
  const auto setup_start = Clock::now();
  // The last solve's problem serves the pass right after it; anything else
  // frees it before building its own (never two problems at once).
  std::unique_ptr<BuiltProblem> built;
  if (keep != nullptr) {
    if (precision_pass && *keep && ServesPass(**keep, options, round, *model)) built = std::move(*keep);
    keep->reset();
  }
  const bool reused = built != nullptr;
  if (!reused) {
    built = std::make_unique<BuiltProblem>();
    built->options = options;
    built->config = ConfigureBundle(*model, options);
    built->pose_a = built->config.image_a >= 0 ? model->images[built->config.image_a].pose : Pose();
    built->blocks = MakeProblemBlocks(*model, built->config, options.estimate_readout);
    built->round = round;
    built->observations = model->observations.size();
  }
  const BundleConfig& config = built->config;
  ProblemBlocks& blocks = built->blocks;
  const Pose& pose_a = built->pose_a;
  RoundResult result;
  result.num_observations = config.num_observations;
  result.num_points = config.num_points;
  result.skipped_points = config.skipped_points;
  result.num_images = config.num_images;
  result.refined_params = config.refined;

  if (!precision_pass && !covariance_pass) {
    std::string why_not;
    result.setup_s = SecondsSince(setup_start);
    if (SolveWithDenseSchur(model, options, config, round, &blocks, &result, &why_not)) {
      result.gauge = config.Describe(*model, result.num_gps, result.num_gcp, result.offset_estimated);
      WriteBack(blocks, config, pose_a, model);
      return result;
    }
  }

  if (!reused) {
    built->bundle = std::make_unique<CeresBundleProblem>(model, built->options, config, &blocks, &built->counts);
    CeresBundleProblem& b = *built->bundle;
    b.AddReprojections();
    b.AddGpsPriors(gps_offsets, gps_drift);
    b.AddAttitudePriors();
    b.AddIntrinsicsPriors();
    b.AddControlPriors();
    b.SetManifoldsAndHeldBlocks();
  }
  const RoundResult& counts = built->counts;  // the build's, whichever solve made it
  result.num_gps = counts.num_gps;
  result.num_gcp = counts.num_gcp;
  result.num_attitude = counts.num_attitude;
  result.offset_estimated = counts.offset_estimated;
  result.drift_estimated = counts.drift_estimated;
  CeresBundleProblem& bundle = *built->bundle;
  result.gauge = config.Describe(*model, result.num_gps, result.num_gcp, result.offset_estimated);
  ceres::Problem& problem = bundle.problem();

  ceres::Solver::Options solver_options = SolverOptions(options, config.num_images, &result.solver);
  if (start_radius > 0.0) {
    solver_options.initial_trust_region_radius =
        std::clamp(start_radius, solver_options.initial_trust_region_radius, solver_options.max_trust_region_radius);
  }
  if (result.num_points > 0) solver_options.linear_solver_ordering = bundle.SchurOrdering(gps_offsets, gps_drift);
  std::unique_ptr<IterationForwarder> forwarder;
  if (options.iteration_callback || options.optimality_gap > 0.0 || options.cost_change_tolerance > 0.0) {
    forwarder = std::make_unique<IterationForwarder>(options.iteration_callback, round, options.optimality_gap,
                                                     options.cost_change_tolerance);
    solver_options.callbacks.push_back(forwarder.get());
  }
  result.setup_s = SecondsSince(setup_start);

  if (precision_pass) {
    if (config.AnyMerged()) {
      result.posterior.note = "not computed: images with a camera group of their own";
    } else if (config.gauge == BundleGauge::kHeldImages) {
      result.posterior.note = "not computed: images held fixed (a local adjustment)";
    } else if (config.gauge == BundleGauge::kFixedImage || config.gauge == BundleGauge::kFreeNetwork) {
      result.posterior.note = "not computed: no priors hold the datum (a fixed image and baseline do; the "
                              "precision would be relative to them)";
    } else {
      result.posterior = PosteriorPrecision(
          &problem, model, config.image_used, config.point_used, blocks.rotations, &blocks.readout, bundle.mark_blocks(),
          [&](double sigma) { return bundle.LossFor(sigma); }, bundle.mark_sigma(), options, gps_offsets, gps_drift,
          bundle.groups(), options.compute_intrinsics_covariance ? &config.refined : nullptr, &result);
    }
  } else if (covariance_pass) {
    if (config.AnyMerged()) {
      result.covariance_note = "not computed: images with a camera group of their own";
    } else {
      IntrinsicsCovariance(&problem, model, config.image_used, config.refined, options, &result);
    }
  } else if (problem.NumResidualBlocks() > 0) {
    SolveProblem(options, solver_options, bundle.EliminatedPoints(), &problem, &result);
    if (result.ceres.termination_type == ceres::USER_SUCCESS && forwarder) {
      // Our stopping rules (optimality gap, cost change) are convergence.
      result.ceres.termination_type = ceres::CONVERGENCE;
      result.ceres.message = forwarder->Reason();
    }
    if (options.compute_intrinsics_covariance) {
      if (config.AnyMerged()) {
        result.covariance_note = "not computed: images with a camera group of their own";
      } else {
        IntrinsicsCovariance(&problem, model, config.image_used, config.refined, options, &result);
      }
    }
  }

  WriteBack(blocks, config, pose_a, model);
  // A solve's problem waits for the pass (a pass's own, with the check
  // points added, is done).
  if (keep != nullptr && !precision_pass && !covariance_pass && options.compute_precision) {
    *keep = std::move(built);
    // The engine's per-iteration Jacobians, freed in many mid-sized blocks,
    // back to the kernel: no rebuild reuses them now before the pass's own
    // large arrays.
    ReleaseFreedMemory();
  }
  return result;
}

// Each observation group's stated sigma: the median over its observations
// (px for image measurements, m for GPS and control; control's horizontal
// and vertical pooled as in its 3 residuals).
std::array<double, kNumObservationGroups> StatedSigmas(const SparseModel& model, const BundleOptions& options) {
  std::array<std::vector<double>, kNumObservationGroups> v;
  const double mark = options.mark_sigma_px > 0.0 ? options.mark_sigma_px : options.observation_sigma_px;
  for (const Observation& obs : model.observations) {
    if (!model.images[obs.image].registered) continue;
    const bool is_mark = model.points[obs.point].role != PointRole::kTie;
    v[static_cast<int>(is_mark ? ObservationGroup::kMarks : ObservationGroup::kTies)].push_back(
        obs.sigma_px > 0.0 ? obs.sigma_px : is_mark ? mark : options.observation_sigma_px);
  }
  for (const Image& image : model.images) {
    if (!image.registered || !image.gps_prior) continue;
    v[static_cast<int>(ObservationGroup::kGpsHorizontal)].push_back(image.gps_prior->sigma_h_m);
    v[static_cast<int>(ObservationGroup::kGpsVertical)].push_back(image.gps_prior->sigma_v_m);
  }
  for (const Point& point : model.points) {
    if (point.role != PointRole::kControl || !point.prior) continue;
    const PositionPrior& p = *point.prior;
    const double rms = p.covariance ? std::sqrt(p.covariance->trace() / 3.0)
                                    : std::sqrt((2.0 * p.sigma_h_m * p.sigma_h_m + p.sigma_v_m * p.sigma_v_m) / 3.0);
    v[static_cast<int>(ObservationGroup::kControl)].push_back(rms);
  }
  std::array<double, kNumObservationGroups> out{};
  for (int g = 0; g < kNumObservationGroups; ++g) {
    if (v[g].empty()) continue;
    std::nth_element(v[g].begin(), v[g].begin() + v[g].size() / 2, v[g].end());
    out[g] = v[g][v[g].size() / 2];
  }
  return out;
}

int CountBehindCamera(const SparseModel& model) {
  int behind = 0;
  for (const Observation& obs : model.observations) {
    const Image& image = model.images[obs.image];
    if (!image.registered) continue;
    if (image.pose.CamFromWorld(model.points[obs.point].position).z() <= 0.0) {
      ++behind;
    }
  }
  return behind;
}

double RmsOfAdjusted(const SparseModel& model, const std::vector<double>& errors) {
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < errors.size(); ++i) {
    const Observation& obs = model.observations[i];
    if (!model.images[obs.image].registered ||
        model.points[obs.point].role == PointRole::kCheck || !std::isfinite(errors[i])) {
      continue;
    }
    sum += errors[i] * errors[i];
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

double MaxRayAngleDeg(const SparseModel& model, const std::vector<int>& obs_of_point) {
  std::vector<Eigen::Vector3d> rays;
  for (int o : obs_of_point) {
    const Observation& obs = model.observations[o];
    const Eigen::Vector3d ray = model.points[obs.point].position -
                                model.images[obs.image].pose.centre_in_world;
    if (ray.norm() > 0.0) rays.push_back(ray.normalized());
  }
  double min_cos = 1.0;
  const size_t n = std::min<size_t>(rays.size(), 40);
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = a + 1; b < n; ++b) min_cos = std::min(min_cos, rays[a].dot(rays[b]));
  }
  return std::acos(std::clamp(min_cos, -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace

std::string ToString(ObservationGroup group) {
  switch (group) {
    case ObservationGroup::kTies:
      return "tie_points";
    case ObservationGroup::kMarks:
      return "target_marks";
    case ObservationGroup::kGpsHorizontal:
      return "gps_horizontal";
    case ObservationGroup::kGpsVertical:
      return "gps_vertical";
    case ObservationGroup::kControl:
      return "control_points";
  }
  return "?";
}

std::string ToString(LossType loss) {
  switch (loss) {
    case LossType::kNone: return "none";
    case LossType::kHuber: return "huber";
    case LossType::kCauchy: return "cauchy";
    case LossType::kTukey: return "tukey";
  }
  return "?";
}

std::string ToString(LinearSolverChoice solver) {
  switch (solver) {
    case LinearSolverChoice::kAuto: return "auto";
    case LinearSolverChoice::kDenseSchur: return "dense_schur";
    case LinearSolverChoice::kSparseSchur: return "sparse_schur";
    case LinearSolverChoice::kIterativeSchur: return "iterative_schur";
  }
  return "?";
}

std::string ToString(BundleEngine engine) {
  switch (engine) {
    case BundleEngine::kAuto: return "auto";
    case BundleEngine::kCeres: return "ceres";
    case BundleEngine::kAerotri: return "aerotri";
  }
  return "?";
}

std::optional<BundleEngine> ParseBundleEngine(const std::string& name) {
  for (BundleEngine e : {BundleEngine::kAuto, BundleEngine::kCeres, BundleEngine::kAerotri}) {
    if (ToString(e) == Lower(name)) return e;
  }
  return std::nullopt;
}

std::string ToString(IntrinsicsRefinement refinement) {
  switch (refinement) {
    case IntrinsicsRefinement::kNone: return "none";
    case IntrinsicsRefinement::kFocal: return "focal";
    case IntrinsicsRefinement::kFocalPrincipalPoint: return "focal,pp";
    case IntrinsicsRefinement::kAll: return "all";
    case IntrinsicsRefinement::kList: return "list";
  }
  return "?";
}

std::optional<LossType> ParseLossType(const std::string& name) {
  for (LossType t : {LossType::kNone, LossType::kHuber, LossType::kCauchy, LossType::kTukey}) {
    if (ToString(t) == Lower(name)) return t;
  }
  return std::nullopt;
}

std::optional<LinearSolverChoice> ParseLinearSolver(const std::string& name) {
  for (LinearSolverChoice s :
       {LinearSolverChoice::kAuto, LinearSolverChoice::kDenseSchur,
        LinearSolverChoice::kSparseSchur, LinearSolverChoice::kIterativeSchur}) {
    if (ToString(s) == Lower(name)) return s;
  }
  return std::nullopt;
}

std::optional<IntrinsicsRefinement> ParseIntrinsicsRefinement(
    const std::string& text, std::vector<std::string>* params) {
  const std::string t = Lower(text);
  if (t == "none") return IntrinsicsRefinement::kNone;
  if (t == "focal" || t == "f") return IntrinsicsRefinement::kFocal;
  if (t == "focal,pp" || t == "f,pp" || t == "f,cx,cy") {
    return IntrinsicsRefinement::kFocalPrincipalPoint;
  }
  if (t == "all") return IntrinsicsRefinement::kAll;
  std::vector<std::string> names;
  std::stringstream stream(t);
  std::string item;
  static const std::vector<std::string> kKnown = {"f", "cx", "cy", "pp", "k1", "k2",
                                                  "k3", "p1", "p2"};
  while (std::getline(stream, item, ',')) {
    if (std::find(kKnown.begin(), kKnown.end(), item) == kKnown.end()) return std::nullopt;
    names.push_back(item);
  }
  if (names.empty()) return std::nullopt;
  if (params) *params = names;
  return IntrinsicsRefinement::kList;
}

bool BundleOptions::Validate(std::string* error) const {
  auto fail = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (!(loss_scale_px > 0.0)) {
    return fail("loss scale must be > 0 px, got " + std::to_string(loss_scale_px));
  }
  if (!(mark_sigma_px >= 0.0)) {
    return fail("mark sigma must be >= 0 px (0 = the observation sigma), got " + std::to_string(mark_sigma_px));
  }
  if (!(observation_sigma_px > 0.0)) {
    return fail("observation sigma must be > 0 px, got " +
                std::to_string(observation_sigma_px));
  }
  if (num_threads < 0) return fail("threads must be >= 0 (0 = all), got " + std::to_string(num_threads));
  if (max_iterations < 0) return fail("max iterations must be >= 0, got " + std::to_string(max_iterations));
  if (!(optimality_gap >= 0.0 && optimality_gap < 1.0)) {
    return fail("optimality gap must be in [0, 1) (0 = off), got " + std::to_string(optimality_gap));
  }
  if (!(function_tolerance >= 0.0) || !(gradient_tolerance >= 0.0) ||
      !(parameter_tolerance >= 0.0) || !(screening_function_tolerance >= 0.0) || !(cost_change_tolerance >= 0.0)) {
    return fail("solver tolerances must be >= 0");
  }
  if (!(outlier_threshold_px >= 0.0)) {
    return fail("outlier threshold must be >= 0 px (0 = off), got " +
                std::to_string(outlier_threshold_px));
  }
  if (max_outlier_rounds < 0) return fail("outlier rounds must be >= 0");
  for (int g = 0; g < kNumObservationGroups; ++g) {
    if (!(sigma_scale[g] > 0.0) || !std::isfinite(sigma_scale[g])) {
      return fail("sigma scale of " + ToString(static_cast<ObservationGroup>(g)) + " must be > 0, got " +
                  std::to_string(sigma_scale[g]));
    }
  }
  if (max_variance_component_iterations < 0) return fail("variance-component iterations must be >= 0");
  if (!(variance_component_tolerance > 0.0)) {
    return fail("variance-component tolerance must be > 0, got " + std::to_string(variance_component_tolerance));
  }
  if (refine_intrinsics == IntrinsicsRefinement::kList && refine_params.empty()) {
    return fail("intrinsics refinement 'list' needs at least one parameter name");
  }
  return true;
}

std::vector<double> ReprojectionErrors(const SparseModel& model) {
  std::vector<double> errors(model.observations.size());
  for (size_t i = 0; i < model.observations.size(); ++i) {
    const Observation& obs = model.observations[i];
    const Image& image = model.images[obs.image];
    const Camera& camera = model.cameras[image.camera];
    // As the adjustment measures it: from the pose at the observed row.
    const Eigen::Vector3d p = image.PoseAtRow(obs.xy.y(), camera.height).CamFromWorld(model.points[obs.point].position);
    if (p.z() == 0.0) {
      errors[i] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    errors[i] = (camera.ImageFromCamera(p) - obs.xy).norm();
  }
  return errors;
}

namespace {

// One AdjustBundle's state between its solves: the model, the GNSS
// parameters carried from solve to solve, and the summary being filled.
struct BundleRun {
  SparseModel* model;
  const BundleOptions& options;
  BundleSummary summary;
  std::vector<Eigen::Vector3d> gps_offsets;  // one, or one per flight
  std::vector<Eigen::Vector3d> gps_drift;    // per flight, when estimated
  int solve = 0;                             // the solves so far
  // The intrinsics' covariance was asked for (BundleOptions::
  // compute_intrinsics_covariance; the solves skip theirs), and has been
  // taken from the final precision pass.
  bool intrinsics_covariance = false;
  bool intrinsics_covariance_done = false;
  // The trust region the last solve ended at (0: none yet). Every solve
  // after the first starts from the one before's optimum, where the
  // Gauss–Newton model holds (gain ratios of 1.000 on rendered surveys);
  // restarting each at Ceres' default radius (damping 1e-4 of the
  // diagonal) held back the block's weakest directions, which then took
  // five or six more iterations to free at the radius' growth of 3 a step.
  double trust_radius = 0.0;
  // The last solve's problem, for the precision pass after it.
  std::unique_ptr<BuiltProblem> kept;
};

// The GNSS parameters' start: one offset, or one per flight (at least one
// either way), and the drift per flight.
void StartGnssParameters(BundleRun* run) {
  const BundleOptions& options = run->options;
  int flights = 0;
  for (const Image& image : run->model->images) {
    if (image.gps_prior) flights = std::max(flights, image.gps_prior->flight + 1);
  }
  run->gps_offsets.assign(options.gps_offset_per_flight ? std::max(flights, 1) : 1, options.initial_gps_offset_m);
  if (options.gps_offset_per_flight) {
    for (size_t f = 0; f < run->gps_offsets.size() && f < options.initial_gps_flight_offsets_m.size(); ++f) {
      run->gps_offsets[f] = options.initial_gps_flight_offsets_m[f];
    }
  }
  if (options.estimate_gps_drift) {
    run->gps_drift.assign(flights, Eigen::Vector3d::Zero());
    for (int f = 0; f < flights && f < static_cast<int>(options.initial_gps_drift_m_per_s.size()); ++f) {
      run->gps_drift[f] = options.initial_gps_drift_m_per_s[f];
    }
  }
}

// What a solve refined, per camera group in use: "all", "none", the
// parameters' names when every group refines the same, else per group
// ("camera 1: f,cx,cy; camera 2: none"). A calibration certificate's fixed
// parameters and groups seen by too few images are not refined.
std::string DescribeRefined(const SparseModel& model, const std::vector<std::vector<int>>& refined) {
  std::vector<char> used(model.cameras.size(), 0);
  for (const Image& image : model.images) {
    if (image.registered) used[image.camera] = 1;
  }
  std::vector<std::pair<int, std::string>> groups;
  for (size_t c = 0; c < model.cameras.size() && c < refined.size(); ++c) {
    if (!used[c]) continue;
    const CameraModelInfo& info = model.cameras[c].info();
    std::string names;
    for (int k : refined[c]) names += (names.empty() ? "" : ",") + info.param_names[k];
    if (static_cast<int>(refined[c].size()) == info.num_params()) names = "all";
    if (refined[c].empty()) names = "none";
    groups.push_back({model.cameras[c].id, names});
  }
  if (groups.empty()) return "none";
  bool same = true;
  for (const auto& g : groups) same &= g.second == groups.front().second;
  if (same) return groups.front().second;
  std::string out;
  for (const auto& [id, names] : groups) out += (out.empty() ? "" : "; ") + ("camera " + std::to_string(id) + ": " + names);
  return out;
}

int IterationsOf(const RoundResult& result) { return std::max(static_cast<int>(result.ceres.iterations.size()) - 1, 0); }

// A solve's figures into the summary (its counts, σ0, cost and times).
void Absorb(BundleRun* run, const RoundResult& result, int round, const std::string& kind) {
  BundleSummary& summary = run->summary;
  const BundleOptions& options = run->options;
  summary.gps_offset_estimated = result.offset_estimated;
  summary.gps_drift_estimated = result.drift_estimated;
  summary.gps_drift_m_per_s = run->gps_drift;
  summary.num_attitude_priors = result.num_attitude;
  summary.redundancy = result.ceres.num_residuals_reduced - result.ceres.num_effective_parameters_reduced;
  summary.sigma0 = summary.redundancy > 0 ? std::sqrt(2.0 * result.ceres.final_cost / summary.redundancy) : 0.0;
  summary.intrinsics_precision = result.precision;
  summary.covariance_note = result.covariance_note;
  summary.refined_intrinsics = DescribeRefined(*run->model, result.refined_params);
  summary.refined_params = result.refined_params;
  summary.gps_offset_m = run->gps_offsets[0];
  if (options.gps_offset_per_flight) summary.gps_flight_offsets_m = run->gps_offsets;
  if (round == 0) {
    summary.initial_cost = result.ceres.initial_cost;
    summary.gauge = result.gauge;
    summary.linear_solver = result.solver;
  }
  summary.final_cost = result.ceres.final_cost;
  summary.iterations += IterationsOf(result);
  summary.termination = std::string(ceres::TerminationTypeToString(
                            result.ceres.termination_type)) +
                        ": " + result.ceres.message;
  summary.solves.push_back({kind, IterationsOf(result), result.ceres.initial_cost, result.ceres.final_cost,
                            result.ceres.total_time_in_seconds, summary.termination});
  summary.converged = result.ceres.termination_type == ceres::CONVERGENCE;
  summary.setup_time_s += result.setup_s;
  summary.solve_time_s += result.ceres.total_time_in_seconds;
  if (options.keep_solver_report) summary.solver_report += result.report.empty() ? result.ceres.FullReport() : result.report;
  summary.num_images = result.num_images;
  summary.num_points = result.num_points;
  summary.num_observations = result.num_observations;
  summary.num_gps_priors = result.num_gps;
  summary.num_gcp_priors = result.num_gcp;
  summary.num_skipped_points = result.skipped_points;
  summary.num_camera_groups = 0;
}

// One solve of the block, absorbed into the summary under `kind`.
RoundResult Solve(BundleRun* run, const BundleOptions& options, const std::string& kind,
                  bool precision_pass = false) {
  const int round = run->solve++;
  RoundResult result = SolveOnce(run->model, options, round, &run->gps_offsets, &run->gps_drift, precision_pass,
                                 /*covariance_pass=*/false, precision_pass ? 0.0 : run->trust_radius, &run->kept);
  if (!precision_pass) {
    Absorb(run, result, round, kind);
    if (!result.ceres.iterations.empty()) run->trust_radius = result.ceres.iterations.back().trust_region_radius;
  }
  return result;
}

// Rejects tie-point observations beyond the threshold; how many. A target
// mark is never dropped silently (the w-test of the precision pass names a
// bad one).
int RejectOutliers(BundleRun* run) {
  SparseModel* model = run->model;
  const std::vector<double> errors = ReprojectionErrors(*model);
  std::vector<Observation> kept;
  kept.reserve(model->observations.size());
  int removed = 0;
  for (size_t i = 0; i < errors.size(); ++i) {
    const Observation& obs = model->observations[i];
    const bool adjusted = model->images[obs.image].registered && model->points[obs.point].role == PointRole::kTie;
    if (adjusted && !(errors[i] <= run->options.outlier_threshold_px)) {
      ++removed;
    } else {
      kept.push_back(obs);
    }
  }
  if (removed > 0) model->observations.swap(kept);
  run->summary.outliers_removed += removed;
  return removed;
}

// Screening (robust, to find the blunders) then least squares, or the
// robust loss throughout; after the estimate, rejection and a re-solve while
// observations go beyond the threshold (max_outlier_rounds times). Returns
// the estimator's options.
BundleOptions SolveWithOutlierRounds(BundleRun* run) {
  const BundleOptions& options = run->options;
  const int max_rounds = options.outlier_threshold_px > 0.0 ? options.max_outlier_rounds : 0;
  const bool screening = options.least_squares_after_screening && options.loss != LossType::kNone && max_rounds > 0;
  BundleOptions screen = options;
  screen.function_tolerance = std::max(options.function_tolerance, options.screening_function_tolerance);
  screen.cost_change_tolerance = 0.0;
  BundleOptions least_squares = options;
  least_squares.loss = LossType::kNone;
  const BundleOptions& estimate = screening ? least_squares : options;
  if (screening) {
    Solve(run, screen, std::string("robust screening (") + ToString(options.loss) + ")");
    if (RejectOutliers(run) > 0) run->summary.outlier_rounds = 1;
  }
  for (int round = 0;; ++round) {
    Solve(run, estimate,
          round > 0   ? "outlier round " + std::to_string(round)
          : screening ? std::string("least squares")
                      : std::string("first"));
    if (round >= max_rounds || RejectOutliers(run) == 0) break;
    ++run->summary.outlier_rounds;
  }
  return estimate;
}

// Each observation group's variance component from a precision pass;
// *settled: every estimated group within its tolerance of 1, else *next
// holds the rescaled sigmas.
void VarianceComponentsOf(const BundleRun& run, const RoundResult& pass, const BundleOptions& weighted,
                          const std::array<double, kNumObservationGroups>& stated, int iteration,
                          std::array<bool, kNumObservationGroups>* estimable,
                          std::vector<VarianceComponent>* components,
                          std::array<double, kNumObservationGroups>* next, bool* settled) {
  const BundleOptions& options = run.options;
  components->clear();
  *settled = true;
  *next = weighted.sigma_scale;
  for (int g = 0; g < kNumObservationGroups; ++g) {
    const internal::GroupRedundancy& gr = pass.groups[g];
    if (gr.rows == 0) continue;
    VarianceComponent vc;
    vc.group = static_cast<ObservationGroup>(g);
    vc.rows = gr.rows;
    vc.redundancy = gr.rows - gr.leverage;
    vc.sigma0 = vc.redundancy > 0.5 ? std::sqrt(gr.sum_squares / vc.redundancy)
                                    : std::numeric_limits<double>::quiet_NaN();
    if (iteration == 0) {
      (*estimable)[g] = vc.redundancy >= BundleOptions::kMinGroupRedundancy && !options.hold_stated_sigmas[g];
    }
    vc.scale = weighted.sigma_scale[g];
    vc.stated_sigma = stated[g];
    vc.estimated = options.estimate_variance_components && (*estimable)[g];
    vc.held = options.hold_stated_sigmas[g];
    components->push_back(vc);
    // Settled within the tolerance or one standard error of the group's σ0
    // (1 / sqrt(2 r_g)), whichever is larger.
    const double tolerance =
        std::max(options.variance_component_tolerance, 1.0 / std::sqrt(2.0 * std::max(vc.redundancy, 1.0)));
    if ((*estimable)[g] && std::isfinite(vc.sigma0) && vc.sigma0 > 0.0 && std::abs(vc.sigma0 - 1.0) > tolerance) {
      *settled = false;
      (*next)[g] *= std::clamp(vc.sigma0, 0.1, 10.0);
    }
  }
}

// The precision pass; with variance-component estimation, each group's
// factor rescales its sigmas and the block is solved again (Förstner's
// iteration), the last pass at the weights it settled on. Which groups are
// estimated is decided at the stated weights: a group with too little
// redundancy of its own to judge (a handful of control points that hold the
// datum) keeps its stated sigmas throughout.
BundleOptions PrecisionWithVarianceComponents(BundleRun* run, const BundleOptions& estimate) {
  const BundleOptions& options = run->options;
  BundleSummary& summary = run->summary;
  summary.sigma0_stated = summary.sigma0;
  summary.redundancy_stated = summary.redundancy;
  BundleOptions weighted = estimate;
  const std::array<double, kNumObservationGroups> stated = StatedSigmas(*run->model, options);
  RoundResult pass;
  std::array<bool, kNumObservationGroups> estimable{};
  for (int iteration = 0;; ++iteration) {
    // Each pass computes the intrinsics' covariance too (a few blocks of the
    // inverse it has): the last one's is the final state's.
    BundleOptions pass_options = weighted;
    pass_options.compute_intrinsics_covariance = run->intrinsics_covariance;
    pass = Solve(run, pass_options, "", /*precision_pass=*/true);
    std::array<double, kNumObservationGroups> next;
    bool settled = true;
    VarianceComponentsOf(*run, pass, weighted, stated, iteration, &estimable, &summary.variance_components, &next,
                         &settled);
    if (!options.estimate_variance_components || !pass.posterior.computed || settled ||
        iteration >= options.max_variance_component_iterations) {
      break;
    }
    weighted.sigma_scale = next;
    Solve(run, weighted, "variance components " + std::to_string(iteration + 1));
    summary.variance_component_iterations = iteration + 1;
  }
  if (run->intrinsics_covariance && pass.posterior.computed) {
    summary.intrinsics_precision = pass.precision;
    summary.covariance_note = pass.covariance_note;
    run->intrinsics_covariance_done = true;
  }
  summary.precision = std::move(pass.posterior);
  BundlePrecision& p = summary.precision;
  if (!p.computed) return weighted;
  p.variance_factor = summary.sigma0 > 0.0 ? summary.sigma0 * summary.sigma0 : 1.0;
  for (ImagePrecision& ip : p.images) {
    ip.centre_cov *= p.variance_factor;
    ip.rotation_cov *= p.variance_factor;
  }
  for (PointPrecision& pt : p.points) pt.cov *= p.variance_factor;
  p.gps_offset_cov *= p.variance_factor;
  for (Eigen::Matrix3d& c : p.gps_flight_offset_cov) c *= p.variance_factor;
  for (Eigen::Matrix3d& c : p.gps_drift_cov) c *= p.variance_factor;
  for (double& v : p.readout_var) v *= p.variance_factor;
  return weighted;
}

// The intrinsics' covariance at the final state and weights (`last`, the
// options of the last solve), once, where no precision pass gave it: the
// solves before it skip theirs.
void FinalIntrinsicsCovariance(BundleRun* run, const BundleOptions& last) {
  const RoundResult r = SolveOnce(run->model, last, run->solve, &run->gps_offsets, &run->gps_drift,
                                  /*precision_pass=*/false, /*covariance_pass=*/true);
  run->summary.intrinsics_precision = r.precision;
  run->summary.covariance_note = r.covariance_note;
}

// Each camera group's estimated readout time (BundleOptions::
// estimate_readout), as the last solve wrote it into its photos, with its
// sigma where the precision was computed.
void ReportReadouts(const SparseModel& model, BundleSummary* summary) {
  std::vector<BundleSummary::Readout> readouts(model.cameras.size());
  for (const Image& image : model.images) {
    if (!image.registered || !image.rolling_shutter) continue;
    BundleSummary::Readout& r = readouts[image.camera];
    r.camera = image.camera;
    ++r.images;
    r.readout_time_s = image.rolling_shutter->readout_time_s;
  }
  const std::vector<double>& var = summary->precision.readout_var;
  for (BundleSummary::Readout& r : readouts) {
    if (r.images == 0) continue;
    if (summary->precision.computed && r.camera < static_cast<int>(var.size())) r.sigma_s = std::sqrt(var[r.camera]);
    summary->readouts.push_back(r);
  }
}

// Weak images (few observations) and tie points seen under small angles.
void Diagnostics(const SparseModel& model, const BundleOptions& options, BundleSummary* summary) {
  summary->num_behind_camera_final = CountBehindCamera(model);
  const std::vector<int> per_image = model.ObservationsPerImage();
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (model.images[i].registered && per_image[i] < options.weak_image_min_observations) {
      summary->weak_images.push_back({model.images[i].name, per_image[i]});
    }
  }
  std::vector<std::vector<int>> obs_of_point(model.points.size());
  for (size_t o = 0; o < model.observations.size(); ++o) {
    obs_of_point[model.observations[o].point].push_back(static_cast<int>(o));
  }
  for (size_t p = 0; p < model.points.size(); ++p) {
    if (model.points[p].role != PointRole::kTie || obs_of_point[p].size() < 2) continue;
    if (MaxRayAngleDeg(model, obs_of_point[p]) < options.weak_point_min_angle_deg) {
      ++summary->weak_points_small_angle;
    }
  }
}

}  // namespace

BundleSummary AdjustBundle(SparseModel* model, const BundleOptions& options) {
  AEROTRI_CHECK(model != nullptr);
  const auto start = Clock::now();
  std::string error;
  if (!options.Validate(&error)) throw InvalidArgument("bundle adjustment: " + error);
  model->Validate();

  // The solves skip the intrinsics' covariance; the final state's is
  // computed once at the end (FinalIntrinsicsCovariance).
  BundleOptions solving = options;
  solving.compute_intrinsics_covariance = false;
  BundleRun run{model, solving, BundleSummary(), {}, {}, 0, options.compute_intrinsics_covariance, false, 0.0, nullptr};
  BundleSummary& summary = run.summary;
  if (options.compute_diagnostics) summary.num_behind_camera_initial = CountBehindCamera(*model);
  summary.initial_rms_px = RmsOfAdjusted(*model, ReprojectionErrors(*model));
  summary.refined_intrinsics = ToString(options.refine_intrinsics);
  if (options.refine_intrinsics == IntrinsicsRefinement::kList) {
    summary.refined_intrinsics.clear();
    for (const auto& p : options.refine_params) {
      summary.refined_intrinsics += (summary.refined_intrinsics.empty() ? "" : ",") + p;
    }
  }
  StartGnssParameters(&run);
  const BundleOptions estimate = SolveWithOutlierRounds(&run);
  BundleOptions last = options.compute_precision ? PrecisionWithVarianceComponents(&run, estimate) : estimate;
  run.kept.reset();
  if (options.compute_intrinsics_covariance && !run.intrinsics_covariance_done) {
    last.compute_intrinsics_covariance = true;
    FinalIntrinsicsCovariance(&run, last);
  }
  if (options.estimate_readout) ReportReadouts(*model, &summary);

  std::vector<char> used(model->cameras.size(), 0);
  for (const Image& image : model->images) {
    if (image.registered) used[image.camera] = 1;
  }
  summary.num_camera_groups = static_cast<int>(std::count(used.begin(), used.end(), 1));
  summary.final_rms_px = RmsOfAdjusted(*model, ReprojectionErrors(*model));
  if (options.compute_diagnostics) Diagnostics(*model, options, &summary);
  summary.total_time_s = SecondsSince(start);
  return summary;
}

const PointPrecision* BundlePrecision::ForPoint(int point) const {
  for (const PointPrecision& p : points) {
    if (p.point == point) return &p;
  }
  return nullptr;
}

const ImagePrecision* BundlePrecision::ForImage(int image) const {
  for (const ImagePrecision& p : images) {
    if (p.image == image) return &p;
  }
  return nullptr;
}

std::string BundleSummary::BriefReport() const {
  std::ostringstream out;
  out.precision(6);
  out << "bundle adjustment: " << num_images << " images, " << num_camera_groups
      << " camera groups, " << num_points << " points, " << num_observations
      << " observations";
  if (num_gps_priors > 0 || num_gcp_priors > 0) {
    out << ", " << num_gps_priors << " GPS priors, " << num_gcp_priors << " GCP priors";
  }
  out << "\n";
  out << "  solver: " << linear_solver << ", intrinsics refined: " << refined_intrinsics << "\n";
  out << "  gauge: " << gauge << "\n";
  out << "  cost: " << initial_cost << " -> " << final_cost << " (½Σ‖r‖²), rms: "
      << initial_rms_px << " -> " << final_rms_px << " px\n";
  out << "  iterations: " << iterations << ", termination: " << termination << "\n";
  out << "  sigma0: " << sigma0 << " (redundancy " << redundancy << ")\n";
  out << "  observations behind their camera (kept): " << num_behind_camera_initial
      << " initially, " << num_behind_camera_final << " after\n";
  if (gps_offset_estimated && gps_flight_offsets_m.empty()) {
    out << "  GPS offset (GPS minus camera, E N U): " << gps_offset_m.x() << " " << gps_offset_m.y()
        << " " << gps_offset_m.z() << " m\n";
  }
  for (size_t f = 0; gps_offset_estimated && f < gps_flight_offsets_m.size(); ++f) {
    const Eigen::Vector3d& o = gps_flight_offsets_m[f];
    out << "  GPS offset of flight " << f + 1 << " (GPS minus camera, E N U): " << o.x() << " " << o.y() << " "
        << o.z() << " m\n";
  }
  if (outlier_rounds > 0 || outliers_removed > 0) {
    out << "  outliers rejected: " << outliers_removed << " in " << outlier_rounds
        << " rounds\n";
  }
  if (num_skipped_points > 0) {
    out << "  tie points skipped (fewer than 2 observations): " << num_skipped_points << "\n";
  }
  if (!weak_images.empty()) {
    out << "  weak images (few observations): " << weak_images.size() << " (";
    for (size_t i = 0; i < weak_images.size() && i < 5; ++i) {
      out << (i ? ", " : "") << weak_images[i].name << ": " << weak_images[i].observations;
    }
    out << (weak_images.size() > 5 ? ", ...)" : ")") << "\n";
  }
  out << "  weak points (narrow rays): " << weak_points_small_angle << "\n";
  out << "  time: setup " << setup_time_s << " s, solve " << solve_time_s << " s, total "
      << total_time_s << " s";
  return out.str();
}

}  // namespace aerotri
