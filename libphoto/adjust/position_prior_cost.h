// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Position prior on a 3-vector parameter block (a camera centre for GPS, a
// point for a ground control point) in the ENU adjustment frame:
//   r = ((E − E0) / σh, (N − N0) / σh, (U − U0) / σv)
// unitless, so that it weighs against reprojection residuals scaled by their
// own σ (px). Analytic Jacobian: diag(1/σh, 1/σh, 1/σv).

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace aerotri {

class PositionPriorCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  PositionPriorCost(const Eigen::Vector3d& prior, double sigma_h_m,
                    double sigma_v_m)
      : prior_(prior),
        sqrt_information_(Eigen::Vector3d(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m).asDiagonal()) {}
  // With a full covariance Σ = L Lᵀ: r = L⁻¹ (X − X0), Jacobian L⁻¹.
  PositionPriorCost(const Eigen::Vector3d& prior, const Eigen::Matrix3d& covariance)
      : prior_(prior),
        sqrt_information_(covariance.llt().matrixL().solve(Eigen::Matrix3d::Identity())) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Vector3d d = Eigen::Map<const Eigen::Vector3d>(parameters[0]) - prior_;
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = sqrt_information_ * d;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[0]);
      j = sqrt_information_;
    }
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Matrix3d sqrt_information_;
};

// GPS prior on a camera centre C with a constant offset o shared by all
// images (GNSS antenna or datum offset): the receiver reads C + o, so
//   r = ((C + o − P) / σh, …, (U + o_u − P_u) / σv);
// both Jacobians are diag(1/σh, 1/σh, 1/σv).
class OffsetPositionPriorCost final : public ceres::SizedCostFunction<3, 3, 3> {
 public:
  OffsetPositionPriorCost(const Eigen::Vector3d& prior, double sigma_h_m, double sigma_v_m)
      : prior_(prior), inv_sigma_(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    for (int i = 0; i < 3; ++i) {
      residuals[i] = (parameters[0][i] + parameters[1][i] - prior_[i]) * inv_sigma_[i];
    }
    if (jacobians != nullptr) {
      for (int b = 0; b < 2; ++b) {
        if (jacobians[b] == nullptr) continue;
        Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[b]);
        j = inv_sigma_.asDiagonal();
      }
    }
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Vector3d inv_sigma_;
};

// GPS prior through a lever arm: the antenna sits at l in the camera frame
// (OpenCV axes: x right, y down the image, z along the optical axis), so the
// receiver reads C + Rᵀ l (+ o, the shared offset, when estimated):
//   r = ((C + Rᵀ l + o − P) / σh, …, / σv).
// Blocks: cam_from_world quaternion (w, x, y, z), C, and o when kWithOffset.
// Autodiff: the rotation enters through l only (a few decimetres).
template <bool kWithOffset>
struct LeverArmPositionPrior {
  Eigen::Vector3d prior, lever, inv_sigma;
  template <typename T>
  bool Residual(const T* q, const T* c, const T* o, T* r) const {
    const T conj[4] = {q[0], -q[1], -q[2], -q[3]};
    const T l[3] = {T(lever.x()), T(lever.y()), T(lever.z())};
    T arm[3];
    ceres::UnitQuaternionRotatePoint(conj, l, arm);
    for (int i = 0; i < 3; ++i) {
      r[i] = (c[i] + arm[i] + (o ? o[i] : T(0.0)) - T(prior[i])) * T(inv_sigma[i]);
    }
    return true;
  }
  template <typename T>
  bool operator()(const T* q, const T* c, T* r) const {
    return Residual(q, c, static_cast<const T*>(nullptr), r);
  }
  template <typename T>
  bool operator()(const T* q, const T* c, const T* o, T* r) const {
    return Residual(q, c, o, r);
  }
};

inline ceres::CostFunction* MakeLeverArmPriorCost(const Eigen::Vector3d& prior, double sigma_h_m, double sigma_v_m,
                                                  const Eigen::Vector3d& lever, bool with_offset) {
  const Eigen::Vector3d inv(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m);
  if (with_offset) {
    return new ceres::AutoDiffCostFunction<LeverArmPositionPrior<true>, 3, 4, 3, 3>(
        new LeverArmPositionPrior<true>{prior, lever, inv});
  }
  return new ceres::AutoDiffCostFunction<LeverArmPositionPrior<false>, 3, 4, 3>(
      new LeverArmPositionPrior<false>{prior, lever, inv});
}

// GPS prior under the GNSS drift model: the receiver reads
// C (+ Rᵀ l) + o + d Δt, with o the shared offset, d the flight's drift rate
// (m/s) and Δt the capture time from the flight's mean:
//   r = ((C + o + d Δt − P) / σh, …, / σv).
// Analytic without a lever arm: Jacobians diag(1/σ) for C and o, Δt diag(1/σ)
// for d.
class DriftPositionPriorCost final : public ceres::SizedCostFunction<3, 3, 3, 3> {
 public:
  DriftPositionPriorCost(const Eigen::Vector3d& prior, double sigma_h_m, double sigma_v_m, double dt_s)
      : prior_(prior), inv_sigma_(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m), dt_(dt_s) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    for (int i = 0; i < 3; ++i) {
      residuals[i] = (parameters[0][i] + parameters[1][i] + dt_ * parameters[2][i] - prior_[i]) * inv_sigma_[i];
    }
    if (jacobians != nullptr) {
      for (int b = 0; b < 3; ++b) {
        if (jacobians[b] == nullptr) continue;
        Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[b]);
        j = (b == 2 ? dt_ : 1.0) * inv_sigma_.asDiagonal().toDenseMatrix();
      }
    }
    return true;
  }

 private:
  Eigen::Vector3d prior_;
  Eigen::Vector3d inv_sigma_;
  double dt_;
};

// The same through a lever arm (blocks: quaternion, C, o, d).
struct DriftLeverArmPositionPrior {
  Eigen::Vector3d prior, lever, inv_sigma;
  double dt;
  template <typename T>
  bool operator()(const T* q, const T* c, const T* o, const T* d, T* r) const {
    const T conj[4] = {q[0], -q[1], -q[2], -q[3]};
    const T l[3] = {T(lever.x()), T(lever.y()), T(lever.z())};
    T arm[3];
    ceres::UnitQuaternionRotatePoint(conj, l, arm);
    for (int i = 0; i < 3; ++i) {
      r[i] = (c[i] + arm[i] + o[i] + T(dt) * d[i] - T(prior[i])) * T(inv_sigma[i]);
    }
    return true;
  }
};

inline ceres::CostFunction* MakeDriftLeverArmPriorCost(const Eigen::Vector3d& prior, double sigma_h_m,
                                                       double sigma_v_m, const Eigen::Vector3d& lever, double dt_s) {
  return new ceres::AutoDiffCostFunction<DriftLeverArmPositionPrior, 3, 4, 3, 3, 3>(new DriftLeverArmPositionPrior{
      prior, lever, Eigen::Vector3d(1.0 / sigma_h_m, 1.0 / sigma_h_m, 1.0 / sigma_v_m), dt_s});
}

// Attitude prior on a rotation block (cam_from_world, w x y z): the
// direction d of the camera frame that should point down (a nadir photo's
// optical axis (0, 0, 1), an oblique one's gimbal vertical) is, in the
// world (ENU), g = Rᵀ d; down means its horizontal part is zero:
// r = (g_E, g_N) / σ (σ in radians; |r| σ is the sine of the tilt).
struct AttitudePrior {
  Eigen::Vector3d down_in_camera;
  double inv_sigma;
  template <typename T>
  bool operator()(const T* q, T* r) const {
    const T conj[4] = {q[0], -q[1], -q[2], -q[3]};
    const T d[3] = {T(down_in_camera.x()), T(down_in_camera.y()), T(down_in_camera.z())};
    T g[3];
    ceres::UnitQuaternionRotatePoint(conj, d, g);
    r[0] = g[0] * T(inv_sigma);
    r[1] = g[1] * T(inv_sigma);
    return true;
  }
};

// Prior on one parameter of a block of size n (a camera's focal length):
// r = (x[index] - prior) / sigma.
class ParameterPriorCost final : public ceres::CostFunction {
 public:
  ParameterPriorCost(int block_size, int index, double prior, double sigma)
      : index_(index), prior_(prior), inv_sigma_(1.0 / sigma) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(block_size);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    residuals[0] = (parameters[0][index_] - prior_) * inv_sigma_;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      const int n = parameter_block_sizes()[0];
      for (int i = 0; i < n; ++i) jacobians[0][i] = i == index_ ? inv_sigma_ : 0.0;
    }
    return true;
  }

 private:
  int index_;
  double prior_;
  double inv_sigma_;
};

}  // namespace aerotri
