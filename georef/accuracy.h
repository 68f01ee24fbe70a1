// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Accuracy statistics of surveyed points against the adjusted survey, and the
// ASPRS Positional Accuracy Standards for Digital Geospatial Data statements:
//  - 2014 edition: horizontal accuracy at 95 % confidence = 1.7308 RMSE_r
//    (RMSE_r = sqrt(RMSE_x² + RMSE_y²), valid when RMSE_x ≈ RMSE_y), and
//    non-vegetated vertical accuracy NVA at 95 % = 1.96 RMSE_z;
//  - 2023 edition (2nd ed.): RMSE_H (= RMSE_r), RMSE_V (= RMSE_z) and
//    RMSE_3D = sqrt(RMSE_H² + RMSE_V²); 95 % statements are dropped.
// Residuals are d = adjusted − surveyed, in metres.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace aerotri {

struct AccuracyStats {
  int count = 0;
  double mean_x_m = 0, mean_y_m = 0, mean_z_m = 0;
  double rmse_x_m = 0, rmse_y_m = 0, rmse_z_m = 0;
  double rmse_h_m = 0;   // sqrt(rmse_x² + rmse_y²)
  double rmse_3d_m = 0;  // sqrt(rmse_h² + rmse_z²)
  double max_h_m = 0, max_abs_z_m = 0;

  static AccuracyStats FromResiduals(const std::vector<Eigen::Vector3d>& residuals);
};

struct AsprsStatements {
  double horizontal_accuracy_95_m = 0;  // 2014: 1.7308 RMSE_r
  double nva_95_m = 0;                  // 2014: 1.96 RMSE_z
  double rmse_h_m = 0;                  // 2023
  double rmse_v_m = 0;                  // 2023
  double rmse_3d_m = 0;                 // 2023

  static AsprsStatements From(const AccuracyStats& stats);
};

}  // namespace aerotri
