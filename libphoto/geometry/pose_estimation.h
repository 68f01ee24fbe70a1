// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Minimal-solver pose estimators on calibrated (normalised) image
// coordinates, robust by RANSAC (OpenCV): the relative pose of two views
// (five-point essential matrix, cheirality) and the absolute pose of one
// view from 2D-3D correspondences (AP3P, then Levenberg-Marquardt on the
// inliers). OpenCV's RANSAC draws from a thread-local generator that other
// work advances by a schedule-dependent amount; each estimator reseeds it,
// so a result depends on its data alone.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct RelativePose {
  // View b's pose with view a at the origin (identity rotation, zero centre);
  // the baseline has unit length.
  Pose b;
  int inliers = 0;  // correspondences in front of both views within the threshold
};

// a[k] and b[k] are one point's normalised coordinates (x/z, y/z) in the two
// views; threshold in normalised units (pixels / focal length). Of a plane
// (a homography explains 90 % of the inliers or more) the two solutions
// that keep every point in front are told apart by the plane's facing: the
// one whose plane faces view a more squarely is returned.
std::optional<RelativePose> EstimateRelativePose(const std::vector<Eigen::Vector2d>& a,
                                                 const std::vector<Eigen::Vector2d>& b, double threshold);

// world[k] seen along rays[k] (normalised coordinates); threshold in
// normalised units. *inliers: the indices RANSAC kept (filled even when
// nullopt is returned, for the caller's report). nullopt when RANSAC fails.
std::optional<Pose> EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& world,
                                         const std::vector<Eigen::Vector2d>& rays, double threshold,
                                         std::vector<int>* inliers);

}  // namespace aerotri
