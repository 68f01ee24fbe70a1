// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A physical camera (one camera group of a survey): a model, its parameters
// and the image size, with projection and unprojection through that model.
//
// Frames: point_in_cam is in the camera frame (+z forward, x right, y down);
// pixels have (0, 0) at the centre of the top-left pixel (OpenCV convention).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>
#include <utility>

#include "camera_models/brown.h"
#include "camera_models/camera_model.h"
#include "camera_models/pinhole.h"
#include "camera_models/snavely.h"

namespace aerotri {

// Calls fn(Model{}) with the model struct for id (a switch, no macros).
template <typename Fn>
decltype(auto) VisitCameraModel(CameraModelId id, Fn&& fn) {
  switch (id) {
    case CameraModelId::kPinhole:
      return fn(PinholeModel{});
    case CameraModelId::kBrown:
      return fn(BrownModel{});
    case CameraModelId::kSnavely:
      return fn(SnavelyModel{});
  }
  return fn(PinholeModel{});  // unreachable for a valid enum value
}

struct Camera {
  int id = 0;
  CameraModelId model = CameraModelId::kPinhole;
  int width = 0;   // px
  int height = 0;  // px
  std::vector<double> params;

  // A camera of the given model with focal length f and principal point at
  // the image centre ((width - 1) / 2, (height - 1) / 2), no distortion.
  static Camera Create(CameraModelId model, double focal_px, int width,
                       int height, int id = 0);

  const CameraModelInfo& info() const { return GetCameraModelInfo(model); }
  double focal_px() const { return params.at(info().focal_params.at(0)); }
  // Principal point; (0, 0) for models without one (Snavely).
  Eigen::Vector2d principal_point_px() const;

  // Throws InvalidArgument when the parameter count does not match the model
  // or a value is not finite or the focal length is not positive.
  void Validate() const;

  // Projection of normalised coordinates (u, v) = (x/z, y/z) to pixels.
  Eigen::Vector2d ImageFromNormalized(const Eigen::Vector2d& uv) const;
  // Projection of a point in the camera frame to pixels. Points behind the
  // camera (z <= 0) still get a value; callers that care test z themselves.
  Eigen::Vector2d ImageFromCamera(const Eigen::Vector3d& point_in_cam) const {
    return ImageFromNormalized(point_in_cam.hnormalized());
  }
  // Inverse of ImageFromNormalized (Newton, see NormalizedFromImage()).
  std::optional<Eigen::Vector2d> NormalizedFromImage(
      const Eigen::Vector2d& xy, const UndistortOptions& options = {}) const;
  // Unit viewing ray in the camera frame through pixel xy.
  std::optional<Eigen::Vector3d> RayFromImage(
      const Eigen::Vector2d& xy, const UndistortOptions& options = {}) const;
};

// The size (width, height) of a width x height image at a working
// resolution whose longer side is at most max_dimension (0: full size);
// full px per working px is width / working width. The one definition for
// ingest (camera groups), features (the resampled image) and the stages
// that map working pixels back to full ones.
std::pair<int, int> WorkingImageSize(int width, int height, int max_dimension);

}  // namespace aerotri
