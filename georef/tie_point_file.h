// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Image measurements of tie points, for a classic aerial triangulation from
// measurements (aerotri adjust --measurements): one measurement per line,
//
//   image_name point_name im_x im_y [sigma_px=S]
//
// a point being every line with its name (seen in two or more images to be
// of use). Blank lines and lines starting with '#' are skipped. Pixels follow
// the control files' convention (gcp_file.h, PixelOrigin): kCentre puts the
// centre of the top-left pixel at (0, 0), kCorner at (0.5, 0.5). Control and
// check marks stay in their own files; a tie point named like a control point
// is still a tie point.
//
// Errors: ParseError "file:line: what was expected, got what".

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "georef/gcp_file.h"

namespace aerotri {

struct TieMeasurement {
  std::string image;
  std::string point;
  Eigen::Vector2d xy_px = Eigen::Vector2d::Zero();  // aerotri convention
  std::optional<double> sigma_px;
  int line = 0;
};

struct TiePointFile {
  std::string path;
  std::vector<TieMeasurement> measurements;  // in file order
};

// Also refuses a point measured twice in one image (naming both lines).
TiePointFile ReadTiePointFile(const std::filesystem::path& path, PixelOrigin origin = PixelOrigin::kCentre);

}  // namespace aerotri
