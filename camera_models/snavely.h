// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The Snavely / Bundler camera used by the BAL benchmark (Agarwal et al.,
// "Bundle Adjustment in the Large", ECCV 2010): focal length and two radial
// terms, principal point at the image centre, pixels measured from it.
//
// Parameters: f (px), k1, k2.
//   r2 = u^2 + v^2,   x_px = f (1 + k1 r2 + k2 r2^2) u,   same for y
//
// Frames: inside aerotri this model sees the usual camera frame (+z forward,
// y down). BAL files use Bundler's frame (the camera looks down -z, y up, and
// p = -P / P.z); the BAL reader converts at the file boundary with
// R_aerotri = diag(1, -1, -1) R_bal and y_aerotri = -y_bal, which leaves every
// residual's magnitude, and so the cost, unchanged.

#include "camera_models/camera_model.h"

namespace aerotri {

struct SnavelyModel {
  static constexpr CameraModelId kId = CameraModelId::kSnavely;
  static constexpr int kNumParams = 3;

  template <typename T>
  static void ImageFromNormalized(const T* params, const T& u, const T& v,
                                  T* xy) {
    const T r2 = u * u + v * v;
    const T scale = params[0] * (T(1.0) + r2 * (params[1] + r2 * params[2]));
    xy[0] = scale * u;
    xy[1] = scale * v;
  }

  static void ImageFromNormalizedWithJacobian(const double* params, double u,
                                              double v, double* xy,
                                              double* d_uv, double* d_params) {
    const double f = params[0], k1 = params[1], k2 = params[2];
    const double r2 = u * u + v * v;
    const double radial = 1.0 + r2 * (k1 + r2 * k2);
    xy[0] = f * radial * u;
    xy[1] = f * radial * v;
    if (d_uv) {
      const double dr = k1 + 2.0 * k2 * r2;  // d radial / d r2
      const double cross = f * 2.0 * u * v * dr;
      d_uv[0] = f * (radial + 2.0 * u * u * dr);
      d_uv[1] = cross;
      d_uv[2] = cross;
      d_uv[3] = f * (radial + 2.0 * v * v * dr);
    }
    if (d_params) {
      d_params[0] = radial * u; d_params[1] = f * u * r2; d_params[2] = f * u * r2 * r2;
      d_params[3] = radial * v; d_params[4] = f * v * r2; d_params[5] = f * v * r2 * r2;
    }
  }
};

}  // namespace aerotri
