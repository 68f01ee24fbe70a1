// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Pair selection, descriptor matching and geometric verification.
//
// Pairs: exhaustive for small sets or without GPS; otherwise each image with
// its nearest GPS neighbours (horizontal distance). Matching: approximate
// nearest neighbours (FLANN randomised kd-trees) with Lowe's ratio test and a
// one-to-one constraint. Verification: fundamental matrix by MAGSAC++ (OpenCV
// USAC), which needs no calibration and tolerates the unknown lens
// distortion at a few pixels; the homography inlier count is kept to flag
// planar or low-parallax pairs.
//
// File: matches.bin, binary: "AERMTCH1", int32 pairs, then per pair int32
// i, j, putative, homography_inliers, n, and n x (int32 feature_i, feature_j).

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "libphoto/base/progress.h"
#include "libphoto/features/features.h"

namespace aerotri {

struct MatchOptions {
  double ratio = 0.8;
  int min_inliers = 20;
  double max_epipolar_px = 3.0;  // working resolution
  int gps_neighbours = 12;
  int exhaustive_up_to = 12;     // images
  int flann_checks = 128;
  int num_threads = 0;

  // Throws InvalidArgument naming the option, its value and the range.
  void Check() const;
};

struct PairMatches {
  int i = 0;
  int j = 0;
  int putative = 0;
  int homography_inliers = 0;
  std::vector<std::array<int, 2>> inliers;  // (feature in i, feature in j)
};

// Candidate pairs (i < j). gps: horizontal positions (m) or nullopt per image.
std::vector<std::pair<int, int>> SelectPairs(const std::vector<std::optional<Eigen::Vector2d>>& gps,
                                             const MatchOptions& options, std::string* strategy);

// Matches and verifies every candidate pair on all cores; returns the pairs
// that passed (at least min_inliers inliers).
std::vector<PairMatches> MatchPairs(const std::vector<ImageFeatures>& features,
                                    const std::vector<std::pair<int, int>>& pairs,
                                    const MatchOptions& options, const ProgressCallback& progress);

void WriteMatches(const std::vector<PairMatches>& matches, const std::filesystem::path& path);
// Throws ParseError for a missing, truncated or foreign file.
std::vector<PairMatches> ReadMatches(const std::filesystem::path& path);
// Checks every pair's image indices and every inlier's feature indices
// against the features they refer to (a matches.bin older than a features
// rerun, or bit-flipped, would otherwise be read out of bounds). Throws
// ParseError naming path, the pair and the index, and what to rerun.
void ValidateMatches(const std::vector<PairMatches>& matches, const std::vector<ImageFeatures>& features,
                     const std::filesystem::path& path);

}  // namespace aerotri
