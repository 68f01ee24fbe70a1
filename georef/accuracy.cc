// SPDX-License-Identifier: BSD-3-Clause
#include "georef/accuracy.h"

#include <algorithm>
#include <cmath>

namespace aerotri {

AccuracyStats AccuracyStats::FromResiduals(const std::vector<Eigen::Vector3d>& residuals) {
  AccuracyStats s;
  s.count = static_cast<int>(residuals.size());
  if (residuals.empty()) return s;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sq = Eigen::Vector3d::Zero();
  for (const auto& d : residuals) {
    sum += d;
    sq += d.cwiseAbs2();
    s.max_h_m = std::max(s.max_h_m, d.head<2>().norm());
    s.max_abs_z_m = std::max(s.max_abs_z_m, std::abs(d.z()));
  }
  const double n = static_cast<double>(residuals.size());
  s.mean_x_m = sum.x() / n;
  s.mean_y_m = sum.y() / n;
  s.mean_z_m = sum.z() / n;
  s.rmse_x_m = std::sqrt(sq.x() / n);
  s.rmse_y_m = std::sqrt(sq.y() / n);
  s.rmse_z_m = std::sqrt(sq.z() / n);
  s.rmse_h_m = std::hypot(s.rmse_x_m, s.rmse_y_m);
  s.rmse_3d_m = std::hypot(s.rmse_h_m, s.rmse_z_m);
  return s;
}

AsprsStatements AsprsStatements::From(const AccuracyStats& stats) {
  AsprsStatements a;
  a.horizontal_accuracy_95_m = 1.7308 * stats.rmse_h_m;
  a.nva_95_m = 1.96 * stats.rmse_z_m;
  a.rmse_h_m = stats.rmse_h_m;
  a.rmse_v_m = stats.rmse_z_m;
  a.rmse_3d_m = stats.rmse_3d_m;
  return a;
}

}  // namespace aerotri
