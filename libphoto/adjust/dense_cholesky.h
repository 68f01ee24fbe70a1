// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The Cholesky factor of a dense symmetric positive definite matrix on
// several threads: right-looking by column blocks, each block's panel and
// the trailing lower triangle's update shared out (Eigen's LLT runs on one
// thread without OpenMP). The reduced systems of the survey engines
// (schur_lm_solver.h) and the precision pass (bundle_precision.h) are
// factored so: at 3,086 columns (513 photos) one factorisation is about a
// second on one thread, once per Levenberg–Marquardt step.

#include <Eigen/Core>

namespace aerotri {
namespace internal {

// A's lower triangle becomes L (A = L Lᵀ), in place; the strict upper
// triangle is left undefined. Reads A's lower triangle only. False where A
// is not (numerically) positive definite.
bool CholeskyInPlace(Eigen::MatrixXd* a, unsigned threads);

// x = (L Lᵀ)⁻¹ b with L the lower triangle CholeskyInPlace left.
Eigen::VectorXd CholeskySolve(const Eigen::MatrixXd& l, const Eigen::VectorXd& b);

}  // namespace internal
}  // namespace aerotri
