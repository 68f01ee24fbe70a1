// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// SIFT keypoints and RootSIFT descriptors (Lowe 2004; Arandjelović and
// Zisserman 2012: L1-normalise, then square root) through OpenCV, at a
// working resolution.
//
// Working resolution: the image is resized (area averaging) so that its
// longer side is at most max_dimension; keypoints stay in working-resolution
// pixels (centre of the top-left pixel at (0, 0)), which is the frame of the
// whole sparse reconstruction. full = (work + 0.5) * scale - 0.5.
//
// Keypoint coordinates follow that convention whatever octave they come
// from (OpenCV's own are 0.25 px high; see features.cc).
//
// Files: features/<image>.sift, binary, little-endian:
//   "AERSIFT2" ("AERSIFT1": the same with OpenCV's raw coordinates, corrected
//   on reading), int32 width, height (working), float64 scale, int32 count,
//   count x (float32 x, y, size, angle, uint8 r, g, b, pad),
//   count x 128 uint8 descriptors (RootSIFT x 512, clipped to 255).

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace aerotri {

struct FeatureOptions {
  int max_dimension = 1600;          // px of the working image's longer side
  int max_features = 12000;          // kept, spread over the image
  double contrast_threshold = 0.02;  // OpenCV's default 0.04 starves low-texture fields

  // Throws InvalidArgument naming the option, its value and the range.
  void Check() const;
};

struct Keypoint {
  float x = 0, y = 0;  // working-resolution px
  float size = 0;
  float angle = 0;
  std::uint8_t rgb[3] = {0, 0, 0};
};

struct ImageFeatures {
  int width = 0;   // working resolution
  int height = 0;
  double scale = 1.0;  // full-resolution px per working px
  std::vector<Keypoint> keypoints;
  cv::Mat descriptors;  // N x 128, CV_8U

  // Descriptors as float rows (what FLANN and distance computations use).
  cv::Mat FloatDescriptors() const;
};

// Reads the image (sensor orientation, EXIF orientation ignored), resizes it
// to the working resolution and extracts features. Throws IoError when the
// file cannot be decoded.
ImageFeatures ExtractFeatures(const std::filesystem::path& image_path, const FeatureOptions& options);
ImageFeatures ExtractFeatures(const cv::Mat& image_bgr, const FeatureOptions& options);

// Working-resolution image (BGR) as ExtractFeatures sees it.
cv::Mat LoadWorkingImage(const std::filesystem::path& image_path, int max_dimension,
                         double* scale = nullptr);

void WriteFeatures(const ImageFeatures& features, const std::filesystem::path& path);
// Throws ParseError / IoError for a missing, truncated or foreign file.
ImageFeatures ReadFeatures(const std::filesystem::path& path);

}  // namespace aerotri
