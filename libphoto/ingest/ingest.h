// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The ingest stage as a module: a folder of photos in, a typed record out
// (images with their EXIF facts and GPS fix, camera groups with their initial
// intrinsics, warnings). The pipeline only decides whether to run it and
// where the record goes (WS/ingest.json, ToJson / IngestRecordFromJson).
//
// Policies decided here, once:
//  - GPS source: a CSV row overrides EXIF; EXIF GPS at (0, 0) is no fix;
//    EXIF altitudes are read in options.gps_altitude.
//  - Stated GPS sigmas replace the default ones where a photo states them
//    (GpsSigmasStatedBy): DJI's RTK standard deviations (sigma_h =
//    hypot(lat, lon) / sqrt 2), else the GPS accuracies of Pix4D's camera
//    tags (Parrot); floored at 5 mm.
//  - Camera groups: one physical camera (make, model, focal mm) and one
//    working image size. A photo that says nothing of its camera joins the
//    group of its size when there is exactly one, with a warning.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera_models/camera.h"
#include "georef/gps_fix.h"
#include "libphoto/base/progress.h"

namespace aerotri {

struct IngestOptions {
  std::filesystem::path images_dir;
  AltitudeReference gps_altitude = AltitudeReference::kEgm96;
  double gps_sigma_h_m = kDefaultGpsSigmaH;  // when neither RTK tags nor the CSV give one
  double gps_sigma_v_m = kDefaultGpsSigmaV;
  std::filesystem::path gps_csv;             // optional, overrides EXIF
  int max_dimension = 1600;                  // working resolution (longer side, px; 0: full)

  // Throws InvalidArgument naming the option and the value.
  void Check() const;
};

struct IngestedImage {
  std::string name;
  bool usable = false;
  std::string problem;  // why not usable
  int width = 0, height = 0;                  // px, as stored
  int working_width = 0, working_height = 0;  // px, features and matching
  double scale = 1.0;                         // full px per working px
  std::string make, model;
  std::optional<double> focal_mm, relative_altitude_m, gimbal_pitch_deg, gimbal_yaw_deg;
  std::optional<double> capture_time_s;  // EXIF DateTimeOriginal (ExifDateTimeSeconds)
  std::optional<GpsFix> gps;
  int group = -1;
  // What the camera says about itself beyond position and gimbal (XMP),
  // tag by tag with the vendor named (image_metadata.h); for ingest.json.
  nlohmann::json camera_says = nlohmann::json::object();
};

struct CameraGroup {
  std::string key, make, model;
  int working_width = 0, working_height = 0;
  Camera camera;            // initial intrinsics, working px (BROWN)
  std::string focal_source;  // for people
  bool focal_measured = false;  // EXIF measured f (a prior to hold), not a guess
  // The initial intrinsics are the camera's own factory calibration
  // (CalibrationStatedBy, the group's first photo; focal_source names it).
  bool calibration_stated = false;
  // Pixel pitch at the working resolution (mm), where EXIF gives it; 0:
  // unknown. The report states the calibration in mm with it.
  double pixel_size_mm = 0.0;
  int images = 0;
};

struct IngestRecord {
  // 2: typed record, focal_measured per group. 1 (before): focal_source only.
  static constexpr int kSchemaVersion = 2;
  std::filesystem::path images_dir;  // absolute
  int working_max_dimension = 0;
  std::vector<IngestedImage> images;
  std::vector<CameraGroup> groups;
  std::vector<std::string> warnings;
  int images_with_gps = 0;
  nlohmann::json options;  // the fingerprint of the options and inputs behind it
};

// Reads every photo of options.images_dir (after options.Check()). Throws
// IoError / InvalidArgument for a missing folder, no photos, a bad CSV;
// unreadable photos are recorded unusable with the reason.
IngestRecord IngestSurveyImages(const IngestOptions& options, const ProgressCallback& progress);

nlohmann::json ToJson(const IngestRecord& record);
// Throws ParseError naming `path` and the field when the document is not an
// ingest record of a known schema version.
IngestRecord IngestRecordFromJson(const nlohmann::json& doc, const std::string& path);

}  // namespace aerotri
