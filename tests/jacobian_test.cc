// SPDX-License-Identifier: BSD-3-Clause
// aerotri's Jacobian evaluation (jacobian.h) against Ceres' own
// Problem::Evaluate, the reference: residuals and Jacobian entry for entry,
// with robust losses (Huber in and beyond its knee, Cauchy), a quaternion
// manifold, a held block and a block left out of the columns.
#include "libphoto/adjust/jacobian.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>

namespace aerotri {
namespace {

// A point seen through a rotation and a shift: 2 residuals, blocks
// (quaternion 4, shift 3, point 3).
struct Project {
  Project(double u, double v) : u(u), v(v) {}
  template <typename T>
  bool operator()(const T* q, const T* t, const T* x, T* r) const {
    T p[3];
    ceres::QuaternionRotatePoint(q, x, p);
    for (int i = 0; i < 3; ++i) p[i] += t[i];
    r[0] = p[0] / p[2] - u;
    r[1] = p[1] / p[2] - v;
    return true;
  }
  double u, v;
};

// A prior on a shift: 3 residuals.
struct Prior {
  template <typename T>
  bool operator()(const T* t, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = (t[i] - T(0.1 * i)) / T(0.05);
    return true;
  }
};

Eigen::MatrixXd Dense(const ceres::CRSMatrix& m) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(m.num_rows, m.num_cols);
  for (int r = 0; r < m.num_rows; ++r) {
    for (int k = m.rows[r]; k < m.rows[r + 1]; ++k) d(r, m.cols[k]) = m.values[k];
  }
  return d;
}

TEST(Jacobian, EqualsCeresEvaluateWithLossesManifoldsAndHeldBlocks) {
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  ceres::Problem problem;
  std::vector<std::array<double, 4>> q(3);
  std::vector<std::array<double, 3>> t(3);
  std::vector<std::array<double, 3>> x(40);
  for (size_t c = 0; c < q.size(); ++c) {
    Eigen::Vector4d v(1.0, 0.05 * gauss(rng), 0.05 * gauss(rng), 0.05 * gauss(rng));
    v.normalize();
    q[c] = {v(0), v(1), v(2), v(3)};
    t[c] = {0.3 * gauss(rng), 0.3 * gauss(rng), 0.1 * gauss(rng)};
  }
  for (auto& p : x) p = {gauss(rng), gauss(rng), 8.0 + gauss(rng)};
  std::vector<ceres::ResidualBlockId> ids;
  for (size_t p = 0; p < x.size(); ++p) {
    for (size_t c = 0; c < q.size(); ++c) {
      // Every fifth observation a blunder (beyond Huber's knee).
      const double blunder = (p * 3 + c) % 5 == 0 ? 0.3 : 0.0;
      ceres::LossFunction* loss = c == 2 ? static_cast<ceres::LossFunction*>(new ceres::CauchyLoss(0.02))
                                         : static_cast<ceres::LossFunction*>(new ceres::HuberLoss(0.05));
      ids.push_back(problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<Project, 2, 4, 3, 3>(
              new Project(x[p][0] / x[p][2] + 0.01 * gauss(rng) + blunder, x[p][1] / x[p][2] + 0.01 * gauss(rng))),
          loss, q[c].data(), t[c].data(), x[p].data()));
    }
  }
  for (size_t c = 0; c < t.size(); ++c) {
    ids.push_back(problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Prior, 3, 3>(new Prior), nullptr,
                                           t[c].data()));
  }
  for (auto& v : q) problem.SetManifold(v.data(), new ceres::QuaternionManifold);
  problem.SetParameterBlockConstant(t[0].data());  // held
  // Columns: the points, then rotations 1 and 2 and shift 2 (rotation 0 and
  // shift 1 left out, so held as well).
  std::vector<double*> blocks;
  for (auto& p : x) blocks.push_back(p.data());
  blocks.push_back(q[2].data());
  blocks.push_back(q[1].data());
  blocks.push_back(t[2].data());

  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = blocks;
  eval.residual_blocks = ids;
  eval.apply_loss_function = true;
  std::vector<double> want_r;
  ceres::CRSMatrix want_j;
  ASSERT_TRUE(problem.Evaluate(eval, nullptr, &want_r, nullptr, &want_j));

  std::vector<double> got_r;
  ceres::CRSMatrix got_j;
  ASSERT_TRUE(internal::EvaluateJacobian(problem, ids, blocks, 2, &got_r, &got_j));
  ASSERT_EQ(got_r.size(), want_r.size());
  ASSERT_EQ(got_j.num_rows, want_j.num_rows);
  ASSERT_EQ(got_j.num_cols, want_j.num_cols);
  int corrected = 0;
  for (size_t i = 0; i < want_r.size(); ++i) {
    EXPECT_NEAR(got_r[i], want_r[i], 1e-12 * (1.0 + std::abs(want_r[i]))) << "row " << i;
  }
  const Eigen::MatrixXd a = Dense(got_j), b = Dense(want_j);
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-10 * b.cwiseAbs().maxCoeff());
  // Each row's columns ascending, as the precision pass reads them.
  for (int r = 0; r < got_j.num_rows; ++r) {
    for (int k = got_j.rows[r] + 1; k < got_j.rows[r + 1]; ++k) EXPECT_LT(got_j.cols[k - 1], got_j.cols[k]);
  }
  // The losses did act: some rows differ from their uncorrected values.
  eval.apply_loss_function = false;
  std::vector<double> raw;
  ASSERT_TRUE(problem.Evaluate(eval, nullptr, &raw, nullptr, nullptr));
  for (size_t i = 0; i < raw.size(); ++i) corrected += std::abs(raw[i] - want_r[i]) > 1e-9;
  EXPECT_GT(corrected, 10);
}

// A cost that cannot be evaluated fails the evaluation.
struct Fails : ceres::SizedCostFunction<1, 1> {
  bool Evaluate(double const* const*, double*, double**) const override { return false; }
};

TEST(Jacobian, AFailingCostFailsTheEvaluation) {
  ceres::Problem problem;
  double x = 1.0;
  const ceres::ResidualBlockId id = problem.AddResidualBlock(new Fails, nullptr, &x);
  std::vector<double> r;
  ceres::CRSMatrix j;
  EXPECT_FALSE(internal::EvaluateJacobian(problem, {id}, {&x}, 1, &r, &j));
}

}  // namespace
}  // namespace aerotri
