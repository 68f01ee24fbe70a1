// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The Cholesky factor of a sparse symmetric positive definite matrix whose
// pattern is fixed while its values change: the reduced camera systems of
// the survey engine (schur_lm_solver.h) beyond dense size, one per
// Levenberg–Marquardt step. SuiteSparse's CHOLMOD (a dependency of Ceres'
// sparse solvers, so already on every machine that builds aerotri): the
// fill-reducing ordering and symbolic analysis once, a supernodal numeric
// factorisation per step.

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace aerotri {
namespace internal {

class SparseCholesky {
 public:
  // The pattern, compressed by columns: column c's row indices are
  // rows[colptr[c] .. colptr[c + 1]), ascending. Only the lower triangle's
  // entries are read (upper entries in the pattern are ignored).
  SparseCholesky(int n, std::vector<int> colptr, std::vector<int> rows);
  ~SparseCholesky();
  SparseCholesky(const SparseCholesky&) = delete;
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  int size() const;
  long nonzeros() const;  // of the pattern
  // Factors the matrix with these values (in the pattern's order). False
  // where it is not (numerically) positive definite.
  bool Factorize(const double* values);
  // x = A⁻¹ b with the last factor.
  Eigen::VectorXd Solve(const Eigen::VectorXd& b);
  // The factor's nonzeros (after the first Factorize): its memory, for reports.
  long FactorNonzeros() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace internal
}  // namespace aerotri
