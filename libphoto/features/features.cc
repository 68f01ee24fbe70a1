// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/features/features.h"

#include <cmath>
#include <algorithm>
#include <cstring>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "libphoto/base/atomic_file.h"
#include "camera_models/camera.h"
#include "libphoto/base/error.h"

namespace aerotri {

void FeatureOptions::Check() const {
  CheckOption(max_dimension == 0 || max_dimension >= 32, "--max-dimension", max_dimension,
              "0 (full size) or at least 32 pixels");
  CheckOption(max_features >= 1, "--max-features", max_features, "a positive number of features");
  CheckOption(contrast_threshold > 0.0 && contrast_threshold < 1.0, "features contrast_threshold",
              contrast_threshold, "a number in (0, 1)");
}
namespace {

// Format 2: keypoints in the project's pixel convention. Format 1 files hold
// OpenCV's raw coordinates, 0.25 px high (see kSiftCentreCorrectionPx); they
// are read and corrected.
constexpr char kMagic[8] = {'A', 'E', 'R', 'S', 'I', 'F', 'T', '2'};
constexpr char kMagicV1[8] = {'A', 'E', 'R', 'S', 'I', 'F', 'T', '1'};

// OpenCV's SIFT builds its first octave from the image doubled by
// cv::resize (INTER_LINEAR, half-pixel centres: doubled pixel u sits at
// original u/2 − 0.25), finds every keypoint in doubled-image units (coarser
// octaves are exact subsamplings of it) and halves them. The halving leaves
// every coordinate 0.25 px high against pixel centres at integers; a blob
// test (tests/features_test.cc) measures the bias on every octave.
constexpr float kSiftCentreCorrectionPx = -0.25f;

// Keeps at most max_features keypoints, spread over the image: an equal
// share per cell of an 8 x 8 grid (strongest first), the rest of the budget
// to the strongest remaining anywhere. A plain strongest-N cap lets tree
// canopy (high contrast, unmatchable) crowd out roads and grass.
std::vector<cv::KeyPoint> SelectSpatially(std::vector<cv::KeyPoint> kps, int max_features, int width,
                                          int height) {
  if (max_features <= 0 || static_cast<int>(kps.size()) <= max_features) return kps;
  constexpr int kGrid = 8;
  std::vector<std::vector<int>> cells(kGrid * kGrid);
  for (size_t i = 0; i < kps.size(); ++i) {
    const int cx = std::clamp(static_cast<int>(kps[i].pt.x * kGrid / width), 0, kGrid - 1);
    const int cy = std::clamp(static_cast<int>(kps[i].pt.y * kGrid / height), 0, kGrid - 1);
    cells[cy * kGrid + cx].push_back(static_cast<int>(i));
  }
  const int per_cell = max_features / (kGrid * kGrid);
  std::vector<char> taken(kps.size(), 0);
  std::vector<cv::KeyPoint> out;
  out.reserve(max_features);
  for (auto& cell : cells) {
    std::sort(cell.begin(), cell.end(), [&](int a, int b) { return kps[a].response > kps[b].response; });
    for (int k = 0; k < std::min<int>(per_cell, static_cast<int>(cell.size())); ++k) {
      taken[cell[k]] = 1;
      out.push_back(kps[cell[k]]);
    }
  }
  std::vector<int> rest;
  for (size_t i = 0; i < kps.size(); ++i) {
    if (!taken[i]) rest.push_back(static_cast<int>(i));
  }
  std::sort(rest.begin(), rest.end(), [&](int a, int b) { return kps[a].response > kps[b].response; });
  for (size_t k = 0; k < rest.size() && static_cast<int>(out.size()) < max_features; ++k) {
    out.push_back(kps[rest[k]]);
  }
  return out;
}

}  // namespace

cv::Mat ImageFeatures::FloatDescriptors() const {
  cv::Mat f;
  descriptors.convertTo(f, CV_32F, 1.0 / 512.0);
  return f;
}

cv::Mat LoadWorkingImage(const std::filesystem::path& image_path, int max_dimension, double* scale) {
  cv::Mat full = cv::imread(image_path.string(), cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  if (full.empty()) throw IoError(image_path.string(), "cannot decode the image (corrupt or not an image)");
  const auto [ww, wh] = WorkingImageSize(full.cols, full.rows, max_dimension);
  if (ww == full.cols && wh == full.rows) {
    if (scale) *scale = 1.0;
    return full;
  }
  cv::Mat work;
  cv::resize(full, work, cv::Size(ww, wh), 0, 0, cv::INTER_AREA);
  if (scale) *scale = static_cast<double>(full.cols) / work.cols;
  return work;
}

ImageFeatures ExtractFeatures(const std::filesystem::path& image_path, const FeatureOptions& options) {
  double scale = 1.0;
  const cv::Mat work = LoadWorkingImage(image_path, options.max_dimension, &scale);
  ImageFeatures f = ExtractFeatures(work, options);
  f.scale = scale;
  return f;
}

ImageFeatures ExtractFeatures(const cv::Mat& image, const FeatureOptions& options) {
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(0, 3, options.contrast_threshold, 10.0, 1.6);
  std::vector<cv::KeyPoint> kps;
  sift->detect(grey, kps);
  kps = SelectSpatially(kps, options.max_features, image.cols, image.rows);
  cv::Mat desc;
  sift->compute(grey, kps, desc);
  ImageFeatures f;
  f.width = image.cols;
  f.height = image.rows;
  f.keypoints.reserve(kps.size());
  f.descriptors.create(static_cast<int>(kps.size()), 128, CV_8U);
  for (size_t i = 0; i < kps.size(); ++i) {
    Keypoint k;
    k.x = kps[i].pt.x + kSiftCentreCorrectionPx;
    k.y = kps[i].pt.y + kSiftCentreCorrectionPx;
    k.size = kps[i].size;
    k.angle = kps[i].angle;
    const int px = std::clamp(static_cast<int>(std::lround(k.x)), 0, image.cols - 1);
    const int py = std::clamp(static_cast<int>(std::lround(k.y)), 0, image.rows - 1);
    const cv::Vec3b bgr = image.at<cv::Vec3b>(py, px);
    k.rgb[0] = bgr[2];
    k.rgb[1] = bgr[1];
    k.rgb[2] = bgr[0];
    f.keypoints.push_back(k);
    // RootSIFT: L1 normalise, square root (unit L2 norm), store x 512.
    const float* d = desc.ptr<float>(static_cast<int>(i));
    double l1 = 0.0;
    for (int c = 0; c < 128; ++c) l1 += std::abs(d[c]);
    std::uint8_t* out = f.descriptors.ptr<std::uint8_t>(static_cast<int>(i));
    for (int c = 0; c < 128; ++c) {
      const double v = l1 > 0 ? std::sqrt(std::abs(d[c]) / l1) : 0.0;
      out[c] = static_cast<std::uint8_t>(std::min(255.0, std::round(512.0 * v)));
    }
  }
  return f;
}

void WriteFeatures(const ImageFeatures& f, const std::filesystem::path& path) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out.write(kMagic, 8);
    const std::int32_t w = f.width, h = f.height, n = static_cast<std::int32_t>(f.keypoints.size());
    out.write(reinterpret_cast<const char*>(&w), 4);
    out.write(reinterpret_cast<const char*>(&h), 4);
    out.write(reinterpret_cast<const char*>(&f.scale), 8);
    out.write(reinterpret_cast<const char*>(&n), 4);
    for (const Keypoint& k : f.keypoints) {
      const float v[4] = {k.x, k.y, k.size, k.angle};
      out.write(reinterpret_cast<const char*>(v), 16);
      const char rgbp[4] = {static_cast<char>(k.rgb[0]), static_cast<char>(k.rgb[1]),
                            static_cast<char>(k.rgb[2]), 0};
      out.write(rgbp, 4);
    }
    if (n > 0) out.write(reinterpret_cast<const char*>(f.descriptors.data), static_cast<std::streamsize>(n) * 128);
  });
}

ImageFeatures ReadFeatures(const std::filesystem::path& path) {
  const std::string data = ReadTextFile(path);
  const std::string p = path.string();
  auto need = [&](size_t offset, size_t bytes) {
    if (offset + bytes > data.size()) throw ParseError(p, 0, "truncated feature file");
  };
  need(0, 28);
  const bool v1 = std::memcmp(data.data(), kMagicV1, 8) == 0;
  if (!v1 && std::memcmp(data.data(), kMagic, 8) != 0) {
    throw ParseError(p, 0, "not an aerotri feature file (bad magic)");
  }
  const float shift = v1 ? kSiftCentreCorrectionPx : 0.0f;
  ImageFeatures f;
  std::int32_t w, h, n;
  std::memcpy(&w, data.data() + 8, 4);
  std::memcpy(&h, data.data() + 12, 4);
  std::memcpy(&f.scale, data.data() + 16, 8);
  std::memcpy(&n, data.data() + 24, 4);
  if (w <= 0 || h <= 0 || n < 0 || !(f.scale > 0)) throw ParseError(p, 0, "corrupt feature file header");
  f.width = w;
  f.height = h;
  need(28, static_cast<size_t>(n) * (20 + 128));
  f.keypoints.resize(n);
  size_t off = 28;
  for (std::int32_t i = 0; i < n; ++i, off += 20) {
    float v[4];
    std::memcpy(v, data.data() + off, 16);
    Keypoint& k = f.keypoints[i];
    k.x = v[0] + shift;
    k.y = v[1] + shift;
    k.size = v[2];
    k.angle = v[3];
    for (int c = 0; c < 3; ++c) k.rgb[c] = static_cast<std::uint8_t>(data[off + 16 + c]);
  }
  f.descriptors.create(n, 128, CV_8U);
  if (n > 0) std::memcpy(f.descriptors.data, data.data() + off, static_cast<size_t>(n) * 128);
  return f;
}

}  // namespace aerotri
