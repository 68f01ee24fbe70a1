// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Brown–Conrady lens distortion (radial k1..k3, tangential p1, p2) on a pinhole
// camera, with OpenCV's formula.
//
// Frames: the camera looks along +z, x right, y down; (u, v) = (x/z, y/z);
// pixels have (0, 0) at the centre of the top-left pixel.
// Parameters (aerotri order): f, cx, cy, k1, k2, k3, p1, p2 (f, cx, cy in px).
// OpenCV's distCoeffs order is (k1, k2, p1, p2, k3): see ToOpenCvDistCoeffs().
//
//   r2 = u^2 + v^2,   radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
//   ud = u radial + 2 p1 u v + p2 (r2 + 2 u^2)
//   vd = v radial + p1 (r2 + 2 v^2) + 2 p2 u v
//   x_px = f ud + cx,   y_px = f vd + cy
//
// Reference: D. C. Brown, "Decentering distortion of lenses", 1966; OpenCV
// calib3d, projectPoints().

#include <array>

#include "camera_models/camera_model.h"

namespace aerotri {

struct BrownModel {
  static constexpr CameraModelId kId = CameraModelId::kBrown;
  static constexpr int kNumParams = 8;

  template <typename T>
  static void ImageFromNormalized(const T* params, const T& u, const T& v,
                                  T* xy) {
    const T& f = params[0];
    const T& k1 = params[3];
    const T& k2 = params[4];
    const T& k3 = params[5];
    const T& p1 = params[6];
    const T& p2 = params[7];
    const T uu = u * u, vv = v * v, uv = u * v;
    const T r2 = uu + vv;
    const T radial = T(1.0) + r2 * (k1 + r2 * (k2 + r2 * k3));
    const T ud = u * radial + T(2.0) * p1 * uv + p2 * (r2 + T(2.0) * uu);
    const T vd = v * radial + p1 * (r2 + T(2.0) * vv) + T(2.0) * p2 * uv;
    xy[0] = f * ud + params[1];
    xy[1] = f * vd + params[2];
  }

  static void ImageFromNormalizedWithJacobian(const double* params, double u,
                                              double v, double* xy,
                                              double* d_uv, double* d_params) {
    const double f = params[0];
    const double k1 = params[3], k2 = params[4], k3 = params[5];
    const double p1 = params[6], p2 = params[7];
    const double uu = u * u, vv = v * v, uv = u * v;
    const double r2 = uu + vv;
    const double r4 = r2 * r2;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double ud = u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * uu);
    const double vd = v * radial + p1 * (r2 + 2.0 * vv) + 2.0 * p2 * uv;
    xy[0] = f * ud + params[1];
    xy[1] = f * vd + params[2];
    if (d_uv) {
      // d radial / d r2
      const double dr = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4;
      const double cross = 2.0 * uv * dr + 2.0 * p1 * u + 2.0 * p2 * v;
      d_uv[0] = f * (radial + 2.0 * uu * dr + 2.0 * p1 * v + 6.0 * p2 * u);
      d_uv[1] = f * cross;
      d_uv[2] = f * cross;
      d_uv[3] = f * (radial + 2.0 * vv * dr + 6.0 * p1 * v + 2.0 * p2 * u);
    }
    if (d_params) {
      double* row0 = d_params;
      double* row1 = d_params + kNumParams;
      row0[0] = ud;  row0[1] = 1.0; row0[2] = 0.0;
      row1[0] = vd;  row1[1] = 0.0; row1[2] = 1.0;
      row0[3] = f * u * r2; row0[4] = f * u * r4; row0[5] = f * u * r4 * r2;
      row1[3] = f * v * r2; row1[4] = f * v * r4; row1[5] = f * v * r4 * r2;
      row0[6] = f * 2.0 * uv;        row0[7] = f * (r2 + 2.0 * uu);
      row1[6] = f * (r2 + 2.0 * vv); row1[7] = f * 2.0 * uv;
    }
  }

  // OpenCV distCoeffs (k1, k2, p1, p2, k3) from aerotri parameters.
  static std::array<double, 5> ToOpenCvDistCoeffs(const double* params) {
    return {params[3], params[4], params[6], params[7], params[5]};
  }
};

}  // namespace aerotri
