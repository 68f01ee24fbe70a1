// SPDX-License-Identifier: BSD-3-Clause
// Cross-on-square targets: rendered ones with a known centre, and the 27
// real crops of ../shared/data/gcp_targets_copr against their hand marks.
#include "libphoto/targets/cross_target.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/test_util.h"

namespace aerotri {
namespace {

// A black square with a white cross of bar width w, centred at `centre`
// (pixel-centre convention), turned by `angle_deg`, on mid-grey ground,
// rendered 8x supersampled, blurred and noisy.
cv::Mat RenderCross(const Eigen::Vector2d& centre, double side, double bar, double angle_deg, double blur,
                    double noise, unsigned seed) {
  const int size = 200, ss = 8;
  cv::Mat big(size * ss, size * ss, CV_32F);
  const double c = std::cos(angle_deg * M_PI / 180.0), s = std::sin(angle_deg * M_PI / 180.0);
  for (int y = 0; y < big.rows; ++y) {
    for (int x = 0; x < big.cols; ++x) {
      const double px = (x + 0.5) / ss - 0.5 - centre.x(), py = (y + 0.5) / ss - 0.5 - centre.y();
      const double u = c * px + s * py, v = -s * px + c * py;
      float value = 120.0f;
      if (std::abs(u) < side / 2 && std::abs(v) < side / 2) {
        value = 20.0f;
        const double arm = 0.42 * side;
        if ((std::abs(u) < bar / 2 && std::abs(v) < arm) || (std::abs(v) < bar / 2 && std::abs(u) < arm)) {
          value = 230.0f;
        }
      }
      big.at<float>(y, x) = value;
    }
  }
  cv::Mat image;
  cv::resize(big, image, cv::Size(size, size), 0, 0, cv::INTER_AREA);
  if (blur > 0.0) cv::GaussianBlur(image, image, cv::Size(0, 0), blur);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, static_cast<float>(noise));
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<float>(y, x) += g(rng);
  }
  cv::Mat out;
  image.convertTo(out, CV_8U);
  return out;
}

TEST(CrossTargets, RenderedCrossesAreFoundToATenthOfAPixel) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  double worst = 0.0;
  for (int k = 0; k < 12; ++k) {
    const Eigen::Vector2d centre(95.0 + 10 * u(rng), 102.0 + 10 * u(rng));
    const double angle = 7.0 * k;
    const double bar = 6.0 + k % 4;
    const cv::Mat image = RenderCross(centre, 12.0 * bar, bar, angle, 1.2, 3.0, 10 + k);
    const std::vector<CrossTarget> found = DetectCrossTargets(image);
    ASSERT_EQ(found.size(), 1u) << "angle " << angle;
    const double error = (found[0].centre_px - centre).norm();
    worst = std::max(worst, error);
    EXPECT_LT(error, 0.1) << "angle " << angle << " bar " << bar;
    EXPECT_NEAR(found[0].angle_deg, 90.0, 2.0);
    EXPECT_GT(found[0].confidence, 0.6);
  }
  std::printf("rendered crosses: worst centre error %.3f px\n", worst);
}

TEST(CrossTargets, GroundWithoutATargetHasNone) {
  cv::Mat ground(200, 200, CV_8U);
  cv::randn(ground, 120, 25);
  cv::GaussianBlur(ground, ground, cv::Size(0, 0), 1.5);
  EXPECT_TRUE(DetectCrossTargets(ground).empty());
  // A white bar on the ground alone (a road marking): not a cross on black.
  cv::line(ground, cv::Point(20, 100), cv::Point(180, 110), cv::Scalar(240), 8);
  EXPECT_TRUE(DetectCrossTargets(ground).empty());
}

// The centre of point symmetry of a crop about `start`: where the image
// turned half a turn about the point matches itself best over a disc of
// `radius` px (mean squared grey difference, bilinear, pattern search down
// to 0.02 px). A cross on a square is symmetric so, whatever its turn; the
// estimate shares nothing with the detector's bar fits, so it is an
// independent reference for real targets whose true centre is unknown.
Eigen::Vector2d SymmetryCentre(const cv::Mat& bgr, const Eigen::Vector2d& start, int radius) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(grey, CV_32F);
  auto at = [&](double x, double y) {
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    if (x0 < 0 || y0 < 0 || x0 + 1 >= grey.cols || y0 + 1 >= grey.rows) return 0.0;
    return (1 - fy) * ((1 - fx) * grey.at<float>(y0, x0) + fx * grey.at<float>(y0, x0 + 1)) +
           fy * ((1 - fx) * grey.at<float>(y0 + 1, x0) + fx * grey.at<float>(y0 + 1, x0 + 1));
  };
  auto cost = [&](const Eigen::Vector2d& c) {
    double sum = 0.0;
    for (int dy = 0; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        if (dx * dx + dy * dy > radius * radius || (dy == 0 && dx <= 0)) continue;
        const double d = at(c.x() + dx, c.y() + dy) - at(c.x() - dx, c.y() - dy);
        sum += d * d;
      }
    return sum;
  };
  Eigen::Vector2d c = start;
  for (double step : {1.0, 0.5, 0.25, 0.1, 0.05, 0.02})
    for (int moves = 0; moves < 20; ++moves) {
      Eigen::Vector2d best = c;
      double best_cost = cost(c);
      for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j) {
          const Eigen::Vector2d t = c + step * Eigen::Vector2d(i, j);
          const double v = cost(t);
          if (v < best_cost) best_cost = v, best = t;
        }
      if (best == c) break;
      c = best;
    }
  return c;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int WithinOnePx(const std::vector<double>& v) {
  return static_cast<int>(std::count_if(v.begin(), v.end(), [](double d) { return d <= 1.0; }));
}

// The real targets of OpenDroneMap's odm_data_copr survey: each crop's one
// target found, and nothing else in any crop. Measured against two
// references:
// - the centre of point symmetry (above, over 24 px): the detections agree
//   with it to a median of 0.28 px, 23 of 27 within 1 px, with no common
//   offset;
// - the author's hand marks: the detections sit a common 1.3 px higher (y)
//   on every target, whatever its turn, and so does the symmetry centre
//   (1.33 px). The hand marks carry that offset and a scatter of their own:
//   some are whole pixels (114, 138), and the one target marked twice in
//   one photo under two names (crops 04 and 23, gcp04 and gcp00, cut at
//   different corners) has hand marks 1.14 px apart, where the detections
//   of the two crops agree to 0.04 px.
// So the detector is held to the symmetry centre (1 px in 22 of 27,
// median under 0.5 px), to itself across the two crops of one target
// (0.1 px), and to the hand marks within their own scatter (4 px), their
// common offset under 2 px and, about it, a median under 1 px.
TEST(CrossTargets, RealTargetsAtTheirHandMarks) {
  const auto dir = testing::SharedData("gcp_targets_copr");
  if (dir.empty()) GTEST_SKIP() << "../shared/data/gcp_targets_copr is absent";
  std::ifstream marks(dir / "marks.txt");
  std::vector<Eigen::Vector2d> d;
  std::vector<double> to_symmetry, hand_to_symmetry;
  Eigen::Vector2d hand_offset_from_symmetry = Eigen::Vector2d::Zero();
  struct InPhoto {
    std::string photo, gcp;
    Eigen::Vector2d px;  // the detection in the photo's pixels
  };
  std::vector<InPhoto> in_photo;
  int crops = 0;
  for (std::string line; std::getline(marks, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    std::string crop, photo, gcp;
    int x0 = 0, y0 = 0;
    Eigen::Vector2d hand;
    in >> crop >> photo >> gcp >> x0 >> y0 >> hand.x() >> hand.y();
    const cv::Mat image = cv::imread((dir / crop).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty()) << crop;
    ++crops;
    const std::vector<CrossTarget> found = DetectCrossTargets(image);
    ASSERT_EQ(found.size(), 1u) << crop << ": exactly one target in each crop";
    const Eigen::Vector2d e = found[0].centre_px - hand;
    d.push_back(e);
    EXPECT_LT(e.norm(), 4.0) << crop;
    const Eigen::Vector2d symmetric = SymmetryCentre(image, found[0].centre_px, 24);
    to_symmetry.push_back((found[0].centre_px - symmetric).norm());
    hand_to_symmetry.push_back((hand - symmetric).norm());
    hand_offset_from_symmetry += hand - symmetric;
    in_photo.push_back({photo, gcp, found[0].centre_px + Eigen::Vector2d(x0, y0)});
    std::printf("%s: (%.2f, %.2f), hand mark (%.2f, %.2f): %+.2f %+.2f px; symmetry centre (%.2f, %.2f): "
                "%+.2f %+.2f px; confidence %.2f, bars %.1f px at %.1f deg\n",
                crop.c_str(), found[0].centre_px.x(), found[0].centre_px.y(), hand.x(), hand.y(), e.x(), e.y(),
                symmetric.x(), symmetric.y(), found[0].centre_px.x() - symmetric.x(),
                found[0].centre_px.y() - symmetric.y(), found[0].confidence, found[0].bar_width_px,
                found[0].angle_deg);
  }
  ASSERT_EQ(crops, 27);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& e : d) mean += e;
  mean /= d.size();
  std::vector<double> raw, about;
  for (const Eigen::Vector2d& e : d) raw.push_back(e.norm()), about.push_back((e - mean).norm());
  std::sort(raw.begin(), raw.end());
  std::sort(about.begin(), about.end());
  const int within = static_cast<int>(std::count_if(raw.begin(), raw.end(), [](double v) { return v <= 1.0; }));
  const int within_about =
      static_cast<int>(std::count_if(about.begin(), about.end(), [](double v) { return v <= 1.0; }));
  std::printf("against the hand marks: common offset (%+.2f, %+.2f) px; within 1 px %d of 27, median %.2f px; "
              "about the offset: within 1 px %d of 27, median %.2f px\n",
              mean.x(), mean.y(), within, raw[raw.size() / 2], within_about, about[about.size() / 2]);
  EXPECT_LT(mean.norm(), 2.0);
  EXPECT_LT(about[about.size() / 2], 1.0);

  hand_offset_from_symmetry /= crops;
  std::printf("against the symmetry centres: within 1 px %d of 27, median %.2f px; the hand marks: within 1 px %d "
              "of 27, median %.2f px, common offset (%+.2f, %+.2f) px\n",
              WithinOnePx(to_symmetry), Median(to_symmetry), WithinOnePx(hand_to_symmetry),
              Median(hand_to_symmetry), hand_offset_from_symmetry.x(), hand_offset_from_symmetry.y());
  EXPECT_GE(WithinOnePx(to_symmetry), 22);
  EXPECT_LT(Median(to_symmetry), 0.5);

  // One target, one photo, two crops (gcp04 and gcp00 on IMG_0031).
  int pairs = 0;
  for (size_t i = 0; i < in_photo.size(); ++i)
    for (size_t j = i + 1; j < in_photo.size(); ++j)
      if (in_photo[i].photo == in_photo[j].photo && (in_photo[i].px - in_photo[j].px).norm() < 5.0) {
        ++pairs;
        const double apart = (in_photo[i].px - in_photo[j].px).norm();
        EXPECT_LT(apart, 0.1) << in_photo[i].photo;
        std::printf("%s, %s and %s: one target, detections %.3f px apart\n", in_photo[i].photo.c_str(),
                    in_photo[i].gcp.c_str(), in_photo[j].gcp.c_str(), apart);
      }
  EXPECT_EQ(pairs, 1);
}

}  // namespace
}  // namespace aerotri
