// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What every camera model shares: its identifier, a description of its
// parameters (names, which are focal / principal point / distortion), and the
// Newton inversion of a model's projection.
//
// A camera model is a struct with
//   static constexpr CameraModelId kId;  static constexpr int kNumParams;
//   template <typename T> static void ImageFromNormalized(const T* params,
//       const T& u, const T& v, T* xy);           // for Jets and tests
//   static void ImageFromNormalizedWithJacobian(const double* params, double u,
//       double v, double* xy, double* d_uv, double* d_params);  // analytic
// where (u, v) = (x/z, y/z) in the camera frame (+z forward, y down) and xy
// are pixels with (0, 0) at the centre of the top-left pixel. Adding a model
// (fisheye, ...) means adding such a struct and one line in each switch of
// camera.h; the bundle adjuster is generic over it.

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace aerotri {

enum class CameraModelId { kPinhole = 0, kBrown = 1, kSnavely = 2 };

struct CameraModelInfo {
  CameraModelId id;
  std::string name;                      // "PINHOLE", "BROWN", "SNAVELY"
  std::vector<std::string> param_names;  // in parameter order
  std::vector<int> focal_params;         // indices of focal length(s)
  std::vector<int> principal_point_params;
  std::vector<int> distortion_params;
  int num_params() const { return static_cast<int>(param_names.size()); }
};

const CameraModelInfo& GetCameraModelInfo(CameraModelId id);
// Case-insensitive lookup by name; std::nullopt for an unknown name.
std::optional<CameraModelId> CameraModelIdFromName(const std::string& name);
std::vector<CameraModelId> AllCameraModelIds();

// Accuracy and limits of the Newton inversion used by CameraFromImage().
struct UndistortOptions {
  // Stop when the reprojected pixel lies this close to the target (px).
  double tolerance_px = 1e-9;
  int max_iterations = 50;
};

// Inverts Model::ImageFromNormalized by Newton's method on the 2x2 system,
// starting from the undistorted pinhole guess ((x - cx) / f, (y - cy) / f).
// Returns std::nullopt when it does not converge within the options or when it
// lands where the distortion folds over (Jacobian determinant <= 0), i.e. the
// pixel has no unique preimage. Typical accuracy is 1e-9 px.
template <typename Model>
std::optional<std::pair<double, double>> NormalizedFromImage(
    const double* params, double x, double y, double f, double cx, double cy,
    const UndistortOptions& options = {}) {
  double u = (x - cx) / f;
  double v = (y - cy) / f;
  for (int it = 0; it < options.max_iterations; ++it) {
    double xy[2];
    double j[4];
    Model::ImageFromNormalizedWithJacobian(params, u, v, xy, j, nullptr);
    const double ex = xy[0] - x;
    const double ey = xy[1] - y;
    const double det = j[0] * j[3] - j[1] * j[2];
    if (!(det > 0.0) || !std::isfinite(ex) || !std::isfinite(ey)) {
      return std::nullopt;
    }
    if (std::hypot(ex, ey) <= options.tolerance_px) {
      return std::make_pair(u, v);
    }
    // Newton step: [du dv] = -J^-1 e
    u -= (j[3] * ex - j[1] * ey) / det;
    v -= (-j[2] * ex + j[0] * ey) / det;
  }
  return std::nullopt;
}

}  // namespace aerotri
