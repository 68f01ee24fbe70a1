// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Renders photos of the synthetic terrain (TerrainHeight) for a Brown camera:
// for every pixel the distorted pixel is unprojected (Newton), its ray is
// intersected with the height field, and a procedural ground texture is
// sampled there (2x2 supersampling against aliasing). The texture has detail
// from 0.1 m to tens of metres (so that SIFT finds features at any GSD of a
// drone survey) and square black-and-white targets at the ground points.

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct GroundTarget {
  Eigen::Vector2d east_north;  // centre (ENU metres)
  double size_m = 1.0;         // side of the square (2x2 checker)
};

struct RenderOptions {
  double relief_m = 12.0;
  std::vector<GroundTarget> targets;
  int supersample = 2;       // per axis
  double noise_dn = 1.5;     // sensor noise (digital numbers)
  std::uint32_t seed = 1;
  int num_threads = 0;       // 0: all cores
};

// An 8-bit BGR image (OpenCV order) of width x height of the camera.
cv::Mat RenderImage(const Camera& camera, const Pose& pose, const RenderOptions& options);

// The ground's albedo at (east, north), RGB in [0, 1].
Eigen::Vector3d GroundAlbedo(double east_m, double north_m,
                             const std::vector<GroundTarget>& targets);

// Intersection of a ray (centre + t * direction, t > 0) with the terrain;
// std::nullopt when it misses (looking up, or no convergence).
std::optional<Eigen::Vector3d> IntersectTerrain(const Eigen::Vector3d& centre,
                                                const Eigen::Vector3d& direction, double relief_m);

}  // namespace aerotri
