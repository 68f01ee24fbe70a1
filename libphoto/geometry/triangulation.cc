// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/geometry/triangulation.h"

#include <Eigen/Dense>
#include <cmath>

namespace aerotri {
namespace {

// Reprojection residuals (2 per view) and their Jacobian w.r.t. the point,
// by central differences (3 unknowns: cheap and model-agnostic).
void Residuals(const std::vector<View>& views, const Eigen::Vector3d& x, Eigen::VectorXd* r) {
  r->resize(2 * views.size());
  for (size_t i = 0; i < views.size(); ++i) {
    r->segment<2>(2 * i) =
        views[i].camera->ImageFromCamera(views[i].pose.CamFromWorld(x)) - views[i].xy;
  }
}

}  // namespace

std::optional<Triangulation> TriangulatePoint(const std::vector<View>& views,
                                              const TriangulationOptions& options) {
  if (views.size() < 2) return std::nullopt;
  std::vector<Eigen::Vector3d> dirs;
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const View& v : views) {
    const auto ray = v.camera->RayFromImage(v.xy);
    if (!ray) return std::nullopt;
    const Eigen::Vector3d d = (v.pose.cam_from_world.conjugate() * *ray).normalized();
    dirs.push_back(d);
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - d * d.transpose();
    a += p;
    b += p * v.pose.centre_in_world;
  }
  double min_cos = 1.0;
  for (size_t i = 0; i < dirs.size(); ++i) {
    for (size_t j = i + 1; j < dirs.size(); ++j) min_cos = std::min(min_cos, dirs[i].dot(dirs[j]));
  }
  const double angle = std::acos(std::clamp(min_cos, -1.0, 1.0)) * 180.0 / M_PI;
  if (angle < options.min_angle_deg) return std::nullopt;
  Eigen::Vector3d x = a.ldlt().solve(b);
  if (!x.allFinite()) return std::nullopt;

  // Gauss–Newton on reprojection error.
  Eigen::VectorXd r;
  Residuals(views, x, &r);
  for (int it = 0; it < options.max_iterations; ++it) {
    Eigen::MatrixXd j(r.size(), 3);
    for (int k = 0; k < 3; ++k) {
      const double h = 1e-6 * std::max(1.0, x.norm());
      Eigen::Vector3d xp = x, xm = x;
      xp[k] += h;
      xm[k] -= h;
      Eigen::VectorXd rp, rm;
      Residuals(views, xp, &rp);
      Residuals(views, xm, &rm);
      j.col(k) = (rp - rm) / (2 * h);
    }
    const Eigen::Vector3d step = (j.transpose() * j).ldlt().solve(-j.transpose() * r);
    if (!step.allFinite()) break;
    Eigen::VectorXd r_new;
    Residuals(views, x + step, &r_new);
    if (r_new.squaredNorm() > r.squaredNorm()) break;
    x += step;
    r = r_new;
    if (step.norm() < 1e-9 * std::max(1.0, x.norm())) break;
  }
  for (const View& v : views) {
    if (v.pose.CamFromWorld(x).z() <= 0.0) return std::nullopt;
  }
  Triangulation t;
  t.position = x;
  t.num_views = static_cast<int>(views.size());
  t.max_angle_deg = angle;
  t.reprojection_rms_px = std::sqrt(r.squaredNorm() / views.size());
  return t;
}

}  // namespace aerotri
