// SPDX-License-Identifier: BSD-3-Clause
#include "camera_models/camera.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "libphoto/base/error.h"

namespace aerotri {

const CameraModelInfo& GetCameraModelInfo(CameraModelId id) {
  static const CameraModelInfo kPinhole{
      CameraModelId::kPinhole, "PINHOLE", {"f", "cx", "cy"}, {0}, {1, 2}, {}};
  static const CameraModelInfo kBrown{
      CameraModelId::kBrown,
      "BROWN",
      {"f", "cx", "cy", "k1", "k2", "k3", "p1", "p2"},
      {0},
      {1, 2},
      {3, 4, 5, 6, 7}};
  static const CameraModelInfo kSnavely{
      CameraModelId::kSnavely, "SNAVELY", {"f", "k1", "k2"}, {0}, {}, {1, 2}};
  switch (id) {
    case CameraModelId::kPinhole:
      return kPinhole;
    case CameraModelId::kBrown:
      return kBrown;
    case CameraModelId::kSnavely:
      return kSnavely;
  }
  ThrowInternalError(__FILE__, __LINE__, "valid CameraModelId");
}

std::vector<CameraModelId> AllCameraModelIds() {
  return {CameraModelId::kPinhole, CameraModelId::kBrown,
          CameraModelId::kSnavely};
}

std::optional<CameraModelId> CameraModelIdFromName(const std::string& name) {
  std::string upper = name;
  std::transform(upper.begin(), upper.end(), upper.begin(),
                 [](unsigned char c) { return std::toupper(c); });
  for (CameraModelId id : AllCameraModelIds()) {
    if (GetCameraModelInfo(id).name == upper) return id;
  }
  return std::nullopt;
}

Camera Camera::Create(CameraModelId model, double focal_px, int width,
                      int height, int id) {
  Camera camera;
  camera.id = id;
  camera.model = model;
  camera.width = width;
  camera.height = height;
  const CameraModelInfo& info = GetCameraModelInfo(model);
  camera.params.assign(info.num_params(), 0.0);
  for (int i : info.focal_params) camera.params[i] = focal_px;
  if (info.principal_point_params.size() == 2) {
    camera.params[info.principal_point_params[0]] = 0.5 * (width - 1);
    camera.params[info.principal_point_params[1]] = 0.5 * (height - 1);
  }
  return camera;
}

Eigen::Vector2d Camera::principal_point_px() const {
  const auto& pp = info().principal_point_params;
  if (pp.size() != 2) return Eigen::Vector2d::Zero();
  return {params.at(pp[0]), params.at(pp[1])};
}

void Camera::Validate() const {
  const CameraModelInfo& model_info = info();
  if (static_cast<int>(params.size()) != model_info.num_params()) {
    throw InvalidArgument("camera " + std::to_string(id) + " (" +
                          model_info.name + "): expected " +
                          std::to_string(model_info.num_params()) +
                          " parameters, got " + std::to_string(params.size()));
  }
  for (size_t i = 0; i < params.size(); ++i) {
    if (!std::isfinite(params[i])) {
      throw InvalidArgument("camera " + std::to_string(id) + ": parameter " +
                            model_info.param_names[i] + " is not finite");
    }
  }
  if (!(focal_px() > 0.0)) {
    throw InvalidArgument("camera " + std::to_string(id) +
                          ": focal length must be positive (px), got " +
                          std::to_string(focal_px()));
  }
}

Eigen::Vector2d Camera::ImageFromNormalized(const Eigen::Vector2d& uv) const {
  Eigen::Vector2d xy;
  VisitCameraModel(model, [&](auto m) {
    using Model = decltype(m);
    AEROTRI_CHECK(static_cast<int>(params.size()) == Model::kNumParams);
    Model::ImageFromNormalized(params.data(), uv.x(), uv.y(), xy.data());
  });
  return xy;
}

std::optional<Eigen::Vector2d> Camera::NormalizedFromImage(
    const Eigen::Vector2d& xy, const UndistortOptions& options) const {
  const Eigen::Vector2d pp = principal_point_px();
  const double f = focal_px();
  return VisitCameraModel(
      model, [&](auto m) -> std::optional<Eigen::Vector2d> {
        using Model = decltype(m);
        AEROTRI_CHECK(static_cast<int>(params.size()) == Model::kNumParams);
        const auto uv = aerotri::NormalizedFromImage<Model>(
            params.data(), xy.x(), xy.y(), f, pp.x(), pp.y(), options);
        if (!uv) return std::nullopt;
        return Eigen::Vector2d(uv->first, uv->second);
      });
}

std::optional<Eigen::Vector3d> Camera::RayFromImage(
    const Eigen::Vector2d& xy, const UndistortOptions& options) const {
  const auto uv = NormalizedFromImage(xy, options);
  if (!uv) return std::nullopt;
  return uv->homogeneous().normalized();
}

std::pair<int, int> WorkingImageSize(int width, int height, int max_dimension) {
  const int longer = std::max(width, height);
  if (max_dimension <= 0 || longer <= max_dimension) return {width, height};
  const double s = static_cast<double>(longer) / max_dimension;
  return {static_cast<int>(std::lround(width / s)), static_cast<int>(std::lround(height / s))};
}

}  // namespace aerotri
