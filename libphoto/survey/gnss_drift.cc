// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/gnss_drift.h"

#include <Eigen/Geometry>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

namespace aerotri {
namespace {

constexpr double kDeg = M_PI / 180.0;

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDeg;
}

// The mean of unit directions and their spread (median angle from it, in
// degrees); false when they cancel out.
bool MeanDirection(const std::vector<Eigen::Vector3d>& directions, Eigen::Vector3d* mean, double* spread_deg) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& d : directions) sum += d;
  if (sum.norm() < 1e-9) return false;
  *mean = sum.normalized();
  std::vector<double> angles;
  for (const auto& d : directions) angles.push_back(AngleDeg(d, *mean));
  *spread_deg = Median(angles);
  return true;
}

}  // namespace

FlightTimes SplitFlights(const std::vector<double>& times_s) {
  FlightTimes out;
  out.flight.assign(times_s.size(), -1);
  out.dt_s.assign(times_s.size(), 0.0);
  std::vector<size_t> order;
  for (size_t k = 0; k < times_s.size(); ++k) {
    if (std::isfinite(times_s[k])) order.push_back(k);
  }
  if (order.empty()) return out;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return times_s[a] < times_s[b]; });
  std::vector<double> gaps;
  for (size_t k = 1; k < order.size(); ++k) gaps.push_back(times_s[order[k]] - times_s[order[k - 1]]);
  const double gap_limit = std::max(120.0, gaps.empty() ? 0.0 : 20.0 * Median(gaps));
  int flight = 0;
  std::vector<std::vector<size_t>> members(1);
  for (size_t k = 0; k < order.size(); ++k) {
    if (k > 0 && times_s[order[k]] - times_s[order[k - 1]] > gap_limit) {
      ++flight;
      members.emplace_back();
    }
    out.flight[order[k]] = flight;
    members[flight].push_back(order[k]);
  }
  for (const auto& m : members) {
    double mean = 0.0;
    for (size_t k : m) mean += times_s[k];
    mean /= static_cast<double>(m.size());
    for (size_t k : m) out.dt_s[k] = times_s[k] - mean;
    out.duration_s.push_back(times_s[m.back()] - times_s[m.front()]);
    out.images.push_back(static_cast<int>(m.size()));
  }
  return out;
}

Eigen::Vector3d OpticalAxisInWorld(const Pose& pose) {
  return pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
}

ViewingGeometry MeasureViewingGeometry(const SparseModel& model) {
  ViewingGeometry g;
  std::vector<Eigen::Vector3d> axes, centres;
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    axes.push_back(OpticalAxisInWorld(image.pose));
    centres.push_back(image.pose.centre_in_world);
  }
  g.images = static_cast<int>(axes.size());
  if (g.images < 3) {
    g.reason = "fewer than 3 registered images";
    return g;
  }
  if (!MeanDirection(axes, &g.mean_axis, &g.spread_deg)) {
    g.reason = "the optical axes point every way";
    return g;
  }

  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& c : centres) centroid += c;
  centroid /= static_cast<double>(centres.size());
  Eigen::MatrixXd a(centres.size(), 3);
  for (size_t k = 0; k < centres.size(); ++k) a.row(k) = (centres[k] - centroid).transpose();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinV);
  const Eigen::Vector3d s = svd.singularValues();
  // Two dimensions: the second extent at least a fifth of the first, the
  // third (height scatter about the plane) under a third of the second.
  g.plane_measured = s(0) > 0.0 && s(1) > 0.2 * s(0) && s(2) < s(1) / 3.0;
  if (g.plane_measured) {
    const Eigen::Vector3d normal = svd.matrixV().col(2);
    g.axis_to_flight_plane_normal_deg = std::min(AngleDeg(g.mean_axis, normal), AngleDeg(g.mean_axis, -normal));
  }
  char text[200];
  if (g.spread_deg > 15.0) {
    std::snprintf(text, sizeof text, "the optical axes spread %.0f deg (median) about their mean: not a nadir block",
                  g.spread_deg);
  } else if (!g.plane_measured) {
    // One line of cameras: a nadir strip and a walk past a facade look the
    // same without gravity; the block's vertical is not in its geometry.
    std::snprintf(text, sizeof text,
                  "the camera centres lie along one line: a nadir strip cannot be told from a side-looking "
                  "walk, no vertical is assumed");
  } else if (g.axis_to_flight_plane_normal_deg > 15.0) {
    std::snprintf(text, sizeof text,
                  "the mean optical axis is %.0f deg from the flight plane's normal: oblique or terrain-following",
                  g.axis_to_flight_plane_normal_deg);
  } else {
    g.nadir = true;
    std::snprintf(text, sizeof text,
                  "optical axes within %.1f deg (median) of their mean, %.1f deg from the flight plane's normal",
                  g.spread_deg, g.axis_to_flight_plane_normal_deg);
  }
  g.reason = text;
  return g;
}

TiltStats MeasureTilt(const SparseModel& model) {
  TiltStats t;
  std::vector<double> tilts;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    const Eigen::Vector3d axis = OpticalAxisInWorld(image.pose);
    tilts.push_back(AngleDeg(axis, down));
    sum += axis;
  }
  t.images = static_cast<int>(tilts.size());
  if (tilts.empty()) return t;
  t.median_deg = Median(tilts);
  t.max_deg = *std::max_element(tilts.begin(), tilts.end());
  t.mean_axis_tilt_deg = sum.norm() > 0.0 ? AngleDeg(sum.normalized(), down) : 180.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Point& p : model.points) {
    if (p.role != PointRole::kTie) continue;
    centroid += p.position;
    ++t.ground_points;
  }
  if (t.ground_points < 3) {
    t.ground_points = 0;
    return t;
  }
  centroid /= t.ground_points;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Point& p : model.points) {
    if (p.role == PointRole::kTie) scatter += (p.position - centroid) * (p.position - centroid).transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  const Eigen::Vector3d normal = eigen.eigenvectors().col(0);  // smallest spread
  t.ground_slope_deg = std::acos(std::min(1.0, std::abs(normal.z()))) * 180.0 / M_PI;
  return t;
}

GimbalVertical MeasureGimbalVertical(const SparseModel& model, const std::map<std::string, GimbalAttitude>& gimbal) {
  GimbalVertical v;
  std::vector<Eigen::Vector3d> downs;
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    const auto it = gimbal.find(image.name);
    if (it == gimbal.end()) continue;
    downs.push_back(image.pose.cam_from_world.conjugate() * DownInCamera(it->second));
  }
  v.images = static_cast<int>(downs.size());
  char text[200];
  if (v.images < 6) {
    std::snprintf(text, sizeof text, "%d registered photos with gimbal angles (6 needed)", v.images);
    v.reason = text;
    return v;
  }
  if (!MeanDirection(downs, &v.down_in_model, &v.spread_deg)) {
    v.reason = "the gimbals' verticals point every way";
    return v;
  }
  v.usable = v.spread_deg <= 10.0;
  std::snprintf(text, sizeof text, "the verticals of %d photos' gimbal pitches agree within %.1f deg (median)%s",
                v.images, v.spread_deg, v.usable ? "" : ": too far apart to say where down is (10 deg allowed)");
  v.reason = text;
  return v;
}

GimbalAgreement CompareWithGimbal(const SparseModel& model, const std::map<std::string, GimbalAttitude>& gimbal) {
  GimbalAgreement g;
  std::vector<double> pitch, yaw_signed;
  Eigen::Vector3d down_sum = Eigen::Vector3d::Zero();
  const auto wrap = [](double deg) { return std::remainder(deg, 360.0); };
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    const auto it = gimbal.find(image.name);
    if (it == gimbal.end()) continue;
    const GimbalAttitude adjusted = AttitudeOf(image.pose);
    down_sum += image.pose.cam_from_world.conjugate() * DownInCamera(it->second);
    const double dp = std::abs(adjusted.pitch_deg - it->second.pitch_deg);
    pitch.push_back(dp);
    if (dp > g.pitch_max_deg) {
      g.pitch_max_deg = dp;
      g.pitch_worst_image = image.name;
    }
    if (it->second.pitch_deg < -45.0) yaw_signed.push_back(wrap(adjusted.yaw_deg - it->second.yaw_deg));
  }
  g.images = static_cast<int>(pitch.size());
  if (pitch.empty()) return g;
  g.pitch_median_deg = Median(pitch);
  if (down_sum.norm() > 0.0) g.block_tilt_deg = AngleDeg(down_sum.normalized(), Eigen::Vector3d(0.0, 0.0, -1.0));
  g.yaw_images = static_cast<int>(yaw_signed.size());
  if (!yaw_signed.empty()) {
    // The circular mean: differences near ±180° must not average to 0.
    double s = 0.0, c = 0.0;
    for (double d : yaw_signed) {
      s += std::sin(d * M_PI / 180.0);
      c += std::cos(d * M_PI / 180.0);
    }
    g.yaw_bias_deg = std::atan2(s, c) * 180.0 / M_PI;
    std::vector<double> yaw;
    for (double d : yaw_signed) yaw.push_back(std::abs(wrap(d - g.yaw_bias_deg)));
    g.yaw_median_deg = Median(yaw);
    g.yaw_max_deg = *std::max_element(yaw.begin(), yaw.end());
  }
  return g;
}

std::optional<SimilarityFit> FitLevelledSimilarity(const std::vector<Eigen::Vector3d>& from,
                                                   const std::vector<Eigen::Vector3d>& to,
                                                   const Eigen::Vector3d& down_in_model, double threshold_m) {
  const size_t n = from.size();
  if (n < 2 || to.size() != n || !(down_in_model.norm() > 0.0)) return std::nullopt;
  const Eigen::Quaterniond level =
      Eigen::Quaterniond::FromTwoVectors(down_in_model.normalized(), Eigen::Vector3d(0.0, 0.0, -1.0));
  std::vector<Eigen::Vector3d> x(n);
  for (size_t k = 0; k < n; ++k) x[k] = level * from[k];

  // y = s Rz(θ) x + t in the plane, as complex numbers: y = a x + t, a = s e^{iθ}.
  struct Fit2 {
    double ar = 1.0, ai = 0.0, tx = 0.0, ty = 0.0;
    Eigen::Vector2d Apply(const Eigen::Vector3d& p) const {
      return {ar * p.x() - ai * p.y() + tx, ai * p.x() + ar * p.y() + ty};
    }
  };
  auto least_squares = [&](const std::vector<size_t>& idx) -> std::optional<Fit2> {
    if (idx.size() < 2) return std::nullopt;
    Eigen::Vector2d mx = Eigen::Vector2d::Zero(), my = Eigen::Vector2d::Zero();
    for (size_t k : idx) mx += x[k].head<2>(), my += to[k].head<2>();
    mx /= static_cast<double>(idx.size());
    my /= static_cast<double>(idx.size());
    double sxx = 0.0, re = 0.0, im = 0.0;
    for (size_t k : idx) {
      const Eigen::Vector2d p = x[k].head<2>() - mx, q = to[k].head<2>() - my;
      sxx += p.squaredNorm();
      re += p.x() * q.x() + p.y() * q.y();
      im += p.x() * q.y() - p.y() * q.x();
    }
    if (!(sxx > 1e-12)) return std::nullopt;
    Fit2 f;
    f.ar = re / sxx;
    f.ai = im / sxx;
    f.tx = my.x() - (f.ar * mx.x() - f.ai * mx.y());
    f.ty = my.y() - (f.ai * mx.x() + f.ar * mx.y());
    return f;
  };
  auto inliers_of = [&](const Fit2& f) {
    std::vector<size_t> in;
    for (size_t k = 0; k < n; ++k) {
      if ((f.Apply(x[k]) - to[k].head<2>()).norm() <= threshold_m) in.push_back(k);
    }
    return in;
  };
  // RANSAC over pairs, then least squares on the best consensus (twice).
  std::mt19937 rng(1);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<size_t> best;
  const int trials = n <= 40 ? static_cast<int>(n * (n - 1) / 2) : 300;
  for (int trial = 0; trial < trials; ++trial) {
    size_t a, b;
    if (n <= 40) {
      a = static_cast<size_t>(trial) % n;  // enumerate when small: deterministic
      b = (a + 1 + static_cast<size_t>(trial) / n) % n;
    } else {
      a = pick(rng);
      b = pick(rng);
    }
    if (a == b) continue;
    const auto f = least_squares({a, b});
    if (!f) continue;
    std::vector<size_t> in = inliers_of(*f);
    if (in.size() > best.size()) best.swap(in);
  }
  if (best.size() < 2) return std::nullopt;
  std::optional<Fit2> f;
  for (int round = 0; round < 3; ++round) {
    f = least_squares(best);
    if (!f) return std::nullopt;
    std::vector<size_t> in = inliers_of(*f);
    if (in.size() < 2 || in == best) break;
    best.swap(in);
  }
  const double scale = std::hypot(f->ar, f->ai);
  const double heading = std::atan2(f->ai, f->ar);
  std::vector<double> dz;
  for (size_t k : best) dz.push_back(to[k].z() - scale * x[k].z());

  SimilarityFit out;
  out.transform.scale = scale;
  out.transform.rotation = (Eigen::Quaterniond(Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ())) * level).normalized();
  out.transform.translation = Eigen::Vector3d(f->tx, f->ty, Median(dz));
  out.inliers.assign(n, 0);
  double sum2 = 0.0;
  for (size_t k : best) {
    out.inliers[k] = 1;
    sum2 += (out.transform.Apply(from[k]) - to[k]).squaredNorm();
  }
  out.num_inliers = static_cast<int>(best.size());
  out.rms_m = std::sqrt(sum2 / static_cast<double>(best.size()));
  return out;
}

DriftTrend FitDriftTrend(const std::vector<Eigen::Vector3d>& residuals, const FlightTimes& flights,
                         double sigma_h_m, double sigma_v_m) {
  DriftTrend out;
  const Eigen::Vector3d prior_sigma(sigma_h_m, sigma_h_m, sigma_v_m);
  for (int f = 0; f < flights.NumFlights(); ++f) {
    DriftTrend::Flight flight;
    flight.images = flights.images[f];
    flight.duration_s = flights.duration_s[f];
    std::vector<size_t> members;
    for (size_t k = 0; k < residuals.size() && k < flights.flight.size(); ++k) {
      if (flights.flight[k] == f) members.push_back(k);
    }
    if (members.size() < 6 || !(flight.duration_s > 0.0)) {
      out.flights.push_back(flight);
      continue;
    }
    for (int axis = 0; axis < 3; ++axis) {
      // r = a + b dt by least squares over `use`.
      auto line = [&](const std::vector<size_t>& use, double* a, double* b) {
        double st = 0, sr = 0, stt = 0, str = 0;
        for (size_t k : use) {
          const double t = flights.dt_s[k], r = residuals[k][axis];
          st += t, sr += r, stt += t * t, str += t * r;
        }
        const double m = static_cast<double>(use.size());
        const double den = m * stt - st * st;
        *b = den > 0.0 ? (m * str - st * sr) / den : 0.0;
        *a = (sr - *b * st) / m;
      };
      double a = 0.0, b = 0.0;
      line(members, &a, &b);
      // Trim what lies beyond 4 robust deviations of the first line (a
      // blundered fix must not make or hide a trend), then refit.
      std::vector<double> abs_dev;
      for (size_t k : members) abs_dev.push_back(std::abs(residuals[k][axis] - a - b * flights.dt_s[k]));
      const double robust = 1.4826 * Median(abs_dev);
      std::vector<size_t> kept;
      for (size_t k : members) {
        if (std::abs(residuals[k][axis] - a - b * flights.dt_s[k]) <= std::max(4.0 * robust, 1e-9)) kept.push_back(k);
      }
      if (kept.size() >= 6) line(kept, &a, &b);
      const std::vector<size_t>& use = kept.size() >= 6 ? kept : members;
      double ss = 0.0, stt = 0.0, mean_t = 0.0;
      for (size_t k : use) mean_t += flights.dt_s[k];
      mean_t /= static_cast<double>(use.size());
      for (size_t k : use) {
        const double e = residuals[k][axis] - a - b * flights.dt_s[k];
        ss += e * e;
        stt += (flights.dt_s[k] - mean_t) * (flights.dt_s[k] - mean_t);
      }
      const double scatter = std::sqrt(ss / std::max<double>(1.0, static_cast<double>(use.size()) - 2.0));
      flight.rate_m_per_s[axis] = b;
      flight.scatter_m[axis] = scatter;
      flight.rate_sigma[axis] = stt > 0.0 ? scatter / std::sqrt(stt) : std::numeric_limits<double>::infinity();
      const bool significant = std::abs(b) > 5.0 * flight.rate_sigma[axis] &&
                               std::abs(b) * flight.duration_s > 3.0 * prior_sigma[axis];
      out.significant_axes[axis] = out.significant_axes[axis] || significant;
    }
    out.flights.push_back(flight);
  }
  return out;
}

}  // namespace aerotri
