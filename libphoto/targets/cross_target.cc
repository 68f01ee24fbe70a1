// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/targets/cross_target.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace aerotri {
namespace {

// The bars are fitted within this many bar widths of the crossing: a
// target's cloth lies on uneven ground and its bars bend, and the mark is
// where they cross.
constexpr double kNearCrossing = 3.0;

struct Line {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d dir = Eigen::Vector2d::UnitX();  // unit
  Eigen::Vector2d Normal() const { return {-dir.y(), dir.x()}; }
  double Distance(const Eigen::Vector2d& p) const { return std::abs(Normal().dot(p - point)); }
};

// The q-quantile of an 8-bit image's values.
double Percentile(const cv::Mat& gray8, double q) {
  int histogram[256] = {0};
  for (int y = 0; y < gray8.rows; ++y) {
    const uchar* row = gray8.ptr<uchar>(y);
    for (int x = 0; x < gray8.cols; ++x) ++histogram[row[x]];
  }
  const double target = q * gray8.total();
  double sum = 0.0;
  for (int v = 0; v < 256; ++v) {
    sum += histogram[v];
    if (sum >= target) return v;
  }
  return 255.0;
}

// The line through the most points within half_width of it, by RANSAC
// (deterministic), its direction at least min_angle_deg from `away` when
// given; *inliers counts them.
std::optional<Line> RansacLine(const std::vector<Eigen::Vector2d>& points, double half_width, double min_span,
                               const Eigen::Vector2d* away, double min_angle_deg, int* inliers) {
  if (points.size() < 2) return std::nullopt;
  std::mt19937 rng(7);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  const double max_cos = std::cos(min_angle_deg * M_PI / 180.0);
  std::optional<Line> best;
  *inliers = 0;
  for (int iteration = 0; iteration < 400; ++iteration) {
    const Eigen::Vector2d& a = points[pick(rng)];
    const Eigen::Vector2d& b = points[pick(rng)];
    if ((b - a).norm() < min_span) continue;
    Line line{a, (b - a).normalized()};
    if (away && std::abs(line.dir.dot(*away)) > max_cos) continue;
    int count = 0;
    for (const Eigen::Vector2d& p : points) count += line.Distance(p) < half_width;
    if (count > *inliers) {
      *inliers = count;
      best = line;
    }
  }
  return best;
}

Eigen::Vector2d Intersect(const Line& a, const Line& b) {
  // a.point + s a.dir = b.point + t b.dir
  Eigen::Matrix2d m;
  m << a.dir, -b.dir;
  const Eigen::Vector2d st = m.colPivHouseholderQr().solve(b.point - a.point);
  return a.point + st.x() * a.dir;
}

// A bar's centre line fitted to the image itself: pixels within 0.9 bar
// widths of the line, outside the crossing and short of the bar's ends,
// each weighed by where its value lies between the square's black and the
// bar's white (0 at or below the black, 1 at or above the white): the
// weights' centroid across the bar is the midpoint of its two edges, to a
// fraction of a pixel, whatever the light does inside the bar.
Line FitBar(const cv::Mat& gray, double black, double white, const Line& line, const Eigen::Vector2d& centre,
            double width, double extent, double near) {
  const Eigen::Vector2d n = line.Normal();
  const double offset = n.dot(line.point - centre);  // the line's across-coordinate at the centre
  const double reach = extent + width;
  const int x0 = std::max(0, static_cast<int>(std::floor(centre.x() - reach)));
  const int x1 = std::min(gray.cols - 1, static_cast<int>(std::ceil(centre.x() + reach)));
  const int y0 = std::max(0, static_cast<int>(std::floor(centre.y() - reach)));
  const int y1 = std::min(gray.rows - 1, static_cast<int>(std::ceil(centre.y() + reach)));
  // Slices across the bar, one pixel apart along it: each its weighted
  // centre across and its total weight (the bar's width where clean).
  const int slices = static_cast<int>(std::ceil(reach));
  std::vector<double> sum_w(2 * slices + 1, 0.0), sum_wc(2 * slices + 1, 0.0);
  for (int y = y0; y <= y1; ++y) {
    const float* row = gray.ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d d = Eigen::Vector2d(x, y) - centre;
      const double across = n.dot(d);
      const double along = line.dir.dot(d);
      if (std::abs(across - offset) > 0.9 * width || std::abs(along) < 0.9 * width ||
          std::abs(along) > std::min(0.85 * extent, near * width)) {
        continue;
      }
      const double w = std::clamp((static_cast<double>(row[x]) - black) / (white - black), 0.0, 1.0);
      const int k = static_cast<int>(std::lround(along)) + slices;
      sum_w[k] += w;
      sum_wc[k] += w * across;
    }
  }
  std::vector<double> t, c, weight;
  for (int k = 0; k < 2 * slices + 1; ++k) {
    if (sum_w[k] <= 0.0) continue;
    t.push_back(k - slices);
    c.push_back(sum_wc[k] / sum_w[k]);
    weight.push_back(sum_w[k]);
  }
  if (t.size() < 6) return line;
  // Slices whose weight is off the bar's own width hold something else (the
  // tick, the other bar's edge, the square's edge): left out.
  std::vector<double> sorted = weight;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median_weight = sorted[sorted.size() / 2];
  std::vector<char> use(t.size());
  for (size_t k = 0; k < t.size(); ++k) use[k] = std::abs(weight[k] - median_weight) < 0.2 * median_weight;
  double a = offset, b = 0.0;
  for (int round = 0; round < 3; ++round) {
    // c = a + b t by least squares over the slices in use.
    double s1 = 0, st = 0, stt = 0, sc = 0, stc = 0;
    for (size_t k = 0; k < t.size(); ++k) {
      if (!use[k]) continue;
      s1 += 1;
      st += t[k];
      stt += t[k] * t[k];
      sc += c[k];
      stc += t[k] * c[k];
    }
    const double det = s1 * stt - st * st;
    if (s1 < 6 || !(std::abs(det) > 0.0)) return line;
    a = (stt * sc - st * stc) / det;
    b = (s1 * stc - st * sc) / det;
    std::vector<double> r;
    for (size_t k = 0; k < t.size(); ++k) {
      if (use[k]) r.push_back(std::abs(c[k] - a - b * t[k]));
    }
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    const double limit = std::max(0.3, 3.0 * 1.4826 * r[r.size() / 2]);
    for (size_t k = 0; k < t.size(); ++k) {
      if (use[k]) use[k] = std::abs(c[k] - a - b * t[k]) < limit;
    }
  }
  return Line{centre + a * n, (line.dir + b * n).normalized()};
}

// One bright region enclosed by dark, as a cross target (or nothing).
std::optional<CrossTarget> CrossOf(const cv::Mat& gray, const cv::Mat& dark, const cv::Mat& labels, int label,
                                   const cv::Rect& box, double dark_level, const CrossTargetOptions& options) {
  const int pad = static_cast<int>(std::ceil(options.max_bar_width_px));
  const cv::Rect roi = (box + cv::Size(2 * pad, 2 * pad) - cv::Point(pad, pad)) & cv::Rect(0, 0, gray.cols, gray.rows);
  const cv::Mat mask = labels(roi) == label;
  cv::Mat distance;
  cv::distanceTransform(mask, distance, cv::DIST_L2, 5);
  std::vector<Eigen::Vector2d> points;
  std::vector<float> depths;
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      if (!mask.at<uchar>(y, x)) continue;
      points.emplace_back(x + roi.x, y + roi.y);
      depths.push_back(distance.at<float>(y, x));
    }
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() * 95 / 100, depths.end());
  const double width = 2.0 * depths[depths.size() * 95 / 100];
  if (width < options.min_bar_width_px || width > options.max_bar_width_px) return std::nullopt;
  // The ring about the region, past the blur of its edge: dark on a
  // target, whatever the ground is.
  const int r_in = std::max(2, static_cast<int>(std::lround(0.4 * width)));
  const int r_out = std::max(r_in + 2, static_cast<int>(std::lround(1.0 * width)));
  cv::Mat inner, outer;
  cv::dilate(mask, inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r_in + 1, 2 * r_in + 1)));
  cv::dilate(mask, outer, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r_out + 1, 2 * r_out + 1)));
  const cv::Mat ring = outer & ~inner;
  const double ring_pixels = cv::countNonZero(ring);
  const double darkness = ring_pixels > 0 ? cv::countNonZero(ring & dark(roi)) / ring_pixels : 0.0;
  if (darkness < 0.5) return std::nullopt;
  int in1 = 0, in2 = 0;
  const auto bar1 = RansacLine(points, 0.5 * width, 3.0 * width, nullptr, 0.0, &in1);
  if (!bar1) return std::nullopt;
  std::vector<Eigen::Vector2d> rest;
  for (const Eigen::Vector2d& p : points) {
    if (bar1->Distance(p) > 0.75 * width) rest.push_back(p);
  }
  const auto bar2 = RansacLine(rest, 0.5 * width, 2.0 * width, &bar1->dir, 45.0, &in2);
  // The second bar reaches at least two bar widths past the first (both arms
  // together). The distance transform counts to the first pixel outside, so
  // a bar is about one pixel narrower than `width` says: at 5 px bars the
  // difference is the one between finding a cross and missing it.
  const double bar_width = std::max(1.0, width - 1.0);
  if (!bar2 || in2 < 2.0 * bar_width * bar_width) return std::nullopt;
  Line lines[2] = {*bar1, *bar2};
  Eigen::Vector2d centre = Intersect(lines[0], lines[1]);
  // Each bar's extent from the crossing: its inliers' farthest reach.
  double extent[2] = {0.0, 0.0};
  for (int b = 0; b < 2; ++b) {
    for (const Eigen::Vector2d& p : points) {
      if (lines[b].Distance(p) < 0.5 * width) extent[b] = std::max(extent[b], std::abs(lines[b].dir.dot(p - centre)));
    }
  }
  // The black of the square (the ring's median) and the white of the cross
  // (its 30th percentile: the light varies along and across the bars).
  std::vector<float> ring_values, cross_values;
  for (int y = 0; y < ring.rows; ++y) {
    for (int x = 0; x < ring.cols; ++x) {
      if (ring.at<uchar>(y, x) && dark(roi).at<uchar>(y, x)) ring_values.push_back(gray(roi).at<float>(y, x));
      if (mask.at<uchar>(y, x)) cross_values.push_back(gray(roi).at<float>(y, x));
    }
  }
  std::nth_element(ring_values.begin(), ring_values.begin() + ring_values.size() / 2, ring_values.end());
  std::nth_element(cross_values.begin(), cross_values.begin() + cross_values.size() * 3 / 10, cross_values.end());
  const double black = ring_values.empty() ? dark_level : ring_values[ring_values.size() / 2];
  const double white = cross_values[cross_values.size() * 3 / 10];
  if (!(white > black + 1.0)) return std::nullopt;
  for (int round = 0; round < 3; ++round) {
    for (int b = 0; b < 2; ++b) lines[b] = FitBar(gray, black, white, lines[b], centre, width, extent[b], kNearCrossing);
    centre = Intersect(lines[0], lines[1]);
  }
  CrossTarget t;
  t.centre_px = centre;
  t.bar_width_px = width;
  t.bar_direction[0] = lines[0].dir;
  t.bar_direction[1] = lines[1].dir;
  const double sine = std::abs(lines[0].dir.x() * lines[1].dir.y() - lines[0].dir.y() * lines[1].dir.x());
  t.angle_deg = std::asin(std::min(1.0, sine)) * 180.0 / M_PI;
  const double explained = std::min(1.0, static_cast<double>(in1 + in2) / points.size());
  t.confidence = std::min(1.0, darkness / 0.8) * explained * sine;
  if (!box.contains(cv::Point(static_cast<int>(centre.x()), static_cast<int>(centre.y())))) return std::nullopt;
  return t;
}

}  // namespace

cv::Mat Gray8Of(const cv::Mat& image) {
  cv::Mat gray8;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray8, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray8, cv::COLOR_BGRA2GRAY);
  } else {
    gray8 = image;
  }
  return gray8;
}

std::vector<CrossTarget> DetectCrossTargets(const cv::Mat& image, const CrossTargetOptions& options) {
  const cv::Mat gray8 = Gray8Of(image);
  cv::Mat gray;
  gray8.convertTo(gray, CV_32F);
  cv::GaussianBlur(gray, gray, cv::Size(0, 0), 1.0);
  // The target's black and the ground: dark is below their midpoint.
  const double low = Percentile(gray8, 0.05), median = Percentile(gray8, 0.5);
  const double dark_level = 0.5 * (low + median);
  const cv::Mat dark = gray < dark_level;
  // The cross's white, from the brightest 0.5 % of the image, and again
  // from the brightest 0.01 %: in a whole photo the targets are less than
  // 0.1 % of it, the 0.5 % are bright ground, and at the level they give,
  // ground that meets a bar's end joins the cross into one region, which
  // is then no cross. The higher level parts them.
  std::vector<double> bright_levels;
  for (double q : {0.995, 0.9999}) {
    const double level = 0.5 * (median + Percentile(gray8, q));
    if (bright_levels.empty() || level > bright_levels.back() + 8.0) bright_levels.push_back(level);
  }
  std::vector<CrossTarget> found;
  const double min_area = 4.0 * options.min_bar_width_px * options.min_bar_width_px;
  for (double bright_level : bright_levels) {
    const cv::Mat bright = gray > bright_level;
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
    for (int label = 1; label < n; ++label) {
      if (stats.at<int>(label, cv::CC_STAT_AREA) < min_area) continue;
      const cv::Rect box(stats.at<int>(label, cv::CC_STAT_LEFT), stats.at<int>(label, cv::CC_STAT_TOP),
                         stats.at<int>(label, cv::CC_STAT_WIDTH), stats.at<int>(label, cv::CC_STAT_HEIGHT));
      const auto t = CrossOf(gray, dark, labels, label, box, dark_level, options);
      if (!t || t->confidence < options.min_confidence) continue;
      // One target found at both levels is one detection: the more confident.
      auto same = std::find_if(found.begin(), found.end(), [&](const CrossTarget& f) {
        return (f.centre_px - t->centre_px).norm() < std::max(f.bar_width_px, t->bar_width_px);
      });
      if (same == found.end()) {
        found.push_back(*t);
      } else if (t->confidence > same->confidence) {
        *same = *t;
      }
    }
  }
  std::sort(found.begin(), found.end(),
            [](const CrossTarget& a, const CrossTarget& b) { return a.confidence > b.confidence; });
  return found;
}

}  // namespace aerotri
