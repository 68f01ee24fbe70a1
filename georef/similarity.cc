// SPDX-License-Identifier: BSD-3-Clause
#include "georef/similarity.h"

#include <Eigen/SVD>
#include <algorithm>
#include <random>

namespace aerotri {
namespace {

bool Collinear(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 3) return true;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov);
  const Eigen::Vector3d sv = svd.singularValues();
  return !(sv(0) > 0.0) || sv(1) < 1e-10 * sv(0);
}

}  // namespace

Similarity Similarity::Inverse() const {
  Similarity inv;
  inv.scale = 1.0 / scale;
  inv.rotation = rotation.conjugate();
  inv.translation = -(inv.scale * (inv.rotation * translation));
  return inv;
}

std::optional<Similarity> FitSimilarity(const std::vector<Eigen::Vector3d>& from,
                                        const std::vector<Eigen::Vector3d>& to) {
  if (from.size() != to.size() || from.size() < 3 || Collinear(from) || Collinear(to)) {
    return std::nullopt;
  }
  Eigen::Matrix3Xd a(3, from.size()), b(3, to.size());
  for (size_t i = 0; i < from.size(); ++i) {
    a.col(i) = from[i];
    b.col(i) = to[i];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(a, b, true);
  Similarity s;
  const Eigen::Matrix3d sr = t.topLeftCorner<3, 3>();
  s.scale = std::cbrt(sr.determinant());
  if (!(s.scale > 0.0) || !std::isfinite(s.scale)) return std::nullopt;
  s.rotation = Eigen::Quaterniond(sr / s.scale).normalized();
  s.translation = t.topRightCorner<3, 1>();
  return s;
}

std::optional<SimilarityFit> FitSimilarityRobust(const std::vector<Eigen::Vector3d>& from,
                                                 const std::vector<Eigen::Vector3d>& to,
                                                 double inlier_threshold_m, std::uint32_t seed,
                                                 int max_iterations) {
  const size_t n = from.size();
  if (n != to.size() || n < 3) return std::nullopt;
  auto score = [&](const Similarity& s, std::vector<char>* inliers) {
    int count = 0;
    inliers->assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
      if ((s.Apply(from[i]) - to[i]).norm() < inlier_threshold_m) {
        (*inliers)[i] = 1;
        ++count;
      }
    }
    return count;
  };

  std::optional<Similarity> best;
  std::vector<char> best_inliers;
  int best_count = -1;
  if (auto all = FitSimilarity(from, to)) {
    best = all;
    best_count = score(*all, &best_inliers);
  }
  std::mt19937 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<char> inliers;
  for (int it = 0; it < max_iterations && n > 3 && best_count < static_cast<int>(n); ++it) {
    size_t i = pick(rng), j = pick(rng), k = pick(rng);
    if (i == j || j == k || i == k) continue;
    const auto s = FitSimilarity({from[i], from[j], from[k]}, {to[i], to[j], to[k]});
    if (!s) continue;
    const int count = score(*s, &inliers);
    if (count > best_count) {
      best_count = count;
      best = s;
      best_inliers = inliers;
    }
  }
  if (!best || best_count < 3) return std::nullopt;

  // Refit on the inliers until the set stops changing.
  for (int round = 0; round < 5; ++round) {
    std::vector<Eigen::Vector3d> a, b;
    for (size_t i = 0; i < n; ++i) {
      if (best_inliers[i]) {
        a.push_back(from[i]);
        b.push_back(to[i]);
      }
    }
    const auto refined = FitSimilarity(a, b);
    if (!refined) break;
    std::vector<char> next;
    const int count = score(*refined, &next);
    best = refined;
    if (next == best_inliers || count < 3) break;
    best_inliers = next;
  }

  SimilarityFit fit;
  fit.transform = *best;
  fit.num_inliers = score(*best, &fit.inliers);
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (fit.inliers[i]) sum += (best->Apply(from[i]) - to[i]).squaredNorm();
  }
  fit.rms_m = fit.num_inliers > 0 ? std::sqrt(sum / fit.num_inliers) : 0.0;
  return fit;
}

}  // namespace aerotri
