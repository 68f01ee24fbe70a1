// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Renders photos of the synthetic terrain (TerrainHeight) for a Brown camera:
// for every pixel the distorted pixel is unprojected (Newton), its ray is
// intersected with the height field, and a procedural ground texture is
// sampled there (2x2 supersampling against aliasing). The texture has detail
// from 0.1 m to tens of metres (so that SIFT finds features at any GSD of a
// drone survey) and square black-and-white targets at the ground points.

#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

// What covers the ground between the targets.
enum class GroundCover {
  kMixed,     // grass and soil with stones: texture at every scale, unique
  kCropRows,  // farmland: fields of crop rows 0.6-0.9 m apart, bare tilled
              // fields, tramlines; texture that repeats along and across
              // the rows (the hard case of matching)
};

// The targets surveyors lay out, as aerotri mark finds them
// (libphoto/targets/targets.h): a 2x2 checker in a white frame, a white
// cross on a black square, a bull's-eye (a white disc on a black square
// with a black dot at its centre).
enum class TargetPattern { kChecker, kCross, kBullseye };

struct GroundTarget {
  Eigen::Vector2d east_north;  // centre (ENU metres)
  double size_m = 1.0;         // side of the square
  TargetPattern pattern = TargetPattern::kChecker;
};

// A flat-roofed box building standing on the terrain: its roof lies
// height_m above the terrain at its centre; its walls go down into the ground.
struct BoxBuilding {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();     // ENU metres
  Eigen::Vector2d half_size = Eigen::Vector2d(4, 3);    // east, north half-widths (m)
  double height_m = 6.0;
  double RoofHeight(double relief_m) const;
  bool Contains(double east_m, double north_m) const {
    return std::abs(east_m - centre.x()) <= half_size.x() && std::abs(north_m - centre.y()) <= half_size.y();
  }
};

struct RenderOptions {
  double relief_m = 12.0;
  std::vector<GroundTarget> targets;
  std::vector<BoxBuilding> buildings;
  GroundCover cover = GroundCover::kMixed;
  int supersample = 2;       // per axis
  int target_supersample = 8;  // per axis, for pixels that see a target or its surroundings
  double noise_dn = 1.5;     // sensor noise (digital numbers)
  std::uint32_t seed = 1;
  int num_threads = 0;       // 0: all cores
  // A rolling shutter's motion (sparse_model.h): each row, and each of its
  // sub-samples, seen from where the camera was when it was read.
  std::optional<RollingShutterMotion> rolling_shutter;
};

// An 8-bit BGR image (OpenCV order) of width x height of the camera.
cv::Mat RenderImage(const Camera& camera, const Pose& pose, const RenderOptions& options);

// The ground's albedo at (east, north), RGB in [0, 1].
Eigen::Vector3d GroundAlbedo(double east_m, double north_m,
                             const std::vector<GroundTarget>& targets,
                             GroundCover cover = GroundCover::kMixed);

// The scene's top surface (roofs where there are buildings) and its colour
// seen from above: what a true orthoimage shows.
double SceneHeight(double east_m, double north_m, double relief_m, const std::vector<BoxBuilding>& buildings);
Eigen::Vector3d SceneAlbedoFromAbove(double east_m, double north_m, const std::vector<GroundTarget>& targets,
                                     const std::vector<BoxBuilding>& buildings,
                                     GroundCover cover = GroundCover::kMixed);

// Intersection of a ray (centre + t * direction, t > 0) with the terrain;
// std::nullopt when it misses (looking up, or no convergence).
std::optional<Eigen::Vector3d> IntersectTerrain(const Eigen::Vector3d& centre,
                                                const Eigen::Vector3d& direction, double relief_m);

}  // namespace aerotri
