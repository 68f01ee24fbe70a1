// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/model/sparse_model.h"

#include <cmath>

#include "libphoto/base/error.h"

namespace aerotri {

Eigen::Vector2d ProjectIntoImage(const Camera& camera, const Image& image, const Eigen::Vector3d& point_in_world,
                                 bool* in_front) {
  Eigen::Vector3d in_cam = image.pose.CamFromWorld(point_in_world);
  Eigen::Vector2d xy = camera.ImageFromCamera(in_cam);
  if (image.rolling_shutter && image.rolling_shutter->readout_time_s != 0.0) {
    for (int step = 0; step < 20; ++step) {
      in_cam = image.PoseAtRow(xy.y(), camera.height).CamFromWorld(point_in_world);
      const Eigen::Vector2d next = camera.ImageFromCamera(in_cam);
      const bool settled = (next - xy).norm() < 1e-9;
      xy = next;
      if (settled) break;
    }
  }
  if (in_front) *in_front = in_cam.z() > 0.0;
  return xy;
}

void SparseModel::Validate() const {
  for (const Camera& camera : cameras) camera.Validate();
  for (const Image& image : images) {
    if (image.camera < 0 || image.camera >= static_cast<int>(cameras.size())) {
      throw InvalidArgument("image '" + image.name + "' refers to camera index " +
                            std::to_string(image.camera) + ", but there are " +
                            std::to_string(cameras.size()) + " cameras");
    }
    if (!image.pose.centre_in_world.allFinite() ||
        !image.pose.cam_from_world.coeffs().allFinite()) {
      throw InvalidArgument("image '" + image.name + "' has a non-finite pose");
    }
  }
  for (const Point& point : points) {
    if (!point.position.allFinite()) {
      throw InvalidArgument("point " + std::to_string(point.id) +
                            " has a non-finite position");
    }
  }
  for (size_t i = 0; i < observations.size(); ++i) {
    const Observation& obs = observations[i];
    if (obs.image < 0 || obs.image >= static_cast<int>(images.size()) ||
        obs.point < 0 || obs.point >= static_cast<int>(points.size())) {
      throw InvalidArgument("observation " + std::to_string(i) +
                            " refers to image " + std::to_string(obs.image) +
                            " / point " + std::to_string(obs.point) +
                            ", outside the model");
    }
    if (!obs.xy.allFinite()) {
      throw InvalidArgument("observation " + std::to_string(i) +
                            " has non-finite pixel coordinates");
    }
    if (!(obs.sigma_px >= 0.0) || !std::isfinite(obs.sigma_px)) {
      throw InvalidArgument("observation " + std::to_string(i) + " has sigma " +
                            std::to_string(obs.sigma_px) + " px; expected >= 0 (0: by kind)");
    }
  }
}

std::vector<int> SparseModel::ObservationsPerPoint() const {
  std::vector<int> count(points.size(), 0);
  for (const Observation& obs : observations) ++count[obs.point];
  return count;
}

std::vector<int> SparseModel::ObservationsPerImage() const {
  std::vector<int> count(images.size(), 0);
  for (const Observation& obs : observations) ++count[obs.image];
  return count;
}

int SparseModel::NumRegisteredImages() const {
  int n = 0;
  for (const Image& image : images) n += image.registered ? 1 : 0;
  return n;
}

void SparseModel::KeepPoints(const std::vector<char>& keep) {
  std::vector<int> remap(points.size(), -1);
  std::vector<Point> kept;
  for (size_t p = 0; p < points.size(); ++p) {
    if (!keep[p]) continue;
    remap[p] = static_cast<int>(kept.size());
    kept.push_back(points[p]);
  }
  std::vector<Observation> obs;
  for (Observation o : observations) {
    if (remap[o.point] < 0) continue;
    o.point = remap[o.point];
    obs.push_back(o);
  }
  points.swap(kept);
  observations.swap(obs);
}

}  // namespace aerotri
