// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/geometry/pose_estimation.h"

#include <cstdint>
#include <Eigen/Eigenvalues>
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

  // Photos of a plane: the five-point solution is two-fold (the plane's
  // twisted pair, both with every point in front), and RANSAC keeps either.
  // When a homography explains nearly every inlier, its decomposition's
  // solutions with the points in front are the candidates, and the one
  // whose plane faces the first view most squarely is kept: photos look at
  // the ground, not along it.
  cv::Mat hmask;
  cv::theRNG().state = kRansacSeed;
  const cv::Mat h = cv::findHomography(pa, pb, cv::RANSAC, threshold, hmask, 2000, 0.9999);
  if (h.empty()) return out;
  const int h_inliers = cv::countNonZero(hmask);
  if (h_inliers < 0.9 * out.inliers) return out;
  std::vector<cv::Mat> rotations, translations, normals;
  cv::decomposeHomographyMat(h, cv::Mat::eye(3, 3, CV_64F), rotations, translations, normals);
  std::vector<cv::Point2f> ia, ib;
  for (size_t k = 0; k < pa.size(); ++k) {
    if (!hmask.at<std::uint8_t>(static_cast<int>(k))) continue;
    ia.emplace_back(static_cast<float>(pa[k].x), static_cast<float>(pa[k].y));
    ib.emplace_back(static_cast<float>(pb[k].x), static_cast<float>(pb[k].y));
  }
  std::vector<int> valid;
  cv::filterHomographyDecompByVisibleRefpoints(rotations, normals, ia, ib, valid);
  int best = -1;
  double best_facing = -1.0;
  for (int s : valid) {
    const double n_norm = cv::norm(normals[s]), t_norm = cv::norm(translations[s]);
    if (!(n_norm > 0.0) || !(t_norm > 1e-9)) continue;  // no baseline: a rotation about the centre
    const double facing = std::abs(normals[s].at<double>(2)) / n_norm;
    if (facing > best_facing) best_facing = facing, best = s;
  }
  if (best < 0) return out;
  const Pose candidate = PoseOf(rotations[best], translations[best] / cv::norm(translations[best]));
  // The five-point answer is the same solution: kept, with its own inliers.
  if (candidate.cam_from_world.angularDistance(out.b.cam_from_world) < 1e-2) return out;
  // The plane's normal in the five-point solution, from its triangulated
  // inliers, against the homography's choice: the one facing the first
  // view more squarely wins.
  const Eigen::Matrix3d rb = out.b.cam_from_world.toRotationMatrix();
  const Eigen::Vector3d tb = out.b.cam_from_world * (-out.b.centre_in_world);
  std::vector<Eigen::Vector3d> points;
  for (size_t k = 0; k < pa.size(); ++k) {
    if (!mask.at<std::uint8_t>(static_cast<int>(k))) continue;
    // Depth along a's ray from b's: x_b ~ R z x_a + t, least squares in z.
    const Eigen::Vector3d xa(pa[k].x, pa[k].y, 1.0), xb(pb[k].x, pb[k].y, 1.0);
    const Eigen::Vector3d u = (rb * xa).cross(xb), v = tb.cross(xb);
    if (!(u.squaredNorm() > 0.0)) continue;
    const double z = -u.dot(v) / u.squaredNorm();
    if (z > 0.0) points.push_back(z * xa);
  }
  if (points.size() >= 3) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points) centroid += p;
    centroid /= static_cast<double>(points.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const auto& p : points) scatter += (p - centroid) * (p - centroid).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
    const double facing = std::abs(eigen.eigenvectors().col(0).z());
    if (facing >= best_facing) return out;
  }
  out.b = candidate;
  out.inliers = h_inliers;
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
