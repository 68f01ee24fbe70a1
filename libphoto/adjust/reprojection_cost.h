// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Reprojection residual with analytic Jacobians, generic over camera models.
//
// Parameter blocks, in order:
//   cam_from_world  4  unit quaternion (w, x, y, z), Ceres order; refine it on
//                      ceres::QuaternionManifold (never additively)
//   centre_in_world 3  camera centre C in the adjustment frame
//   point_in_world  3  point X in the adjustment frame
//   intrinsics      N  Model parameters (camera_models/)
// Residual (2): (Model(R (X - C)) - observed_xy) / sigma_px, unitless; with
// sigma_px = 1 it is in pixels and the cost is the BAL/Ceres ½Σ‖r‖² in px².
//
// Jacobians: with d = X - C, p = R d, and for a unit quaternion
//   R d = d + 2w (v × d) + 2 v × (v × d),   v = (x, y, z)
//   ∂p/∂w = 2 (v × d)
//   ∂p/∂v = −2w [d]× + 2 ((v·d) I + v dᵀ − 2 d vᵀ)
//   ∂p/∂X = R,  ∂p/∂C = −R,  ∂(u,v)/∂p = [1/z 0 −x/z²; 0 1/z −y/z²]
// and the model supplies ∂xy/∂(u,v) and ∂xy/∂intrinsics.
//
// A rolling-shutter photo's observation carries the shift of the camera
// centre at its row (RollingShutterMotion::CentreShift, sparse_model.h): the
// residual is then Model(R (X − C − shift)), with the same Jacobians (the
// shift is a constant of the observation: its row is measured, and the
// motion known).
//
// Points behind the camera are evaluated like any other (the residual still
// measures the misfit); only z ≈ 0, where the projection is undefined, makes
// Evaluate() return false so that Ceres rejects the step.

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <cmath>

namespace aerotri {

// Residual and analytic Jacobians of one observation. Jacobian outputs are
// row-major (2x4, 2x3, 2x3, 2xN) and may be null. Returns false where the
// projection is undefined (point on the camera plane).
template <typename Model>
inline bool EvaluateReprojection(const double* q, const double* c, const double* x,
                                 const double* intrinsics, const Eigen::Vector2d& observed,
                                 double inv_sigma, double* residuals, double* j_q,
                                 double* j_c, double* j_x, double* j_k) {
  const double w = q[0];
  const Eigen::Vector3d v(q[1], q[2], q[3]);
  const Eigen::Vector3d d(x[0] - c[0], x[1] - c[1], x[2] - c[2]);
  const Eigen::Vector3d vxd = v.cross(d);
  const Eigen::Vector3d p = d + 2.0 * w * vxd + 2.0 * v.cross(vxd);

  if (!(std::abs(p.z()) > 1e-12 * (1.0 + d.norm()))) return false;
  const double inv_z = 1.0 / p.z();
  const double u = p.x() * inv_z;
  const double vv = p.y() * inv_z;

  double xy[2];
  const bool any_jacobian = j_q || j_c || j_x || j_k;
  double d_uv[4];
  Model::ImageFromNormalizedWithJacobian(intrinsics, u, vv, xy,
                                         any_jacobian ? d_uv : nullptr, j_k);
  residuals[0] = (xy[0] - observed.x()) * inv_sigma;
  residuals[1] = (xy[1] - observed.y()) * inv_sigma;
  if (!any_jacobian) return true;
  if (j_k != nullptr) {
    for (int i = 0; i < 2 * Model::kNumParams; ++i) j_k[i] *= inv_sigma;
  }

  // A = ∂xy/∂(u,v) · ∂(u,v)/∂p, scaled by 1/sigma (2x3).
  const Eigen::Map<const Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> j_uv(d_uv);
  Eigen::Matrix<double, 2, 3> d_uv_d_p;
  d_uv_d_p << inv_z, 0.0, -u * inv_z, 0.0, inv_z, -vv * inv_z;
  const Eigen::Matrix<double, 2, 3> a = inv_sigma * (j_uv * d_uv_d_p);

  if (j_q != nullptr) {
    Eigen::Matrix<double, 3, 4> dp_dq;
    dp_dq.col(0) = 2.0 * vxd;
    Eigen::Matrix3d d_cross;
    d_cross << 0.0, -d.z(), d.y(), d.z(), 0.0, -d.x(), -d.y(), d.x(), 0.0;
    dp_dq.rightCols<3>() = -2.0 * w * d_cross +
                           2.0 * (v.dot(d) * Eigen::Matrix3d::Identity() +
                                  v * d.transpose() - 2.0 * d * v.transpose());
    Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> jq(j_q);
    jq = a * dp_dq;
  }
  if (j_c != nullptr || j_x != nullptr) {
    const double x2 = v.x(), y2 = v.y(), z2 = v.z();
    Eigen::Matrix3d r;
    r << 1 - 2 * (y2 * y2 + z2 * z2), 2 * (x2 * y2 - w * z2), 2 * (x2 * z2 + w * y2),
        2 * (x2 * y2 + w * z2), 1 - 2 * (x2 * x2 + z2 * z2), 2 * (y2 * z2 - w * x2),
        2 * (x2 * z2 - w * y2), 2 * (y2 * z2 + w * x2), 1 - 2 * (x2 * x2 + y2 * y2);
    const Eigen::Matrix<double, 2, 3> a_r = a * r;
    if (j_c != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jc(j_c);
      jc = -a_r;
    }
    if (j_x != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jx(j_x);
      jx = a_r;
    }
  }
  return true;
}

// Separate blocks: cam_from_world (4), centre (3), point (3), intrinsics (N).
// Used when a camera group is shared by several images.
template <typename Model>
class ReprojectionCost final
    : public ceres::SizedCostFunction<2, 4, 3, 3, Model::kNumParams> {
 public:
  explicit ReprojectionCost(const Eigen::Vector2d& observed_xy, double sigma_px = 1.0,
                            const Eigen::Vector3d& centre_shift = Eigen::Vector3d::Zero())
      : observed_(observed_xy), inv_sigma_(1.0 / sigma_px), shift_(centre_shift) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Vector3d centre =
        Eigen::Map<const Eigen::Vector3d>(parameters[1]) + shift_;
    return EvaluateReprojection<Model>(
        parameters[0], centre.data(), parameters[2], parameters[3], observed_, inv_sigma_,
        residuals, jacobians ? jacobians[0] : nullptr, jacobians ? jacobians[1] : nullptr,
        jacobians ? jacobians[2] : nullptr, jacobians ? jacobians[3] : nullptr);
  }

 private:
  Eigen::Vector2d observed_;
  double inv_sigma_;
  Eigen::Vector3d shift_;
};

// A rolling-shutter observation whose camera group's readout time is
// estimated: blocks cam_from_world (4), centre (3), point (3), intrinsics
// (N) and the readout time (1, seconds). The centre at the row is
// C + r · f · v, f the row's fraction of the readout from its middle
// (RollingShutterMotion::RowTime / readout) and v the photo's velocity, so
// ∂res/∂r = ∂res/∂C · f v.
template <typename Model>
class RollingShutterReprojectionCost final
    : public ceres::SizedCostFunction<2, 4, 3, 3, Model::kNumParams, 1> {
 public:
  RollingShutterReprojectionCost(const Eigen::Vector2d& observed_xy, double sigma_px, double row_fraction,
                                 const Eigen::Vector3d& velocity)
      : observed_(observed_xy), inv_sigma_(1.0 / sigma_px), per_second_(row_fraction * velocity) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Vector3d centre = Eigen::Map<const Eigen::Vector3d>(parameters[1]) + parameters[4][0] * per_second_;
    double* j_c = jacobians ? jacobians[1] : nullptr;
    double j_c_local[6];
    if (jacobians != nullptr && jacobians[4] != nullptr && j_c == nullptr) j_c = j_c_local;
    if (!EvaluateReprojection<Model>(parameters[0], centre.data(), parameters[2], parameters[3], observed_,
                                     inv_sigma_, residuals, jacobians ? jacobians[0] : nullptr, j_c,
                                     jacobians ? jacobians[2] : nullptr, jacobians ? jacobians[3] : nullptr)) {
      return false;
    }
    if (jacobians != nullptr && jacobians[4] != nullptr) {
      const Eigen::Map<const Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jc(j_c);
      Eigen::Map<Eigen::Vector2d> j_r(jacobians[4]);
      j_r = jc * per_second_;
    }
    return true;
  }

 private:
  Eigen::Vector2d observed_;
  double inv_sigma_;
  Eigen::Vector3d per_second_;  // the centre's shift per second of readout
};

// One block per image, [cam_from_world (4), centre (3), intrinsics (N)], and
// the point (3). Used when an image has its camera group to itself (BAL):
// Ceres then sees one uniform camera block per image and picks its
// specialised Schur eliminator (e.g. 2,3,9 for SNAVELY).
template <typename Model>
class ReprojectionCostMergedCamera final
    : public ceres::SizedCostFunction<2, 7 + Model::kNumParams, 3> {
 public:
  static constexpr int kCameraSize = 7 + Model::kNumParams;
  explicit ReprojectionCostMergedCamera(const Eigen::Vector2d& observed_xy,
                                        double sigma_px = 1.0,
                                        const Eigen::Vector3d& centre_shift = Eigen::Vector3d::Zero())
      : observed_(observed_xy), inv_sigma_(1.0 / sigma_px), shift_(centre_shift) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const double* camera = parameters[0];
    const Eigen::Vector3d centre = Eigen::Map<const Eigen::Vector3d>(camera + 4) + shift_;
    double* j_camera = jacobians ? jacobians[0] : nullptr;
    if (j_camera == nullptr) {
      return EvaluateReprojection<Model>(camera, centre.data(), parameters[1], camera + 7,
                                         observed_, inv_sigma_, residuals, nullptr, nullptr,
                                         jacobians ? jacobians[1] : nullptr, nullptr);
    }
    double j_q[8], j_c[6], j_k[2 * Model::kNumParams];
    if (!EvaluateReprojection<Model>(camera, centre.data(), parameters[1], camera + 7,
                                     observed_, inv_sigma_, residuals, j_q, j_c,
                                     jacobians[1], j_k)) {
      return false;
    }
    for (int r = 0; r < 2; ++r) {
      double* row = j_camera + r * kCameraSize;
      for (int i = 0; i < 4; ++i) row[i] = j_q[r * 4 + i];
      for (int i = 0; i < 3; ++i) row[4 + i] = j_c[r * 3 + i];
      for (int i = 0; i < Model::kNumParams; ++i) row[7 + i] = j_k[r * Model::kNumParams + i];
    }
    return true;
  }

 private:
  Eigen::Vector2d observed_;
  double inv_sigma_;
  Eigen::Vector3d shift_;
};

// Reference implementation of the same residual for Ceres Jets (tests compare
// the analytic Jacobians of ReprojectionCost against it).
template <typename Model>
struct ReprojectionResidualFunctor {
  Eigen::Vector2d observed;
  double sigma_px = 1.0;

  template <typename T>
  bool operator()(const T* q, const T* c, const T* x, const T* intrinsics,
                  T* residuals) const {
    const T d[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    // R(q) d for a unit quaternion, written out as rotation matrix times d.
    const T w = q[0], qx = q[1], qy = q[2], qz = q[3];
    const T p0 = (T(1) - T(2) * (qy * qy + qz * qz)) * d[0] +
                 T(2) * (qx * qy - w * qz) * d[1] + T(2) * (qx * qz + w * qy) * d[2];
    const T p1 = T(2) * (qx * qy + w * qz) * d[0] +
                 (T(1) - T(2) * (qx * qx + qz * qz)) * d[1] +
                 T(2) * (qy * qz - w * qx) * d[2];
    const T p2 = T(2) * (qx * qz - w * qy) * d[0] + T(2) * (qy * qz + w * qx) * d[1] +
                 (T(1) - T(2) * (qx * qx + qy * qy)) * d[2];
    const T u = p0 / p2;
    const T v = p1 / p2;
    T xy[2];
    Model::ImageFromNormalized(intrinsics, u, v, xy);
    residuals[0] = (xy[0] - T(observed.x())) / T(sigma_px);
    residuals[1] = (xy[1] - T(observed.y())) / T(sigma_px);
    return true;
  }
};

}  // namespace aerotri
