// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Position prior on a 3-vector parameter block (a camera centre for GPS, a
// point for a ground control point) in the ENU adjustment frame:
//   r = ((E − E0) / σh, (N − N0) / σh, (U − U0) / σv)
// unitless, so that it weighs against reprojection residuals scaled by their
// own σ (px). Analytic Jacobian: diag(1/σh, 1/σh, 1/σv).

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

namespace aerotri {

class PositionPriorCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  PositionPriorCost(const Eigen::Vector3d& prior, double sigma_h_m,
                    double sigma_v_m)
      : prior_(prior),
        inv_sigma_(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    for (int i = 0; i < 3; ++i) {
      residuals[i] = (parameters[0][i] - prior_[i]) * inv_sigma_[i];
    }
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[0]);
      j = inv_sigma_.asDiagonal();
    }
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Vector3d inv_sigma_;
};

}  // namespace aerotri
