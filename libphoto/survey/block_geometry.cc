// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/block_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace aerotri {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

BlockGeometry MeasureBlockGeometry(const SparseModel& model, const Eigen::Vector3d& down_in) {
  BlockGeometry g;
  const Eigen::Vector3d down = down_in.normalized();
  std::vector<std::vector<double>> depths(model.images.size());
  std::vector<std::vector<Eigen::Vector3d>> samples(model.images.size());  // u, v, 1/z
  for (const Observation& obs : model.observations) {
    const Image& image = model.images[obs.image];
    if (!image.registered || model.points[obs.point].role != PointRole::kTie) continue;
    const Eigen::Vector3d x = image.pose.CamFromWorld(model.points[obs.point].position);
    if (!(x.z() > 0.0)) continue;
    depths[obs.image].push_back(x.z());
    samples[obs.image].emplace_back(x.x() / x.z(), x.y() / x.z(), 1.0 / x.z());
  }
  std::vector<double> median_depths, relief, roughness, heights, tilts, gsd, sigma_v;
  for (size_t i = 0; i < model.images.size(); ++i) {
    const Image& image = model.images[i];
    if (!image.registered) continue;
    ++g.images;
    heights.push_back(-down.dot(image.pose.centre_in_world));
    const Eigen::Vector3d axis = image.pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
    tilts.push_back(std::acos(std::clamp(axis.dot(down), -1.0, 1.0)) * 180.0 / M_PI);
    if (image.gps_prior) sigma_v.push_back(image.gps_prior->sigma_v_m);
    if (depths[i].size() < 10) continue;
    const double m = Median(depths[i]);
    double mean = 0.0, var = 0.0;
    for (double d : depths[i]) mean += d;
    mean /= depths[i].size();
    for (double d : depths[i]) var += (d - mean) * (d - mean);
    median_depths.push_back(m);
    relief.push_back(std::sqrt(var / depths[i].size()) / m);
    // A plane n·X = d in the camera frame has 1/z = (n1 u + n2 v + n3) / d.
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& s : samples[i]) {
      const Eigen::Vector3d row(1.0, s.x(), s.y());
      ata += row * row.transpose();
      atb += row * s.z();
    }
    const Eigen::Vector3d plane = ata.ldlt().solve(atb);
    std::vector<double> residuals;
    for (const Eigen::Vector3d& s : samples[i]) {
      residuals.push_back(std::abs(s.z() - plane.dot(Eigen::Vector3d(1.0, s.x(), s.y()))));
    }
    // Robust (1.4826 MAD): a few mismatched points far off the ground are
    // not relief.
    roughness.push_back(1.4826 * Median(residuals) * m);  // δ(1/z) · z ≈ δz / z
    const auto& focal = model.cameras[image.camera].info().focal_params;
    if (!focal.empty()) gsd.push_back(m / model.cameras[image.camera].params[focal[0]]);
  }
  g.median_depth_m = Median(median_depths);
  g.relief_ratio = Median(relief);
  g.roughness_ratio = Median(roughness);
  g.tilt_p90_deg = Percentile(tilts, 0.9);
  g.gsd_m = Median(gsd);
  g.gps_sigma_v_m = Median(sigma_v);
  if (heights.size() >= 2 && g.median_depth_m > 0.0) {
    double mean = 0.0, var = 0.0;
    for (double h : heights) mean += h;
    mean /= heights.size();
    for (double h : heights) var += (h - mean) * (h - mean);
    g.height_variation_ratio = std::sqrt(var / heights.size()) / g.median_depth_m;
  }
  g.nadir_flat_single_altitude =
      g.roughness_ratio < kPlanarRoughnessRatio && g.height_variation_ratio < 0.05 && g.tilt_p90_deg < 15.0;
  return g;
}

double StudentTCriticalValue(int dof, double alpha) {
  // P(|T| > t) = 1 - 2 * integral of the density over [0, t] (Simpson), and
  // bisection on t; the density is smooth, so 4000 panels reach 1e-9.
  const double v = std::max(dof, 1);
  const double c = std::exp(std::lgamma(0.5 * (v + 1.0)) - std::lgamma(0.5 * v)) / std::sqrt(v * M_PI);
  auto tail = [&](double t) {
    const int m = 4000;
    const double h = t / m;
    double sum = 0.0;
    for (int i = 0; i <= m; ++i) {
      const double x = i * h;
      const double f = c * std::pow(1.0 + x * x / v, -0.5 * (v + 1.0));
      sum += f * (i == 0 || i == m ? 1.0 : (i % 2 ? 4.0 : 2.0));
    }
    return 1.0 - 2.0 * sum * h / 3.0;
  };
  double lo = 0.0, hi = 1.0;
  while (tail(hi) > alpha && hi < 1e6) hi *= 2.0;
  for (int i = 0; i < 100 && hi - lo > 1e-9 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (tail(mid) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

DomeTest FitDome(const std::vector<Eigen::Vector2d>& xy, const std::vector<double>& dz,
                 const Eigen::Vector2d& centre, double radius_m, const std::string& source) {
  DomeTest d;
  d.radius_m = radius_m;
  const size_t n = std::min(xy.size(), dz.size());
  if (n < 6 || !(radius_m > 0.0)) return d;
  // dz = a + b x/R + c y/R + amplitude r²/R²: the plane takes the datum's
  // shift and tilt (a GPS-only datum is tilted by decimetres), the last term
  // is the dome.
  Eigen::MatrixXd A(n, 4);
  Eigen::VectorXd z(n);
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d v = (xy[k] - centre) / radius_m;
    A.row(k) << 1.0, v.x(), v.y(), v.squaredNorm();
    z[k] = dz[k];
  }
  const Eigen::Matrix4d N = A.transpose() * A;
  Eigen::FullPivLU<Eigen::Matrix4d> lu(N);
  if (lu.rank() < 4) return d;
  const Eigen::Vector4d x = lu.solve(A.transpose() * z);
  const double rss = (A * x - z).squaredNorm();
  d.source = source;
  d.points = static_cast<int>(n);
  d.amplitude_m = x[3];
  d.amplitude_sigma_m = std::sqrt(rss / (n - 4) * lu.inverse()(3, 3));
  d.t = d.amplitude_sigma_m > 0.0 ? d.amplitude_m / d.amplitude_sigma_m : 0.0;
  d.t_critical = StudentTCriticalValue(static_cast<int>(n) - 4, kDomeAlpha);
  d.significant = std::abs(d.t) >= d.t_critical;
  return d;
}

}  // namespace aerotri
