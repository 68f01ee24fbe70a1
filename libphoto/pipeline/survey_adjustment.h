// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The one georeferencing entry point, shared by `aerotri run` (its
// georeference stage) and `aerotri adjust`: the control, check and camera
// files read and brought to the model's pixels, the adjustment
// (adjust/georeferencing.h) with the input problems first among its
// findings, and the camera products written beside the report.

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "georef/gcp_file.h"
#include "georef/gps_fix.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct SurveyAdjustmentInputs {
  std::map<std::string, GpsFix> gps;  // by image name
  std::filesystem::path gcp;          // optional control file
  std::filesystem::path checkpoints;  // optional check-point file
  PixelOrigin gcp_pixel_origin = PixelOrigin::kCentre;
  std::filesystem::path camera_file;  // optional calibration certificate
  // Full-resolution pixels per model pixel, by image name: control files and
  // certificates measure full-resolution pixels, the model may be at a
  // working resolution. Absent: 1.
  std::map<std::string, double> full_from_model;
  // Problems met reading the inputs (EXIF, GPS files): INPUT warnings, first
  // among the report's findings.
  std::vector<std::string> input_warnings;
  // Gimbal angles by image name (DJI XMP), to check the adjusted attitudes
  // against (GeoreferenceReport::gimbal, GIMBAL_ATTITUDE_DISAGREES) and to
  // give an oblique block its vertical (GeoreferenceOptions::gimbal).
  std::map<std::string, GimbalAttitude> gimbal;
};

// Reads the control and check files (their CRS checked before anything is
// adjusted) and the camera file, then georeferences and adjusts model in
// place (GeoreferenceAndAdjust), and compares the adjusted attitudes with
// the gimbal angles given: a block whose mean optical axis is more than 3°
// from the one its gimbals state is a warning, more than 10° an error (a tilted survey, e.g.
// from drifting GPS heights, looks right by every other figure). Not in a
// LOCAL frame, whose axes need not be east, north, up. Throws the inputs'
// own errors, naming file and line.
GeoreferenceReport AdjustSurvey(SparseModel* model, const SurveyAdjustmentInputs& inputs,
                                GeoreferenceOptions options);

// The adjusted cameras and tie points beside the report in folder:
// cameras.csv (positions in the output CRS, geodetic, GPS residuals),
// exterior_orientation.csv, cameras.gpkg and tie_points.csv. Each written
// atomically.
void WriteCameraProducts(const GeoreferenceReport& report, const SparseModel& model,
                         const std::filesystem::path& folder);

// tie_points.csv: every adjusted tie point (two or more images) in the
// output CRS with its id, name (from a measurement file), image count and
// posterior sigmas on the CRS's axes (report.axes) where computed.
void WriteTiePointsCsv(const GeoreferenceReport& report, const SparseModel& model,
                       const std::filesystem::path& path);

// cameras.gpkg: the adjusted camera centres as a GeoPackage point layer in
// the output CRS (GDAL and QGIS read its CRS), with omega / phi / kappa,
// their posterior sigmas and the GPS residuals; the description says what z is.
void WriteCamerasGpkg(const GeoreferenceReport& report, const std::filesystem::path& path);

}  // namespace aerotri
