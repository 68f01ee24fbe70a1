// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A Ceres problem's residuals and Jacobian evaluated from its cost
// functions directly, on every thread, as ceres::Problem::Evaluate gives
// them with apply_loss_function: each robust loss through Triggs'
// correction, each manifold's tangent coordinates. Shared by aerotri's
// Schur engine (schur_lm_solver.h) and the posterior precision pass
// (bundle_precision.h), where Ceres' Evaluate took a third of each pass (it
// runs on one thread and builds its program anew on every call).

#include <ceres/crs_matrix.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>

#include <vector>

namespace aerotri {
namespace internal {

// Ceres' robust-loss correction (Triggs): the residual and Jacobian rows
// scaled so that the Gauss–Newton model of ½ρ(‖r‖²) is that of ½‖r‖².
struct LossCorrector {
  double cost = 0.0;  // ½ρ(‖r‖²)
  double residual_scaling = 1.0;
  double sqrt_rho1 = 1.0;
  double alpha_sq_norm = 0.0;
  LossCorrector(const ceres::LossFunction* loss, const double* r, int rows);
  bool Identity() const { return residual_scaling == 1.0 && sqrt_rho1 == 1.0 && alpha_sq_norm == 0.0; }
};

// The residuals of `residual_blocks` (in their order) and their Jacobian
// over `parameter_blocks` (columns in their order, each block's tangent
// size; every other block held), the loss corrected, in Ceres' compressed
// rows with each row's columns ascending, on `threads` threads. False where
// a block cannot be evaluated or gives a value that is not finite.
bool EvaluateJacobian(const ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& residual_blocks,
                      const std::vector<double*>& parameter_blocks, int threads, std::vector<double>* residuals,
                      ceres::CRSMatrix* jacobian);

}  // namespace internal
}  // namespace aerotri
