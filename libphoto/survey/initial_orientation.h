// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Initial values for a classic aerial triangulation from image measurements
// alone (no reconstruction): the exterior orientation of each image and the
// positions of the tie points, to start the bundle adjustment from
// (GeoreferenceAndAdjust), as an analytical plotter's AT does.
//
//  1. Seed. Every image with `min_resection_points` or more control marks is
//     oriented by space resection (AP3P in RANSAC, then Levenberg–Marquardt
//     on the inliers) in a Cartesian frame of the control: the file's own
//     coordinates for a local engineering frame, else ENU metres tangent at
//     the first control point. Without two such images, the pair of images
//     sharing the most points is oriented relatively (five-point essential
//     matrix) and scaled by their GPS baseline where both have one; control
//     marks then count as tie points, and the adjustment's similarity brings
//     the block to the datum.
//  2. Growth, until nothing changes: forward intersection of every point
//     seen in two or more oriented images (rays at least min_angle_deg apart;
//     a ray that disagrees with the others set aside as a blunder while
//     three remain), a free bundle adjustment of what is oriented (the
//     certificate's intrinsics held, Huber loss), then space resection of
//     every image seeing `min_resection_points` or more of the points known
//     so far.
//
// Check-point marks never enter: check points stay independent. The model
// returned holds one camera (the certificate's), every image measured (those
// that could not be oriented with registered = false, and why in the report)
// and the intersected tie points with their observations; control and check
// points are added by the adjustment from their files.

#include <map>
#include <string>
#include <vector>

#include "georef/gcp_file.h"
#include "georef/gps_fix.h"
#include "georef/tie_point_file.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct InitialOrientationOptions {
  int min_resection_points = 4;
  double resection_threshold_px = 4.0;  // RANSAC inlier threshold
  double max_intersection_rms_px = 4.0;  // a point further off stays unknown
  double min_angle_deg = 1.0;

  // Throws InvalidArgument naming the option, its value and the range.
  void Check() const;
};

struct ImageOrientationResult {
  std::string name;
  bool oriented = false;
  // "resection from N control points", "resection from N points",
  // "relative orientation (seed pair)", or why it could not be oriented.
  std::string how;
  int round = 0;  // growth round in which it was oriented (0: seed)
  int points_used = 0;
};

struct InitialOrientationReport {
  std::string seed;   // what fixed the start: control resection or a relative pair
  bool control_frame = false;  // the model is in the control's Cartesian frame
  std::vector<ImageOrientationResult> images;  // in the model's image order
  int tie_points = 0;              // named in the file
  int tie_points_intersected = 0;  // in the model
  int oriented = 0;
  int rounds = 0;
  // Tie marks whose ray disagreed with the point's others beyond
  // max_intersection_rms_px: left out of the initial orientation, kept in
  // the model for the adjustment's outlier test to judge.
  int suspect_marks = 0;
  // One sentence per image left out or tie point lost, for the report's
  // input warnings.
  std::vector<std::string> warnings;
};

// camera: the certificate's camera (pixels, the measurements' resolution).
// control may be null; gps (by image name) may be empty. Throws
// InvalidArgument when no image can be oriented at all (naming what was
// missing: too few control marks per image and no pair of images sharing
// enough points).
SparseModel OrientFromMeasurements(const Camera& camera, const TiePointFile& ties, const GcpFile* control,
                                   const std::map<std::string, GpsFix>& gps,
                                   const InitialOrientationOptions& options, InitialOrientationReport* report);

}  // namespace aerotri
