// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/geometry/pose_estimation.h"

#include <cstdint>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace aerotri {
namespace {

// The state OpenCV's RNG is reset to before each RANSAC.
constexpr std::uint64_t kRansacSeed = 0x2545F4914F6CDD1DULL;

Pose PoseOf(const cv::Mat& rotation, const cv::Mat& translation) {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rotation, r);
  cv::cv2eigen(translation, t);
  return Pose::FromRotationTranslation(Eigen::Quaterniond(r), t);
}

}  // namespace

std::optional<RelativePose> EstimateRelativePose(const std::vector<Eigen::Vector2d>& a,
                                                 const std::vector<Eigen::Vector2d>& b, double threshold) {
  if (a.size() < 5 || a.size() != b.size()) return std::nullopt;
  std::vector<cv::Point2d> pa, pb;
  for (size_t k = 0; k < a.size(); ++k) {
    pa.emplace_back(a[k].x(), a[k].y());
    pb.emplace_back(b[k].x(), b[k].y());
  }
  cv::Mat mask;
  cv::theRNG().state = kRansacSeed;
  const cv::Mat e = cv::findEssentialMat(pa, pb, 1.0, cv::Point2d(0, 0), cv::RANSAC, 0.9999, threshold, mask);
  if (e.rows != 3 || e.cols != 3) return std::nullopt;  // none, or several candidates stacked
  cv::Mat r, t;
  RelativePose out;
  out.inliers = cv::recoverPose(e, pa, pb, r, t, 1.0, cv::Point2d(0, 0), mask);
  out.b = PoseOf(r, t);
  return out;
}

std::optional<Pose> EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& world,
                                         const std::vector<Eigen::Vector2d>& rays, double threshold,
                                         std::vector<int>* inliers) {
  inliers->clear();
  if (world.size() < 4 || world.size() != rays.size()) return std::nullopt;
  std::vector<cv::Point3d> w;
  std::vector<cv::Point2d> r;
  for (size_t k = 0; k < world.size(); ++k) {
    w.emplace_back(world[k].x(), world[k].y(), world[k].z());
    r.emplace_back(rays[k].x(), rays[k].y());
  }
  cv::Mat rvec, tvec;
  cv::theRNG().state = kRansacSeed;
  if (!cv::solvePnPRansac(w, r, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false, 2000, threshold, 0.9999,
                          *inliers, cv::SOLVEPNP_AP3P)) {
    return std::nullopt;
  }
  if (inliers->size() >= 4) {
    std::vector<cv::Point3d> wi;
    std::vector<cv::Point2d> ri;
    for (int k : *inliers) {
      wi.push_back(w[k]);
      ri.push_back(r[k]);
    }
    cv::solvePnPRefineLM(wi, ri, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec);
  }
  cv::Mat rotation;
  cv::Rodrigues(rvec, rotation);
  return PoseOf(rotation, tvec);
}

}  // namespace aerotri
