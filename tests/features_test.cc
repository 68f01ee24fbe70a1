// SPDX-License-Identifier: BSD-3-Clause
// SIFT keypoints against rendered blobs at known sub-pixel positions: the
// keypoint coordinates must follow the project's pixel convention (0, 0 =
// centre of the top-left pixel) whatever octave they come from. OpenCV's SIFT
// doubles the image for its first octave (INTER_LINEAR, half-pixel centres)
// and halves the coordinates back without the -0.25 px that convention needs;
// an uncorrected detector shows a +0.25 px bias in x and y here.
#include "libphoto/features/features.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "tests/test_util.h"

namespace aerotri {
namespace {

// Mean of a 1-D Gaussian of sigma s centred at c over the pixel [i-0.5, i+0.5]
// (pixel centres at integers): the area-sampled profile a camera records.
double PixelIntegral(int i, double c, double s) {
  const double k = 1.0 / (s * std::sqrt(2.0));
  return 0.5 * (std::erf((i + 0.5 - c) * k) - std::erf((i - 0.5 - c) * k));
}

struct Blob {
  double x, y, sigma;
};

// Dark Gaussian blobs on a mid-grey background, area-sampled, 8-bit BGR.
cv::Mat RenderBlobs(const std::vector<Blob>& blobs, int width, int height) {
  cv::Mat grey(height, width, CV_64F, cv::Scalar(200.0));
  for (const Blob& b : blobs) {
    const int r = static_cast<int>(std::ceil(5 * b.sigma));
    const double amplitude = 150.0 * 2 * M_PI * b.sigma * b.sigma;  // peak ~150 grey levels
    for (int y = static_cast<int>(b.y) - r; y <= static_cast<int>(b.y) + r; ++y) {
      if (y < 0 || y >= height) continue;
      const double wy = PixelIntegral(y, b.y, b.sigma);
      for (int x = static_cast<int>(b.x) - r; x <= static_cast<int>(b.x) + r; ++x) {
        if (x < 0 || x >= width) continue;
        grey.at<double>(y, x) -= amplitude * wy * PixelIntegral(x, b.x, b.sigma);
      }
    }
  }
  cv::Mat grey8, bgr;
  grey.convertTo(grey8, CV_8U);
  cv::cvtColor(grey8, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

struct Bias {
  double mean_dx = 0, mean_dy = 0;
  int matched = 0;
};

// Detects keypoints on blobs of one sigma on a grid with random sub-pixel
// offsets and returns the mean keypoint-minus-truth offset of the nearest
// keypoint (within 1.5 px) of each blob.
Bias MeasureBias(double sigma, std::uint32_t seed) {
  constexpr int kWidth = 960, kHeight = 720;
  const int spacing = static_cast<int>(std::ceil(12 * sigma));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> frac(0.0, 1.0);
  std::vector<Blob> blobs;
  for (int y = spacing; y + spacing <= kHeight; y += spacing) {
    for (int x = spacing; x + spacing <= kWidth; x += spacing) {
      blobs.push_back({x + frac(rng), y + frac(rng), sigma});
    }
  }
  FeatureOptions options;
  options.max_dimension = 0;  // no resizing: the rendered pixels are the working pixels
  options.max_features = 100000;
  const ImageFeatures features = ExtractFeatures(RenderBlobs(blobs, kWidth, kHeight), options);
  Bias bias;
  for (const Blob& b : blobs) {
    double best = std::numeric_limits<double>::infinity();
    double dx = 0, dy = 0;
    for (const Keypoint& k : features.keypoints) {
      const double d = std::hypot(k.x - b.x, k.y - b.y);
      if (d < best) {
        best = d;
        dx = k.x - b.x;
        dy = k.y - b.y;
      }
    }
    if (best > 1.5) continue;
    bias.mean_dx += dx;
    bias.mean_dy += dy;
    ++bias.matched;
  }
  if (bias.matched > 0) {
    bias.mean_dx /= bias.matched;
    bias.mean_dy /= bias.matched;
  }
  std::printf("blob sigma %.1f px: mean keypoint - truth %+.4f, %+.4f px over %d blobs\n", sigma,
              bias.mean_dx, bias.mean_dy, bias.matched);
  return bias;
}

// The bound: a mean bias of at most 0.05 px in x and y, on blobs small
// enough to be found in the doubled first octave (sigma 1.2–2 px) and on
// larger ones found in the coarser octaves (4–8 px).
constexpr double kMaxMeanBiasPx = 0.05;

// Every blob size given: at least min_matched blobs found, mean bias within
// the bound in x and y.
void ExpectUnbiased(std::initializer_list<double> sigmas, std::uint32_t seed, int min_matched) {
  for (const double sigma : sigmas) {
    const Bias bias = MeasureBias(sigma, seed);
    SCOPED_TRACE("blob sigma " + std::to_string(sigma) + " px");
    ASSERT_GT(bias.matched, min_matched);
    EXPECT_LT(std::abs(bias.mean_dx), kMaxMeanBiasPx);
    EXPECT_LT(std::abs(bias.mean_dy), kMaxMeanBiasPx);
  }
}

TEST(Features, KeypointsAreUnbiasedInTheDoubledFirstOctave) { ExpectUnbiased({1.2, 1.6, 2.0}, 7, 300); }

TEST(Features, KeypointsAreUnbiasedInCoarserOctaves) { ExpectUnbiased({4.0, 8.0}, 11, 20); }

// A shifted rendering moves the keypoints by the shift: the detector sees
// sub-pixel positions at all (a detector that snapped to integers would pass
// a zero-mean test over random offsets but fail this one).
TEST(Features, KeypointsFollowASubPixelShift) {
  const Blob a{200.3, 150.6, 2.0};
  const Blob b{200.3 + 0.37, 150.6 - 0.21, 2.0};
  FeatureOptions options;
  options.max_dimension = 0;
  auto nearest = [&](const Blob& blob) {
    const ImageFeatures f = ExtractFeatures(RenderBlobs({blob}, 400, 300), options);
    Eigen::Vector2d best(1e9, 1e9);
    for (const Keypoint& k : f.keypoints) {
      const Eigen::Vector2d p(k.x, k.y);
      if ((p - Eigen::Vector2d(blob.x, blob.y)).norm() < (best - Eigen::Vector2d(blob.x, blob.y)).norm()) {
        best = p;
      }
    }
    return best;
  };
  const Eigen::Vector2d pa = nearest(a), pb = nearest(b);
  EXPECT_NEAR(pb.x() - pa.x(), 0.37, 0.05);
  EXPECT_NEAR(pb.y() - pa.y(), -0.21, 0.05);
}

// Feature files written before the correction (format 1) are read back in
// the corrected convention, so an existing workspace's matches stay valid.
TEST(Features, FormatOneFilesAreReadInTheCurrentConvention) {
  testing::TempDir dir;
  ImageFeatures f;
  f.width = 10;
  f.height = 8;
  f.keypoints.resize(1);
  f.keypoints[0].x = 3.5f;
  f.keypoints[0].y = 2.25f;
  f.descriptors = cv::Mat::zeros(1, 128, CV_8U);
  WriteFeatures(f, dir / "a.sift");
  const ImageFeatures same = ReadFeatures(dir / "a.sift");
  EXPECT_FLOAT_EQ(same.keypoints[0].x, 3.5f);
  EXPECT_FLOAT_EQ(same.keypoints[0].y, 2.25f);

  // Rewrite the magic as format 1: OpenCV's raw coordinates, 0.25 px high.
  {
    std::fstream file(dir / "a.sift", std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(7);
    file.put('1');
  }
  const ImageFeatures old = ReadFeatures(dir / "a.sift");
  EXPECT_FLOAT_EQ(old.keypoints[0].x, 3.25f);
  EXPECT_FLOAT_EQ(old.keypoints[0].y, 2.0f);
}

}  // namespace
}  // namespace aerotri
