// SPDX-License-Identifier: BSD-3-Clause
// CHOLMOD through SparseCholesky (sparse_cholesky.h) against Eigen's dense
// LLT, the reference: a block pattern like a reduced camera system's (a
// band of neighbouring cameras and a dense border of shared intrinsics),
// upper entries in the pattern ignored, the same solution over several
// factorisations of changing values, and a matrix that is not positive
// definite refused.
#include "libphoto/adjust/sparse_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

namespace aerotri {
namespace {

// A symmetric matrix on the pattern: `cameras` 6-column blocks, each
// coupled to its next `band` neighbours, and an 8-column border coupled to
// all; diagonally dominant where `definite`.
struct Pattern {
  int n = 0;
  std::vector<int> colptr, rows;
  Eigen::MatrixXd dense;
  std::vector<double> values;
};

Pattern BlockPattern(int cameras, int band, unsigned seed, bool definite) {
  const int border = 8;
  Pattern p;
  p.n = 6 * cameras + border;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto block_of = [&](int c) { return c < 6 * cameras ? c / 6 : cameras; };
  const auto coupled = [&](int r, int c) {
    const int a = block_of(r), b = block_of(c);
    return a == cameras || b == cameras || std::abs(a - b) <= band;
  };
  p.dense = Eigen::MatrixXd::Zero(p.n, p.n);
  for (int c = 0; c < p.n; ++c) {
    for (int r = c + 1; r < p.n; ++r) {
      if (coupled(r, c)) p.dense(r, c) = p.dense(c, r) = u(rng);
    }
  }
  for (int c = 0; c < p.n; ++c) {
    p.dense(c, c) = definite ? p.dense.col(c).cwiseAbs().sum() + 1.0 : (c == p.n / 2 ? -1.0 : 1.0);
  }
  // Compressed by columns; a diagonal block stored whole, its upper half
  // garbage (CHOLMOD reads the lower triangle).
  p.colptr.push_back(0);
  for (int c = 0; c < p.n; ++c) {
    for (int r = 0; r < p.n; ++r) {
      const bool same_block = block_of(r) == block_of(c);
      if (r < c && !same_block) continue;
      if (!coupled(r, c)) continue;
      p.rows.push_back(r);
      p.values.push_back(r < c ? 1e300 : p.dense(r, c));
    }
    p.colptr.push_back(static_cast<int>(p.rows.size()));
  }
  return p;
}

TEST(SparseCholesky, SolvesAsEigenOverChangingValues) {
  Pattern p = BlockPattern(60, 3, 7, true);
  internal::SparseCholesky chol(p.n, p.colptr, p.rows);
  EXPECT_EQ(chol.size(), p.n);
  EXPECT_EQ(chol.nonzeros(), static_cast<long>(p.rows.size()));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int round = 0; round < 3; ++round) {
    // New values on the same pattern (a damping that changes, as in LM).
    for (int c = 0; c < p.n; ++c) {
      p.dense(c, c) += round;
      for (int k = p.colptr[c]; k < p.colptr[c + 1]; ++k) {
        if (p.rows[k] == c) p.values[k] = p.dense(c, c);
      }
    }
    ASSERT_TRUE(chol.Factorize(p.values.data())) << round;
    Eigen::VectorXd b(p.n);
    for (int i = 0; i < p.n; ++i) b(i) = u(rng);
    const Eigen::VectorXd x = chol.Solve(b);
    const Eigen::VectorXd want = p.dense.llt().solve(b);
    EXPECT_LT((x - want).cwiseAbs().maxCoeff(), 1e-12 * want.cwiseAbs().maxCoeff()) << round;
    EXPECT_LT((p.dense * x - b).norm(), 1e-12 * b.norm()) << round;
  }
  EXPECT_GT(chol.FactorNonzeros(), 0);
}

TEST(SparseCholesky, RefusesAMatrixThatIsNotPositiveDefinite) {
  const Pattern p = BlockPattern(20, 2, 11, false);
  internal::SparseCholesky chol(p.n, p.colptr, p.rows);
  EXPECT_FALSE(chol.Factorize(p.values.data()));
  EXPECT_THROW(internal::SparseCholesky(3, {0, 1}, {0}), std::invalid_argument);
}

}  // namespace
}  // namespace aerotri
