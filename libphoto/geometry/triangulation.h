// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Multi-view triangulation of one point from calibrated views: the point that
// minimises the sum of squared perpendicular distances to the viewing rays
// (closed form), refined by minimising reprojection error with the cameras
// held fixed (Gauss–Newton on the 3 coordinates). Used for check points
// (never adjusted) and for initial positions of control points.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct View {
  const Camera* camera = nullptr;
  Pose pose;
  Eigen::Vector2d xy;  // px, aerotri convention
};

struct Triangulation {
  Eigen::Vector3d position;
  double reprojection_rms_px = 0.0;  // sqrt(mean ‖e‖²) over the views
  double max_angle_deg = 0.0;        // widest angle between two rays
  int num_views = 0;
};

struct TriangulationOptions {
  double min_angle_deg = 1.0;  // below this the depth is too uncertain
  int max_iterations = 20;
};

// std::nullopt when fewer than 2 views, the rays are too parallel, a pixel
// cannot be unprojected, or the point ends up behind a camera.
std::optional<Triangulation> TriangulatePoint(const std::vector<View>& views,
                                              const TriangulationOptions& options = {});

}  // namespace aerotri
