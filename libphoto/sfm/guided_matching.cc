// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/sfm/guided_matching.h"

#include <algorithm>
#include <cmath>

namespace aerotri {

GuidedMatcher::GuidedMatcher(const ImageFeatures& features, const Camera& camera, double search_radius_px)
    : features_(features), camera_(camera), search_(search_radius_px), descriptors_(features.FloatDescriptors()) {
  grid_w_ = static_cast<int>(features.width / kCell) + 1;
  grid_h_ = static_cast<int>(features.height / kCell) + 1;
  grid_.resize(static_cast<size_t>(grid_w_) * grid_h_);
  for (size_t k = 0; k < features.keypoints.size(); ++k) {
    const int cx = std::clamp(static_cast<int>(features.keypoints[k].x / kCell), 0, grid_w_ - 1);
    const int cy = std::clamp(static_cast<int>(features.keypoints[k].y / kCell), 0, grid_h_ - 1);
    grid_[static_cast<size_t>(cy) * grid_w_ + cx].push_back(static_cast<int>(k));
  }
}

bool GuidedMatcher::Predict(const Pose& pose, const Eigen::Vector3d& x, Eigen::Vector2d* xy) const {
  const Eigen::Vector3d pc = pose.CamFromWorld(x);
  if (pc.z() <= 0) return false;
  *xy = camera_.ImageFromCamera(pc);
  return true;
}

std::vector<std::pair<double, int>> GuidedMatcher::Candidates(const Eigen::Vector2d& xy, double radius,
                                                              const cv::Mat& d) const {
  std::vector<std::pair<double, int>> out;
  const int x0 = static_cast<int>(std::floor((xy.x() - radius) / kCell));
  const int x1 = static_cast<int>(std::floor((xy.x() + radius) / kCell));
  const int y0 = static_cast<int>(std::floor((xy.y() - radius) / kCell));
  const int y1 = static_cast<int>(std::floor((xy.y() + radius) / kCell));
  for (int cy = std::max(0, y0); cy <= std::min(grid_h_ - 1, y1); ++cy) {
    for (int cx = std::max(0, x0); cx <= std::min(grid_w_ - 1, x1); ++cx) {
      for (int k : grid_[static_cast<size_t>(cy) * grid_w_ + cx]) {
        const double dx = features_.keypoints[k].x - xy.x(), dy = features_.keypoints[k].y - xy.y();
        if (dx * dx + dy * dy > radius * radius) continue;
        out.push_back({cv::norm(descriptors_.row(k), d, cv::NORM_L2SQR), k});
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

Eigen::Vector2d GuidedMatcher::VoteShift(const Pose& predicted, const std::vector<GuidedPoint>& points) const {
  constexpr double kBin = 8.0;
  const int nb = static_cast<int>(2 * search_ / kBin) + 1;
  std::vector<float> votes(static_cast<size_t>(nb) * nb, 0.0f);
  for (const GuidedPoint& p : points) {
    Eigen::Vector2d xy;
    if (!Predict(predicted, p.position, &xy)) continue;
    if (xy.x() < -search_ || xy.y() < -search_ || xy.x() > features_.width + search_ ||
        xy.y() > features_.height + search_) {
      continue;
    }
    const auto c = Candidates(xy, search_, p.descriptor);
    for (size_t r = 0; r < c.size() && r < 2; ++r) {
      const Keypoint& k = features_.keypoints[c[r].second];
      const int bx = static_cast<int>((k.x - xy.x() + search_) / kBin);
      const int by = static_cast<int>((k.y - xy.y() + search_) / kBin);
      if (bx >= 0 && by >= 0 && bx < nb && by < nb) votes[static_cast<size_t>(by) * nb + bx] += 1.0f;
    }
  }
  // The 3 x 3 bins with the most votes.
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
  float best = 0.0f;
  for (int by = 1; by + 1 < nb; ++by) {
    for (int bx = 1; bx + 1 < nb; ++bx) {
      float sum = 0.0f;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) sum += votes[static_cast<size_t>(by + dy) * nb + bx + dx];
      }
      if (sum > best) {
        best = sum;
        shift = Eigen::Vector2d((bx + 0.5) * kBin - search_, (by + 0.5) * kBin - search_);
      }
    }
  }
  return shift;
}

std::vector<GuidedMatch> GuidedMatcher::Match(const Pose& pose, const Eigen::Vector2d& shift, double radius_px,
                                              const std::vector<GuidedPoint>& points, double ratio) const {
  std::vector<GuidedMatch> out;
  std::vector<char> used(features_.keypoints.size(), 0);
  for (const GuidedPoint& p : points) {
    Eigen::Vector2d xy;
    if (!Predict(pose, p.position, &xy)) continue;
    xy += shift;
    const auto c = Candidates(xy, radius_px, p.descriptor);
    if (c.empty()) continue;
    const double second = c.size() > 1 ? c[1].first : 1e9;
    const int k = c[0].second;
    if (used[k] || !(c[0].first < ratio * ratio * second)) continue;
    used[k] = 1;
    out.push_back({k, p.id});
  }
  return out;
}

}  // namespace aerotri
