// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Ground-control targets found in a photo: a white cross on a black square
// (the target OpenDroneMap's example surveys and many surveyors lay out),
// its centre to a fraction of a pixel.
//
// The cross is a bright region enclosed by dark: every bright connected
// region whose surrounding ring is mostly dark is a candidate. Its two bars
// are found by RANSAC on its pixels (the second at 45 degrees or more from
// the first), each centre line then fitted to the image's own intensities
// across the bar (weights above the dark level, the crossing itself and the
// bar ends left out), and the centre is their intersection. A short tick
// or a missing arm does not move it. Pixels: the centre of the top-left
// pixel is (0, 0), x right, y down (aerotri's and OpenDroneMap's marks).

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace aerotri {

struct CrossTargetOptions {
  // The bars' width in pixels that a target may have (its square is some
  // four to eight times as wide).
  double min_bar_width_px = 3.0;
  double max_bar_width_px = 60.0;
  // Detections below this confidence are not returned.
  double min_confidence = 0.5;
};

struct CrossTarget {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  // In [0, 1]: how dark the ring about the cross is, how much of the cross
  // the two bars explain, and how square they meet, multiplied.
  double confidence = 0.0;
  double bar_width_px = 0.0;
  double angle_deg = 0.0;  // between the two bars (90 for a true cross)
  Eigen::Vector2d bar_direction[2] = {Eigen::Vector2d::UnitX(), Eigen::Vector2d::UnitY()};
};

// An 8-bit grey, BGR or BGRA image as 8-bit grey (grey as it is).
cv::Mat Gray8Of(const cv::Mat& image);

// Every cross target in an 8-bit grey or BGR image, the most confident first.
std::vector<CrossTarget> DetectCrossTargets(const cv::Mat& image, const CrossTargetOptions& options = {});

}  // namespace aerotri
