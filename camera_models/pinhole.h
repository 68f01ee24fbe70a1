// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Pinhole camera without distortion.
//
// Frames: the camera looks along +z, x right, y down; (u, v) = (x/z, y/z) are
// normalised image coordinates; pixels have (0, 0) at the centre of the
// top-left pixel (OpenCV). Parameters: f, cx, cy (all in pixels).
//   x_px = f u + cx,   y_px = f v + cy

#include "camera_models/camera_model.h"

namespace aerotri {

struct PinholeModel {
  static constexpr CameraModelId kId = CameraModelId::kPinhole;
  static constexpr int kNumParams = 3;

  template <typename T>
  static void ImageFromNormalized(const T* params, const T& u, const T& v,
                                  T* xy) {
    xy[0] = params[0] * u + params[1];
    xy[1] = params[0] * v + params[2];
  }

  // Analytic Jacobians, row-major: d_uv is 2x2 (d xy / d (u, v)), d_params is
  // 2 x kNumParams. Either output may be null.
  static void ImageFromNormalizedWithJacobian(const double* params, double u,
                                              double v, double* xy,
                                              double* d_uv, double* d_params) {
    const double f = params[0];
    xy[0] = f * u + params[1];
    xy[1] = f * v + params[2];
    if (d_uv) {
      d_uv[0] = f;   d_uv[1] = 0.0;
      d_uv[2] = 0.0; d_uv[3] = f;
    }
    if (d_params) {
      d_params[0] = u; d_params[1] = 1.0; d_params[2] = 0.0;
      d_params[3] = v; d_params[4] = 0.0; d_params[5] = 1.0;
    }
  }
};

}  // namespace aerotri
