// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/targets/targets.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "libphoto/targets/cross_target.h"

namespace aerotri {
namespace {

float Bilinear(const cv::Mat& f, double x, double y) {
  x = std::clamp(x, 0.0, f.cols - 1.001);
  y = std::clamp(y, 0.0, f.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double ax = x - x0, ay = y - y0;
  const float* r0 = f.ptr<float>(y0);
  const float* r1 = f.ptr<float>(y0 + 1);
  return static_cast<float>((1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
                            ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]));
}

// ---- checker ----------------------------------------------------------------

struct Ring {
  bool checker = false;
  double contrast = 0.0;
  double asymmetry = 1.0;  // mean |I(a) - I(a + 180 deg)| over the contrast
};

// The circle of radius r about c: a checker's crosses the mean of its
// extremes four times, and opposite sectors match.
Ring RingAbout(const cv::Mat& f, const Eigen::Vector2d& c, double r) {
  constexpr int kSamples = 64;
  double v[kSamples];
  for (int k = 0; k < kSamples; ++k) {
    const double a = 2.0 * M_PI * k / kSamples;
    v[k] = Bilinear(f, c.x() + r * std::cos(a), c.y() + r * std::sin(a));
  }
  const auto [lo, hi] = std::minmax_element(v, v + kSamples);
  Ring ring;
  ring.contrast = *hi - *lo;
  if (ring.contrast <= 0.0) return ring;
  const double mid = 0.5 * (*hi + *lo);
  int crossings = 0;
  double asym = 0.0;
  int extreme = 0;
  for (int k = 0; k < kSamples; ++k) {
    crossings += (v[k] > mid) != (v[(k + 1) % kSamples] > mid);
    asym += std::abs(v[k] - v[(k + kSamples / 2) % kSamples]);
    extreme += std::abs(v[k] - mid) > 0.25 * ring.contrast;
  }
  ring.asymmetry = asym / kSamples / ring.contrast;
  // Near the centre the blur takes a larger share of the circle.
  const double min_extreme = r >= 5.0 ? 0.6 : 0.35;
  ring.checker = crossings == 4 && ring.asymmetry < 0.2 && extreme >= min_extreme * kSamples;
  return ring;
}

// The checker's centre as the crossing of its two edge lines: on circles
// about c (radii from 0.3 to 0.9 of the checker's), the four places where
// the brightness crosses the ring's mid-level, interpolated along the
// circle, each assigned to its ray; opposite rays make one straight line
// (under perspective too), fitted by total least squares. JPEG's blocks
// and noise move a gradient-weighted centre by tenths of a pixel; hundreds
// of edge points average them out.
std::optional<Eigen::Vector2d> CentreFromEdges(const cv::Mat& f, const Eigen::Vector2d& c, double size) {
  std::vector<Eigen::Vector2d> rays[4];
  double ray_angle[4] = {0, 0, 0, 0};
  bool have_rays = false;
  for (double r = std::max(2.5, 0.3 * size); r <= 0.9 * size; r += 0.5) {
    const int n = std::max(64, static_cast<int>(4.0 * M_PI * r));
    std::vector<double> v(n);
    for (int k = 0; k < n; ++k) {
      const double a = 2.0 * M_PI * k / n;
      v[k] = Bilinear(f, c.x() + r * std::cos(a), c.y() + r * std::sin(a));
    }
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    const double mid = 0.5 * (*lo + *hi);
    std::vector<double> angles;
    for (int k = 0; k < n; ++k) {
      const double a = v[k] - mid, b = v[(k + 1) % n] - mid;
      if ((a > 0) != (b > 0)) angles.push_back(2.0 * M_PI * (k + a / (a - b)) / n);
    }
    if (angles.size() != 4) continue;
    if (!have_rays) {
      std::copy(angles.begin(), angles.end(), ray_angle);
      have_rays = true;
    }
    for (double a : angles) {
      int best = 0;
      double best_d = 1e9;
      for (int q = 0; q < 4; ++q) {
        const double d = std::abs(std::remainder(a - ray_angle[q], 2.0 * M_PI));
        if (d < best_d) best_d = d, best = q;
      }
      if (best_d > 0.5) continue;
      rays[best].push_back(c + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
  }
  if (!have_rays) return std::nullopt;
  Eigen::Vector3d lines[2];
  for (int l = 0; l < 2; ++l) {
    std::vector<Eigen::Vector2d> pts = rays[l];
    pts.insert(pts.end(), rays[l + 2].begin(), rays[l + 2].end());
    if (rays[l].size() < 3 || rays[l + 2].size() < 3) return std::nullopt;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    const Eigen::Vector2d normal = eig.eigenvectors().col(0);
    lines[l] = Eigen::Vector3d(normal.x(), normal.y(), -normal.dot(mean));
  }
  const Eigen::Vector3d x = lines[0].cross(lines[1]);
  if (std::abs(x.z()) < 1e-9) return std::nullopt;
  return Eigen::Vector2d(x.x() / x.z(), x.y() / x.z());
}

}  // namespace

std::vector<TargetDetection> DetectCheckerTargets(const cv::Mat& gray8, const TargetDetectionOptions& options) {
  cv::Mat f, smooth;
  gray8.convertTo(f, CV_32F);
  cv::GaussianBlur(f, smooth, cv::Size(0, 0), 1.5);
  cv::Mat dxx, dyy, dxy;
  cv::Sobel(smooth, dxx, CV_32F, 2, 0, 3);
  cv::Sobel(smooth, dyy, CV_32F, 0, 2, 3);
  cv::Sobel(smooth, dxy, CV_32F, 1, 1, 3);
  const cv::Mat det = dxx.mul(dyy) - dxy.mul(dxy);
  cv::Mat local_min;
  cv::erode(det, local_min, cv::Mat(), cv::Point(-1, -1), 3);
  // A saddle of contrast c smoothed by 1.5 px: |det|^1/2 is about c / 4 in
  // these units; a tenth of the least contrast lets every target through.
  const float limit = -static_cast<float>(std::pow(0.1 * options.min_contrast_dn, 2));
  std::vector<std::pair<float, cv::Point>> candidates;
  const int border = 3;
  for (int y = border; y < det.rows - border; ++y) {
    const float* d = det.ptr<float>(y);
    const float* m = local_min.ptr<float>(y);
    for (int x = border; x < det.cols - border; ++x) {
      if (d[x] < limit && d[x] <= m[x]) candidates.push_back({d[x], cv::Point(x, y)});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (candidates.size() > 5000) candidates.resize(5000);
  cv::Mat light;  // for the rings: little blur, the pattern's own edges
  cv::GaussianBlur(f, light, cv::Size(0, 0), 0.7);
  std::vector<TargetDetection> found;
  const auto refine = [&](const Eigen::Vector2d& from, int half) {
    // cv::cornerSubPix needs the image 2 half + 5 wide and high: a crop cut
    // narrow by a photo's edge takes a smaller window, or none (NaN: the
    // callers keep their centre, or drop the candidate).
    half = std::min({half, (light.cols - 5) / 2, (light.rows - 5) / 2});
    if (half < 2) return Eigen::Vector2d(std::nan(""), std::nan(""));
    std::vector<cv::Point2f> corner = {cv::Point2f(static_cast<float>(from.x()), static_cast<float>(from.y()))};
    cv::cornerSubPix(light, corner, cv::Size(half, half), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
    return Eigen::Vector2d(corner[0].x, corner[0].y);
  };
  for (const auto& [strength, at] : candidates) {
    // The rings about the pixel nearest a saddle would be lopsided by up
    // to half a pixel: first a centre from the nearest few pixels.
    Eigen::Vector2d c(at.x, at.y);
    if (at.x >= 4 && at.y >= 4 && at.x < f.cols - 4 && at.y < f.rows - 4) {
      const Eigen::Vector2d near = refine(c, 3);
      if ((near - c).norm() < 1.5) c = near;
    }
    double size = 0.0, contrast = 1e9, asymmetry = 0.0;
    int passed = 0;
    for (double r = 2.5; r <= options.max_radius_px; r *= 1.35) {
      if (c.x() - r < 0 || c.y() - r < 0 || c.x() + r > f.cols - 1 || c.y() + r > f.rows - 1) break;
      const Ring ring = RingAbout(light, c, r);
      if (!ring.checker || ring.contrast < options.min_contrast_dn) break;
      size = r;
      contrast = std::min(contrast, ring.contrast);
      asymmetry = std::max(asymmetry, ring.asymmetry);
      ++passed;
    }
    if (passed < 2 || size < options.min_radius_px) continue;
    bool near = false;
    for (const TargetDetection& d : found) near = near || (d.centre_px - c).norm() < 0.5 * std::max(d.size_px, 4.0);
    if (near) continue;
    // Förstner's centre over the checker's own squares (not its frame).
    // The rings pass through a white frame as well as the squares, so the
    // size can be the frame's: a window that reaches past the squares'
    // outer corners can carry the iteration to one of them (20 px off, seen
    // on level, unturned checkers), so the window shrinks until it stays.
    Eigen::Vector2d centre = c;
    bool stayed = false;
    for (int half = static_cast<int>(std::clamp(0.6 * size, 2.0, 25.0)); half >= 2 && !stayed; half = half * 2 / 3) {
      centre = refine(c, half);
      stayed = (centre - c).norm() <= 2.0;
    }
    if (!stayed) continue;
    if (const auto edges = CentreFromEdges(light, centre, size); edges && (*edges - centre).norm() < 1.0) {
      centre = *edges;
    }
    TargetDetection d;
    d.kind = TargetKind::kChecker;
    d.centre_px = centre;
    d.size_px = size;
    d.confidence = std::min(1.0, contrast / (2.0 * options.min_contrast_dn)) * (1.0 - asymmetry / 0.2 * 0.5) *
                   std::min(1.0, passed / 3.0);
    if (d.confidence >= options.min_confidence) found.push_back(d);
  }
  return found;
}

// ---- circle -----------------------------------------------------------------

namespace {

struct Outline {
  cv::RotatedRect ellipse;
  double rms_px = 0.0;
  double contrast = 0.0;
  double consistency = 0.0;  // 1 - spread of the two shades along the outline over the contrast
  int points = 0;
};

// Distance of p from the ellipse, approximately (along the normal of the
// unit-circle map).
double EllipseDistance(const cv::RotatedRect& e, const Eigen::Vector2d& p, Eigen::Vector2d* normal) {
  const double a = 0.5 * e.size.width, b = 0.5 * e.size.height;
  const double t = e.angle * M_PI / 180.0, c = std::cos(t), s = std::sin(t);
  const Eigen::Vector2d d = p - Eigen::Vector2d(e.center.x, e.center.y);
  const double u = c * d.x() + s * d.y(), v = -s * d.x() + c * d.y();
  const double rho = std::hypot(u / a, v / b);
  Eigen::Vector2d g_local(u / (a * a), v / (b * b));
  g_local.normalize();
  *normal = Eigen::Vector2d(c * g_local.x() - s * g_local.y(), s * g_local.x() + c * g_local.y());
  // First order: (rho - 1) over |grad rho|.
  const double grad = std::hypot(u / (a * a), v / (b * b)) / std::max(rho, 1e-9);
  return (rho - 1.0) / std::max(grad, 1e-9);
}

// The outline's points where the brightness crosses the mean of inside and
// outside, along the first ellipse's normals; the ellipse refitted to them.
std::optional<Outline> RefineOutline(const cv::Mat& f, const std::vector<cv::Point>& contour) {
  cv::RotatedRect e = cv::fitEllipse(contour);
  const double minor = 0.5 * std::min(e.size.width, e.size.height);
  if (!(minor > 1.5)) return std::nullopt;
  const double reach = std::clamp(0.35 * minor, 1.5, 4.0);
  Outline out;
  for (int round = 0; round < 2; ++round) {
    std::vector<cv::Point2f> points;
    std::vector<double> inside, outside;
    const int n = std::clamp(static_cast<int>(contour.size()), 24, 720);
    const double a = 0.5 * e.size.width, b = 0.5 * e.size.height;
    const double t = e.angle * M_PI / 180.0, c = std::cos(t), s = std::sin(t);
    for (int k = 0; k < n; ++k) {
      const double phi = 2.0 * M_PI * k / n;
      const Eigen::Vector2d p(e.center.x + a * std::cos(phi) * c - b * std::sin(phi) * s,
                              e.center.y + a * std::cos(phi) * s + b * std::sin(phi) * c);
      Eigen::Vector2d normal;
      EllipseDistance(e, p, &normal);
      const double in = Bilinear(f, p.x() - reach * normal.x(), p.y() - reach * normal.y());
      const double outv = Bilinear(f, p.x() + reach * normal.x(), p.y() + reach * normal.y());
      const double mid = 0.5 * (in + outv);
      // Walk the profile in quarter pixels for the crossing.
      double prev = in, found = std::nan("");
      for (double q = -reach + 0.25; q <= reach + 1e-9; q += 0.25) {
        const double val = Bilinear(f, p.x() + q * normal.x(), p.y() + q * normal.y());
        if ((prev - mid) * (val - mid) <= 0.0 && prev != val) {
          found = q - 0.25 * (val - mid) / (val - prev);
          break;
        }
        prev = val;
      }
      if (!std::isfinite(found)) continue;
      points.emplace_back(static_cast<float>(p.x() + found * normal.x()), static_cast<float>(p.y() + found * normal.y()));
      inside.push_back(in);
      outside.push_back(outv);
    }
    if (points.size() < 0.7 * n || points.size() < 12) return std::nullopt;
    e = cv::fitEllipse(points);
    const auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    const double in_level = median(inside), out_level = median(outside);
    out.contrast = std::abs(in_level - out_level);
    double spread = 0.0, sq = 0.0;
    for (size_t k = 0; k < points.size(); ++k) {
      spread += std::abs(inside[k] - in_level) + std::abs(outside[k] - out_level);
      Eigen::Vector2d normal;
      const double d = EllipseDistance(e, Eigen::Vector2d(points[k].x, points[k].y), &normal);
      sq += d * d;
    }
    out.consistency = 1.0 - spread / (2.0 * points.size()) / std::max(out.contrast, 1e-9);
    out.rms_px = std::sqrt(sq / points.size());
    out.points = static_cast<int>(points.size());
  }
  out.ellipse = e;
  return out;
}

}  // namespace

std::vector<TargetDetection> DetectCircleTargets(const cv::Mat& gray8, const TargetDetectionOptions& options) {
  cv::Mat f;
  gray8.convertTo(f, CV_32F);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 0.7);
  std::vector<TargetDetection> outlines;
  // Several levels, both shades: a disc is a region at some level whatever
  // the ground about it; its outline is then measured at its own mean shade.
  for (const double level : {64.0, 96.0, 128.0, 160.0, 192.0}) {
    for (const bool bright : {true, false}) {
      cv::Mat binary = bright ? gray8 > level : gray8 < level;
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(binary, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
      for (const auto& contour : contours) {
        if (contour.size() < 12) continue;
        const double area = std::abs(cv::contourArea(contour));
        const double r_min = options.min_radius_px, r_max = options.max_radius_px;
        if (area < M_PI * r_min * r_min || area > M_PI * r_max * r_max) continue;
        const cv::RotatedRect rough = cv::fitEllipse(contour);
        const double ellipse_area = M_PI * 0.25 * rough.size.width * rough.size.height;
        if (!(std::abs(area / ellipse_area - 1.0) < 0.08)) continue;
        const double ratio = std::min(rough.size.width, rough.size.height) / std::max(rough.size.width, rough.size.height);
        if (ratio < 0.4) continue;
        const auto outline = RefineOutline(f, contour);
        if (!outline || outline->contrast < options.min_contrast_dn) continue;
        const double radius = 0.25 * (outline->ellipse.size.width + outline->ellipse.size.height);
        if (outline->rms_px > std::max(0.15, 0.02 * radius) || outline->consistency < 0.7) continue;
        TargetDetection d;
        d.kind = TargetKind::kCircle;
        d.centre_px = Eigen::Vector2d(outline->ellipse.center.x, outline->ellipse.center.y);
        d.size_px = radius;
        d.confidence = std::min(1.0, outline->contrast / (2.0 * options.min_contrast_dn)) * outline->consistency *
                       std::clamp(1.0 - outline->rms_px / std::max(0.3, 0.04 * radius), 0.0, 1.0);
        outlines.push_back(d);
      }
    }
  }
  // One outline is found at several levels, and a bull's-eye has several
  // outlines: those about one centre are one target, its centre their mean
  // (distinct outlines weighed alike).
  std::sort(outlines.begin(), outlines.end(),
            [](const TargetDetection& a, const TargetDetection& b) { return a.size_px > b.size_px; });
  std::vector<TargetDetection> found;
  std::vector<std::vector<TargetDetection>> members;
  for (const TargetDetection& o : outlines) {
    size_t k = 0;
    for (; k < found.size(); ++k) {
      if ((found[k].centre_px - o.centre_px).norm() < std::max(1.0, 0.15 * o.size_px)) break;
    }
    if (k == found.size()) {
      found.push_back(o);
      members.push_back({o});
    } else {
      members[k].push_back(o);
    }
  }
  std::vector<TargetDetection> out;
  for (size_t k = 0; k < found.size(); ++k) {
    // Distinct rings: radii more than 1 px apart; the same ring seen at
    // several levels counts once (its best fit).
    std::vector<TargetDetection> rings;
    for (const TargetDetection& m : members[k]) {
      bool same = false;
      for (TargetDetection& r : rings) {
        if (std::abs(r.size_px - m.size_px) < std::max(1.0, 0.05 * m.size_px)) {
          same = true;
          if (m.confidence > r.confidence) r = m;
        }
      }
      if (!same) rings.push_back(m);
    }
    // Weighed by radius: an outline's points, and so its centre's weight,
    // grow with it. A lone disc is a weaker sign than a bull's-eye (a round
    // stone is one too).
    TargetDetection d = rings.front();
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    double best = 0.0, weight = 0.0;
    for (const TargetDetection& r : rings) {
      sum += r.size_px * r.centre_px;
      weight += r.size_px;
      best = std::max(best, r.confidence);
    }
    d.centre_px = sum / weight;
    d.confidence = best * (rings.size() > 1 ? 1.0 : 0.7);
    if (d.confidence >= options.min_confidence) out.push_back(d);
  }
  return out;
}

const char* TargetKindName(TargetKind kind) {
  switch (kind) {
    case TargetKind::kChecker:
      return "checker";
    case TargetKind::kCross:
      return "cross";
    case TargetKind::kCircle:
      return "circle";
  }
  return "checker";
}

std::optional<TargetKind> TargetKindFromName(const std::string& name) {
  for (TargetKind k : {TargetKind::kChecker, TargetKind::kCross, TargetKind::kCircle}) {
    if (name == TargetKindName(k)) return k;
  }
  return std::nullopt;
}

std::vector<TargetDetection> DetectTargets(const cv::Mat& image, const TargetDetectionOptions& options) {
  const cv::Mat gray8 = Gray8Of(image);
  std::vector<TargetDetection> all;
  for (const TargetKind kind : options.kinds) {
    std::vector<TargetDetection> found;
    if (kind == TargetKind::kChecker) found = DetectCheckerTargets(gray8, options);
    if (kind == TargetKind::kCircle) found = DetectCircleTargets(gray8, options);
    if (kind == TargetKind::kCross) {
      CrossTargetOptions cross;
      cross.min_bar_width_px = std::max(2.0, 0.4 * options.min_radius_px);
      cross.max_bar_width_px = std::max(cross.min_bar_width_px + 1.0, 0.5 * options.max_radius_px);
      cross.min_confidence = options.min_confidence;
      for (const CrossTarget& t : DetectCrossTargets(gray8, cross)) {
        found.push_back({TargetKind::kCross, t.centre_px, t.confidence, 3.0 * t.bar_width_px});
      }
    }
    all.insert(all.end(), found.begin(), found.end());
  }
  std::sort(all.begin(), all.end(),
            [](const TargetDetection& a, const TargetDetection& b) { return a.confidence > b.confidence; });
  std::vector<TargetDetection> out;
  for (const TargetDetection& d : all) {
    bool taken = false;
    for (const TargetDetection& o : out) taken = taken || (o.centre_px - d.centre_px).norm() < 2.0;
    if (!taken) out.push_back(d);
  }
  return out;
}

}  // namespace aerotri
