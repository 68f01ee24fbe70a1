// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The ground-control targets surveyors lay out, found in a photo with a
// sub-pixel centre and a confidence:
//
//   checker   black and white squares meeting at the centre (two squares
//             corner to corner, or four): the centre is a saddle of the
//             brightness. Candidates are the saddles of the smoothed image
//             (negative Hessian determinant); one is a checker when the
//             circles about it, at several radii, cross from dark to light
//             exactly four times with opposite sectors alike. The centre is
//             then where every gradient in a window about it points away
//             from it (Förstner's operator, as cv::cornerSubPix).
//   cross     a white cross on a black square (cross_target.h).
//   circle    a disc (bright on dark or dark on bright), alone or as a
//             bull's-eye of concentric discs: each region whose outline is
//             an ellipse and whose surround is of the other shade. Its
//             outline is found to a fraction of a pixel (where the
//             brightness crosses the mean of the two shades, interpolated
//             between pixels), the ellipse fitted to it, and the centre is
//             the ellipse's (of all the concentric outlines, averaged by
//             radius). Under perspective the ellipse's centre is not quite
//             the circle's: about r^2 tan(tilt) / f off (0.04 px for a
//             disc 30 px across at 3,000 px focal length, 8 deg off nadir).
//   A cross's bars should be 5 px wide or more.
//
// Pixels: the centre of the top-left pixel is (0, 0), x right, y down.

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace aerotri {

enum class TargetKind { kChecker, kCross, kCircle };

const char* TargetKindName(TargetKind kind);  // "checker", "cross", "circle"
std::optional<TargetKind> TargetKindFromName(const std::string& name);

struct TargetDetection {
  TargetKind kind = TargetKind::kChecker;
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  // In [0, 1]: how clearly the pattern is the target's (contrast, symmetry,
  // the outline's fit), multiplied; see each detector.
  double confidence = 0.0;
  double size_px = 0.0;  // the pattern's extent about the centre (radius)
};

struct TargetDetectionOptions {
  std::vector<TargetKind> kinds = {TargetKind::kChecker, TargetKind::kCross, TargetKind::kCircle};
  // The target's radius in pixels that a detection may have.
  double min_radius_px = 4.0;
  double max_radius_px = 150.0;
  // The smallest difference of the target's dark and light (digital numbers).
  double min_contrast_dn = 30.0;
  double min_confidence = 0.5;
};

// Every target of the given kinds in an 8-bit grey or BGR image, the most
// confident first. Detections of different kinds within 2 px of each other
// are one (the more confident kept).
std::vector<TargetDetection> DetectTargets(const cv::Mat& image, const TargetDetectionOptions& options = {});

// Each detector alone (grey 8-bit input).
std::vector<TargetDetection> DetectCheckerTargets(const cv::Mat& gray8, const TargetDetectionOptions& options);
std::vector<TargetDetection> DetectCircleTargets(const cv::Mat& gray8, const TargetDetectionOptions& options);

}  // namespace aerotri
