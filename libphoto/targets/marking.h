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
//                   target, or two coordinates for one).
// A point seen in one photo only is marked when one target is found there
// (SINGLE_PHOTO: nothing confirms it).

#include <filesystem>
#include <map>
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
  Similarity model_to_enu;
  double search_radius_m = 0.0;
  int gps_photos = 0;
};

// model: registered photos with full-resolution cameras; gps by photo name
// (at least 3 of the model's photos); enu_origin: the frame GPS and
// control are compared in. Throws UsageError when the photos have no GPS
// (the correspondence from the photos alone is not built).
MarkingResult MarkControl(const SparseModel& model, const std::filesystem::path& images_dir,
                          const std::map<std::string, GpsFix>& gps, const Geodetic& enu_origin, const GcpFile& control,
                          const GcpFile* checks, const MarkingOptions& options);

}  // namespace aerotri
