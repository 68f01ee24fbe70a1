// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Ground control marked in the photos from coordinates alone (what a GNSS
// rover gives): each surveyed point is predicted in every photo through the
// GPS-georeferenced model, the targets near the prediction are detected
// (targets.h), and the detections are joined across photos by the model:
// the marks of a point are the detections whose rays meet at one place
// (triangulated; within 2 px in every photo). So a detection of something
// else near the prediction, or a target seen in only some photos, does not
// move the mark, and the common offset of the GPS georeferencing (metres)
// does not matter.
//
// Nothing is guessed. A point is reported, not marked, when
//   NOT_SEEN        no photo's footprint holds it;
//   NOT_FOUND       no target within the search radius of its surveyed
//                   position in the photos that should see it (a point
//                   surveyed far from its target, or a target covered);
//   TWO_CANDIDATES  two targets near it, each seen in several photos, and
//                   neither clearly at the GPS georeferencing's offset that
//                   the points marked unambiguously show;
//   SHARED_TARGET   its target is another point's too (two names for one
//                   target, or two coordinates for one);
//   UNPLACED        photos without GPS, and the coordinate list could not be
//                   placed on the targets found in them (see MarkControl).
// A point seen in one photo only is marked when one target is found there
// (SINGLE_PHOTO: nothing confirms it).

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "georef/gcp_file.h"
#include "georef/gps_fix.h"
#include "georef/similarity.h"
#include "libphoto/base/progress.h"
#include "libphoto/model/sparse_model.h"
#include "libphoto/targets/targets.h"

namespace aerotri {

struct MarkingOptions {
  TargetDetectionOptions detection;
  // How far from its predicted place a target is looked for (metres on the
  // ground); 0: twice the photos' median GPS sigma (horizontal), at least 1.5 m.
  double search_radius_m = 0.0;
  // A detection joins a point's marks when the point triangulated from the
  // marks reprojects within this many pixels of it.
  double max_reprojection_px = 2.0;
  int num_threads = 0;
  ProgressCallback progress;
};

struct TargetMark {
  std::string image;
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Zero();  // from the surveyed position
  bool predicted_inside = true;  // else searched because the window met the photo
  bool detected = false;                                    // a mark in this photo
  Eigen::Vector2d xy_px = Eigen::Vector2d::Zero();
  double confidence = 0.0;
  TargetKind kind = TargetKind::kChecker;
  double reprojection_px = 0.0;  // of the triangulated target
};

struct PointMarking {
  std::string name;
  bool check = false;          // a check point (else control)
  std::string status;          // MARKED, SINGLE_PHOTO, NOT_SEEN, NOT_FOUND, TWO_CANDIDATES, SHARED_TARGET
  std::string reason;          // for the user, when not MARKED
  std::vector<TargetMark> photos;  // every photo it was predicted in
  // The target found, in ENU metres through the GPS georeferencing, minus the
  // surveyed position (the GPS's common offset is in it).
  Eigen::Vector3d offset_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d target_model = Eigen::Vector3d::Zero();  // in the model's frame
  bool Marked() const { return status == "MARKED" || status == "SINGLE_PHOTO"; }
};

struct MarkingResult {
  std::vector<PointMarking> points;  // control, then checks, in file order
  GcpFile control_marks, check_marks;  // the marked points, gcp_list.txt format
  // "gps": the model placed by the photos' GPS; "targets": by the targets
  // found in the photos, with the coordinate list placed on them.
  std::string method;
  Similarity model_to_enu;
  double search_radius_m = 0.0;
  int gps_photos = 0;
  // method "targets": targets found in 3 photos or more, surveyed points
  // placed on one, and the placement's RMS (metres).
  int targets_found = 0;
  int placed_points = 0;
  double placement_rms_m = 0.0;
};

// A coordinate list placed on targets found in the photos (photos without
// GPS): the similarity from the model's frame to ENU under which the most
// surveyed points sit on a target (within 0.5 m), found from the 40 widest
// triangles of surveyed points against every triangle of targets whose sides
// have the same ratios (within 5 %), each refitted on every point it
// places. None, and *why says why, when there are fewer than 3 of either,
// no triangle is alike, or the layout is ambiguous: another assignment of
// two or more points to targets fits as many points about as well (within
// 3 times the RMS and 5 cm; a symmetric layout, which GPS or a hand mark
// settles).
struct ListPlacement {
  Similarity model_to_enu;
  int placed = 0;  // surveyed points on a target
  double rms_m = 0.0;
};
std::optional<ListPlacement> PlaceListOnTargets(const std::vector<Eigen::Vector3d>& targets_in_model,
                                                const std::vector<Eigen::Vector3d>& surveyed_in_enu,
                                                std::string* why);

// model: registered photos with full-resolution cameras; gps by photo name;
// enu_origin: the frame GPS and control are compared in (any point near the
// survey when the photos have no GPS).
//
// With GPS in 3 photos or more, the model is placed by it. Without, it is
// placed from the photos alone: every target in every photo, joined into
// targets seen by 3 photos or more (triangulated within max_reprojection_px),
// and the coordinate list placed on them by the similarity under which the
// most surveyed points sit on a target (within 0.5 m; found from triangles of
// surveyed points against triangles of targets with the same side ratios).
// A list that cannot be placed (fewer than 3 targets, no triangle alike, or
// a symmetric layout that fits two ways) leaves every point UNPLACED, with
// the reason. Once placed, each point is marked as with GPS, its search
// radius 4 times the placement's RMS (at least 0.5 m).
MarkingResult MarkControl(const SparseModel& model, const std::filesystem::path& images_dir,
                          const std::map<std::string, GpsFix>& gps, const Geodetic& enu_origin, const GcpFile& control,
                          const GcpFile* checks, const MarkingOptions& options);

}  // namespace aerotri
