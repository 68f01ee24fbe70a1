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

// The real targets of OpenDroneMap's odm_data_copr survey: each crop's one
// target found, and nothing else in any crop. Against the author's hand
// marks the detections sit a common 1.3 px higher (y) on every target,
// whatever its turn, where the rendered crosses above show no bias: the
// hand marks are below the bars' crossing (crop 10: 3.8 px off it, down
// and right, on the image), and some are whole pixels (114, 138). So the
// test holds the detections to the hand marks within their own scatter
// (4 px), the common offset to under 2 px, and about it the median to
// under 1 px; the figures per crop are printed.
TEST(CrossTargets, RealTargetsAtTheirHandMarks) {
  const auto dir = testing::SharedData("gcp_targets_copr");
  if (dir.empty()) GTEST_SKIP() << "../shared/data/gcp_targets_copr is absent";
  std::ifstream marks(dir / "marks.txt");
  std::vector<Eigen::Vector2d> d;
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
    std::printf("%s: (%.2f, %.2f), hand mark (%.2f, %.2f): %+.2f %+.2f px, confidence %.2f, bars %.1f px at %.1f deg\n",
                crop.c_str(), found[0].centre_px.x(), found[0].centre_px.y(), hand.x(), hand.y(), e.x(), e.y(),
                found[0].confidence, found[0].bar_width_px, found[0].angle_deg);
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
}

}  // namespace
}  // namespace aerotri
