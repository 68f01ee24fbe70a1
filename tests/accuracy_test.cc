// SPDX-License-Identifier: BSD-3-Clause
#include "georef/accuracy.h"

#include <gtest/gtest.h>

namespace aerotri {
namespace {

TEST(Accuracy, RmseAndAsprsStatementsByHand) {
  // Residuals chosen so every figure is checkable by hand.
  const std::vector<Eigen::Vector3d> d = {{0.03, 0.04, 0.10}, {-0.03, -0.04, -0.10}};
  const AccuracyStats s = AccuracyStats::FromResiduals(d);
  EXPECT_EQ(s.count, 2);
  EXPECT_NEAR(s.rmse_x_m, 0.03, 1e-15);
  EXPECT_NEAR(s.rmse_y_m, 0.04, 1e-15);
  EXPECT_NEAR(s.rmse_z_m, 0.10, 1e-15);
  EXPECT_NEAR(s.rmse_h_m, 0.05, 1e-15);
  EXPECT_NEAR(s.rmse_3d_m, std::sqrt(0.0125), 1e-15);
  EXPECT_NEAR(s.mean_z_m, 0.0, 1e-15);
  EXPECT_NEAR(s.max_h_m, 0.05, 1e-15);
  const AsprsStatements a = AsprsStatements::From(s);
  EXPECT_NEAR(a.horizontal_accuracy_95_m, 1.7308 * 0.05, 1e-15);  // ASPRS 2014
  EXPECT_NEAR(a.nva_95_m, 1.96 * 0.10, 1e-15);                     // ASPRS 2014
  EXPECT_NEAR(a.rmse_3d_m, std::sqrt(0.05 * 0.05 + 0.1 * 0.1), 1e-15);  // ASPRS 2023
  EXPECT_EQ(AccuracyStats::FromResiduals({}).count, 0);
}

}  // namespace
}  // namespace aerotri
