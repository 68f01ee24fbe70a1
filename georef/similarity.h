// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Similarity (7-parameter Helmert) transforms y = s R x + t, and their robust
// estimation from point correspondences: RANSAC over minimal 3-point samples,
// each solved in closed form (Umeyama 1991, via Eigen::umeyama), then a
// least-squares refit on the inliers.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

namespace aerotri {

struct Similarity {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d Apply(const Eigen::Vector3d& x) const {
    return scale * (rotation * x) + translation;
  }
  Similarity Inverse() const;
};

struct SimilarityFit {
  Similarity transform;
  std::vector<char> inliers;  // per correspondence
  int num_inliers = 0;
  double rms_m = 0.0;  // over inliers, in the target frame
};

// Least squares over all correspondences (needs 3 non-collinear points).
std::optional<Similarity> FitSimilarity(const std::vector<Eigen::Vector3d>& from,
                                        const std::vector<Eigen::Vector3d>& to);

// Robust fit: a correspondence is an inlier when its residual in the target
// frame is below inlier_threshold_m. std::nullopt when fewer than 3 points or
// all are collinear.
std::optional<SimilarityFit> FitSimilarityRobust(const std::vector<Eigen::Vector3d>& from,
                                                 const std::vector<Eigen::Vector3d>& to,
                                                 double inlier_threshold_m,
                                                 std::uint32_t seed = 1,
                                                 int max_iterations = 500);

}  // namespace aerotri
