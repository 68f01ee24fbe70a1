// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Guided matching: the features of one image matched to known 3D points
// through a predicted pose, rather than to other images. Each point is
// projected with the prediction and matched only to keypoints near its
// predicted pixel (nearest descriptor, Lowe's ratio among those near), which
// lets weakly textured images -- bare fields, where unguided matching finds
// too few distinctive pairs -- be registered. GPS and attitude errors of the
// prediction mostly shift the whole image, so the shift is found first by a
// Hough vote over all points' candidate pairs.
//
// The incremental mapper uses it to rescue images left out, predicting each
// one's pose from its GPS position and its capture-order neighbour's
// attitude (incremental_mapper.h).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "camera_models/camera.h"
#include "libphoto/features/features.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct GuidedPoint {
  int id = -1;                 // the caller's index (e.g. into SparseModel::points)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  cv::Mat descriptor;          // 1 x 128, CV_32F (ImageFeatures::FloatDescriptors' row)
};

struct GuidedMatch {
  int feature = -1;  // keypoint of the image
  int point = -1;    // GuidedPoint::id
};

class GuidedMatcher {
 public:
  // features: the image's (working pixels); camera: its intrinsics;
  // search_radius_px: how far the prediction may be off, for the shift vote.
  GuidedMatcher(const ImageFeatures& features, const Camera& camera, double search_radius_px);

  // The shift (px) from predicted to observed pixels that most points'
  // candidates agree on; zero when nothing is in view.
  Eigen::Vector2d VoteShift(const Pose& predicted, const std::vector<GuidedPoint>& points) const;

  // One match per point in front of the camera whose best keypoint within
  // radius_px of its predicted pixel (plus shift) passes the ratio test;
  // each keypoint used once.
  std::vector<GuidedMatch> Match(const Pose& pose, const Eigen::Vector2d& shift, double radius_px,
                                 const std::vector<GuidedPoint>& points, double ratio = 0.85) const;

 private:
  // Keypoints within radius of xy, by descriptor distance (squared L2) to d.
  std::vector<std::pair<double, int>> Candidates(const Eigen::Vector2d& xy, double radius, const cv::Mat& d) const;
  bool Predict(const Pose& pose, const Eigen::Vector3d& x, Eigen::Vector2d* xy) const;

  static constexpr double kCell = 32.0;
  const ImageFeatures& features_;
  const Camera& camera_;
  double search_;
  cv::Mat descriptors_;
  int grid_w_ = 0;
  int grid_h_ = 0;
  std::vector<std::vector<int>> grid_;  // keypoints per kCell x kCell cell
};

}  // namespace aerotri
