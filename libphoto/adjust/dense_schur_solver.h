// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// aerotri's own Levenberg–Marquardt for reprojection-only bundles whose
// reduced camera system is small enough to hold dense (BAL problems, free
// networks of up to a few hundred images with a camera group each).
//
// Why not Ceres here: on such problems Ceres' generic machinery (program
// evaluation, block-sparse bookkeeping, per-iteration re-analysis) costs
// more than the arithmetic. This solver does the same mathematics with the
// structure written out:
//   - per camera one block of P = 6 + N tangent parameters: a rotation
//     increment θ (R ← Exp(θ) R, camera frame), the centre C, and the
//     camera model's N intrinsics (those not refined have zero Jacobian
//     columns and stay exactly where they are);
//   - per point its position (3);
//   - the normal equations are linearised once per accepted step, in one
//     pass over the points (residuals, analytic Jacobians, JᵀJ blocks),
//     shared by every trial step of that linearisation;
//   - the points are eliminated in parallel (each thread accumulates its
//     own copy of the reduced camera system, summed afterwards); the camera
//     system S δc = b is solved by dense Cholesky; the points are
//     back-substituted in parallel.
// Damping follows Ceres' Levenberg–Marquardt: (JᵀJ + D/μ) δ = −Jᵀr with D the
// diagonal of JᵀJ clamped to [1e-6, 1e32], μ the trust radius (start 1e4),
// grown by 1/max(1/3, 1 − (2ρ − 1)³) on a step whose gain ratio ρ exceeds
// 1e-3, else shrunk by a factor that doubles on each rejection. A step that
// puts a point on a camera plane (projection undefined) is rejected.
//
// The gauge (7 degrees of freedom of a free network) is left to the damping,
// as Ceres does on BAL; the caller restores its datum afterwards.
//
// Stopping (BundleStopRule, shared with the Ceres path): function, gradient
// and parameter tolerances as Ceres states them, and the optimality gap:
// stop once the cost is estimated to lie within `optimality_gap` (relative)
// of the optimum, the estimate being the larger of the last accepted
// decrease and its geometric extrapolation Δₖ ρ/(1 − ρ), ρ the larger of
// the last two contraction ratios Δₖ/Δₖ₋₁ and Δₖ₋₁/Δₖ₋₂.

#include <functional>
#include <string>
#include <vector>

#include "camera_models/camera_model.h"

namespace aerotri {

// Stopping by estimated distance to the optimum, from the accepted costs.
class BundleStopRule {
 public:
  explicit BundleStopRule(double optimality_gap) : gap_(optimality_gap) {}
  // Call with the cost after each accepted step; true when the cost is
  // estimated within the gap of the optimum.
  bool Accepted(double cost);
  // The estimated gap (relative) after the last accepted step; infinity
  // before two steps.
  double EstimatedGap() const { return estimate_; }

 private:
  double gap_;
  double last_cost_ = -1.0;
  double last_decrease_ = -1.0;
  double last_ratio_ = 0.0;
  double estimate_ = 1e300;
};

// Levenberg–Marquardt's trust region as Ceres runs it (shared by aerotri's
// engines): the damping is 1/μ; a step of gain ratio ρ grows μ by
// 1/max(1/3, 1 − (2ρ − 1)³), up to max_radius; a rejected step divides it
// by a factor that doubles with each rejection in a row.
class LmTrustRegion {
 public:
  LmTrustRegion(double radius, double max_radius) : radius_(radius), max_radius_(max_radius) {}
  double Radius() const { return radius_; }
  double Damping() const { return 1.0 / radius_; }
  void Accept(double rho);
  void Reject();

 private:
  double radius_;
  double max_radius_;
  double decrease_factor_ = 2.0;
};

struct DenseSchurProblem {
  CameraModelId model = CameraModelId::kSnavely;
  // Per camera a block [q (w, x, y, z), C (3), intrinsics (N)], changed in
  // place; and which intrinsics are refined (index-aligned with the model's
  // parameters).
  std::vector<double*> cameras;
  std::vector<std::vector<char>> refined;
  std::vector<double*> points;  // 3 each, changed in place
  struct Observation {
    int camera = 0;
    int point = 0;
    double x = 0.0, y = 0.0;  // px
    double inv_sigma = 1.0;   // 1 / image sigma (px)
  };
  std::vector<Observation> observations;
};

struct DenseSchurOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  double optimality_gap = 0.0;  // 0: off
  double max_time_s = 0.0;      // 0: no limit
  int num_threads = 0;          // 0: every core
  // iteration (0 = initial), cost, seconds since the start.
  std::function<void(int, double, double)> iteration_callback;
};

struct DenseSchurSummary {
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;        // accepted and rejected steps
  int accepted = 0;
  bool converged = false;
  bool usable = true;        // false: the initial state cannot be evaluated
  std::string termination;   // CONVERGENCE, NO_CONVERGENCE or FAILURE
  std::string message;
  int num_residuals = 0;
  int num_parameters = 0;    // tangent parameters that vary
  double time_s = 0.0;
  double linearize_s = 0.0, eliminate_s = 0.0, factor_s = 0.0, evaluate_s = 0.0;
  std::string Report() const;
};

// Largest reduced camera system (rows) this solver takes; above it the
// caller uses Ceres' sparse or iterative Schur solvers.
constexpr int kMaxDenseSchurSize = 2000;

DenseSchurSummary SolveDenseSchur(const DenseSchurProblem& problem, const DenseSchurOptions& options);

}  // namespace aerotri
