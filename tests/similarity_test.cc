// SPDX-License-Identifier: BSD-3-Clause
#include "georef/similarity.h"

#include <gtest/gtest.h>

#include <random>

namespace aerotri {
namespace {

Similarity Known() {
  Similarity s;
  s.scale = 37.5;
  s.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()));
  s.translation = {1200.0, -340.0, 55.0};
  return s;
}

TEST(Similarity, RecoversAKnownTransformExactly) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  const Similarity truth = Known();
  std::vector<Eigen::Vector3d> from, to;
  for (int i = 0; i < 20; ++i) {
    from.emplace_back(g(rng), g(rng), g(rng));
    to.push_back(truth.Apply(from.back()));
  }
  const auto s = FitSimilarity(from, to);
  ASSERT_TRUE(s.has_value());
  EXPECT_NEAR(s->scale, truth.scale, 1e-9);
  EXPECT_LT(s->rotation.angularDistance(truth.rotation), 1e-10);
  EXPECT_LT((s->translation - truth.translation).norm(), 1e-8);
  const Similarity inv = s->Inverse();
  EXPECT_LT((inv.Apply(to[3]) - from[3]).norm(), 1e-10);
}

TEST(Similarity, RobustFitIgnoresGrossOutliersAndStaysAtTheNoise) {
  std::mt19937 rng(6);
  std::normal_distribution<double> g(0.0, 1.0);
  const Similarity truth = Known();
  std::vector<Eigen::Vector3d> from, to;
  const double noise = 0.5;  // metres in the target frame
  for (int i = 0; i < 60; ++i) {
    from.emplace_back(3 * g(rng), 3 * g(rng), 0.3 * g(rng));
    to.push_back(truth.Apply(from.back()) + noise * Eigen::Vector3d(g(rng), g(rng), g(rng)));
  }
  for (int i = 0; i < 12; ++i) to[i * 5] += Eigen::Vector3d(80.0, -60.0, 40.0);  // 20 % outliers
  const auto fit = FitSimilarityRobust(from, to, 3.0, 1);
  ASSERT_TRUE(fit.has_value());
  EXPECT_EQ(fit->num_inliers, 48);
  for (int i = 0; i < 12; ++i) EXPECT_FALSE(fit->inliers[i * 5]);
  // RMS of 3D residuals of N(0, 0.5) per axis is 0.5 sqrt(3) = 0.87 m.
  EXPECT_GT(fit->rms_m, 0.6);
  EXPECT_LT(fit->rms_m, 1.1);
  EXPECT_NEAR(fit->transform.scale, truth.scale, 0.02 * truth.scale);
}

TEST(Similarity, CollinearOrTooFewPointsHaveNoAnswer) {
  EXPECT_FALSE(FitSimilarity({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}).has_value());
  EXPECT_FALSE(FitSimilarity({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}})
                   .has_value());
  EXPECT_FALSE(FitSimilarityRobust({{0, 0, 0}}, {{0, 0, 0}}, 1.0).has_value());
}

}  // namespace
}  // namespace aerotri
