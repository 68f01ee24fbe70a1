// SPDX-License-Identifier: BSD-3-Clause
// The threaded blocked Cholesky (dense_cholesky.h) against Eigen's LLT, the
// reference: the same factor and solution on sizes that leave a ragged last
// block, and a matrix that is not positive definite refused.
#include "libphoto/adjust/dense_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

namespace aerotri {
namespace {

Eigen::MatrixXd Spd(int n, unsigned seed) {
  std::srand(seed);
  const Eigen::MatrixXd g = Eigen::MatrixXd::Random(n, n / 2 + 3);
  Eigen::MatrixXd s = g * g.transpose();
  s.diagonal().array() += 1.0;
  return s;
}

TEST(DenseCholesky, EqualsEigensFactorAndSolution) {
  for (const int n : {5, 300, 1001}) {
    const Eigen::MatrixXd s = Spd(n, 3 + n);
    const Eigen::VectorXd b = Eigen::VectorXd::Random(n);
    const Eigen::LLT<Eigen::MatrixXd> want(s);
    ASSERT_EQ(want.info(), Eigen::Success);
    for (const unsigned threads : {1u, 2u, 3u}) {
      Eigen::MatrixXd a = s;
      a.triangularView<Eigen::StrictlyUpper>().setConstant(1e300);  // only the lower triangle is read
      ASSERT_TRUE(internal::CholeskyInPlace(&a, threads)) << n;
      const Eigen::MatrixXd l = a.triangularView<Eigen::Lower>();
      const Eigen::MatrixXd ref = want.matrixL();
      EXPECT_LT((l - ref).cwiseAbs().maxCoeff(), 1e-10 * ref.cwiseAbs().maxCoeff()) << n << " " << threads;
      const Eigen::VectorXd x = internal::CholeskySolve(a, b);
      EXPECT_LT((s * x - b).norm(), 1e-9 * b.norm()) << n << " " << threads;
    }
  }
}

TEST(DenseCholesky, ANotPositiveDefiniteMatrixIsRefused) {
  for (const int n : {5, 1001}) {
    Eigen::MatrixXd s = Spd(n, 11);
    s(n - 2, n - 2) = -1.0;  // in the last block
    EXPECT_FALSE(internal::CholeskyInPlace(&s, 2)) << n;
  }
}

}  // namespace
}  // namespace aerotri
