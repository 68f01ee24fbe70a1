// SPDX-License-Identifier: BSD-3-Clause
// The precision pass (bundle_precision.h) against its definition: the
// inverse of the whole JᵀJ, points included, formed densely from Ceres'
// own Jacobian of the same problem. The pass never forms it: it eliminates
// the points, inverts the reduced camera system and puts the points' blocks
// and the leverages back together, on several threads.
#include "libphoto/adjust/bundle_precision.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/crs_matrix.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <random>
#include <vector>

namespace aerotri {
namespace internal {
namespace {

struct Ray {
  template <typename T>
  bool operator()(const T* q, const T* c, const T* f, const T* x, T* r) const {
    const T d[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    T p[3];
    ceres::QuaternionRotatePoint(q, d, p);
    r[0] = (f[0] * p[0] / p[2] - u) / sigma;
    r[1] = (f[0] * p[1] / p[2] - v) / sigma;
    return true;
  }
  double u, v, sigma;
};

struct Near {
  template <typename T>
  bool operator()(const T* c, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = (c[k] - at[k]) / sigma;
    return true;
  }
  std::array<double, 3> at;
  double sigma;
};

// Nadir cameras over a grid sharing a focal length, GPS on each centre,
// points seen by every camera they fall in (noisy observations at a
// perturbed state: the residuals are not zero, as at any optimum).
struct Block {
  std::vector<std::array<double, 4>> q;
  std::vector<std::array<double, 3>> c;
  std::vector<std::array<double, 3>> x;
  double f = 1000.0;
  ceres::Problem problem;
  std::vector<ceres::ResidualBlockId> rays, priors;
  std::vector<double*> points;
};

void Build(Block* b, std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 12; ++i) {
    b->q.push_back({0.0, 1.0, 0.01 * g(rng), 0.01 * g(rng)});
    Eigen::Map<Eigen::Vector4d>(b->q.back().data()).normalize();
    b->c.push_back({25.0 * (i % 4), 25.0 * (i / 4), 60.0 + g(rng)});
  }
  for (int k = 0; k < 150; ++k) b->x.push_back({-20.0 + 115.0 * u(rng), -20.0 + 90.0 * u(rng), 3.0 * g(rng)});
  for (size_t i = 0; i < b->q.size(); ++i) {
    b->problem.AddParameterBlock(b->q[i].data(), 4, new ceres::QuaternionManifold);
    const Near near{{b->c[i][0] + 0.5 * g(rng), b->c[i][1] + 0.5 * g(rng), b->c[i][2] + 0.5 * g(rng)}, 0.5};
    b->priors.push_back(b->problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Near, 3, 3>(new Near(near)),
                                                     nullptr, b->c[i].data()));
  }
  for (auto& x : b->x) {
    std::vector<size_t> seen;
    for (size_t i = 0; i < b->q.size(); ++i) {
      const double d[3] = {x[0] - b->c[i][0], x[1] - b->c[i][1], x[2] - b->c[i][2]};
      double p[3];
      ceres::QuaternionRotatePoint(b->q[i].data(), d, p);
      if (p[2] > 0.0 && std::abs(b->f * p[0] / p[2]) < 600.0 && std::abs(b->f * p[1] / p[2]) < 450.0) {
        seen.push_back(i);
      }
    }
    if (seen.size() < 2) continue;
    for (size_t i : seen) {
      const double d[3] = {x[0] - b->c[i][0], x[1] - b->c[i][1], x[2] - b->c[i][2]};
      double p[3];
      ceres::QuaternionRotatePoint(b->q[i].data(), d, p);
      const Ray ray{b->f * p[0] / p[2] + 0.7 * g(rng), b->f * p[1] / p[2] + 0.7 * g(rng), 0.5};
      b->rays.push_back(b->problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Ray, 2, 4, 3, 1, 3>(new Ray(ray)),
                                                     nullptr, b->q[i].data(), b->c[i].data(), &b->f, x.data()));
    }
    b->points.push_back(x.data());
  }
}

TEST(BundlePrecision, EqualsTheInverseOfTheWholeNormalMatrix) {
  std::mt19937 rng(17);
  Block b;
  Build(&b, rng);
  PrecisionProblem p;
  p.problem = &b.problem;
  p.points = b.points;
  for (size_t i = 0; i < b.q.size(); ++i) {
    p.reduced.push_back(b.q[i].data());
    p.reduced.push_back(b.c[i].data());
  }
  p.reduced.push_back(&b.f);
  p.adjusted = b.rays;
  p.adjusted.insert(p.adjusted.end(), b.priors.begin(), b.priors.end());
  PrecisionProblem::Group rays, gps;
  for (auto id : b.rays) rays.rows.emplace_back(id, 3u);
  for (auto id : b.priors) gps.rows.emplace_back(id, 7u);
  p.groups = {rays, gps};

  // The definition: N = JᵀJ over points then the reduced blocks, inverted.
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = p.points;
  eval.parameter_blocks.insert(eval.parameter_blocks.end(), p.reduced.begin(), p.reduced.end());
  eval.residual_blocks = p.adjusted;
  ceres::CRSMatrix crs;
  ASSERT_TRUE(b.problem.Evaluate(eval, nullptr, nullptr, nullptr, &crs));
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) j(r, crs.cols[k]) = crs.values[k];
  }
  const Eigen::MatrixXd n_inv = (j.transpose() * j).inverse();
  const Eigen::MatrixXd h = j * n_inv * j.transpose();
  const int n3 = 3 * static_cast<int>(p.points.size());
  const int nc = crs.num_cols - n3;
  ASSERT_GT(p.points.size(), 100u);

  for (int threads : {1, 2, 3}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    p.num_threads = threads;
    const PrecisionSolution s = SolvePrecision(p);
    ASSERT_TRUE(s.ok) << s.note;
    EXPECT_EQ(s.undetermined_points, 0);
    ASSERT_EQ(s.reduced_cov.rows(), nc);
    const double scale = n_inv.diagonal().cwiseAbs().maxCoeff();
    EXPECT_LT((s.reduced_cov - n_inv.bottomRightCorner(nc, nc)).cwiseAbs().maxCoeff(), 1e-9 * scale);
    double worst = 0.0;
    for (size_t k = 0; k < p.points.size(); ++k) {
      const Eigen::Matrix3d d = s.point_cov[k] - n_inv.block<3, 3>(3 * k, 3 * k);
      worst = std::max(worst, d.cwiseAbs().maxCoeff() / n_inv.block<3, 3>(3 * k, 3 * k).diagonal().maxCoeff());
    }
    EXPECT_LT(worst, 1e-8);
    // The leverages: the rays' rows first (2 each), then the priors' (3).
    const int ray_rows = 2 * static_cast<int>(b.rays.size());
    ASSERT_EQ(s.groups.size(), 2u);
    EXPECT_EQ(s.groups[0].rows, ray_rows);
    EXPECT_EQ(s.groups[1].rows, 3 * static_cast<int>(b.priors.size()));
    const double h_rays = h.diagonal().head(ray_rows).sum();
    const double h_gps = h.diagonal().tail(crs.num_rows - ray_rows).sum();
    EXPECT_NEAR(s.groups[0].leverage, h_rays, 1e-8 * h_rays);
    EXPECT_NEAR(s.groups[1].leverage, h_gps, 1e-8 * (1.0 + h_gps));
    // Σ h over all rows is the number of parameters.
    EXPECT_NEAR(s.groups[0].leverage + s.groups[1].leverage, n3 + nc, 1e-6);
  }
}

}  // namespace
}  // namespace internal
}  // namespace aerotri
