// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Writes a synthetic survey to disk as a surveyor would receive it, plus its
// truth:
//   images/IMG_*.JPG     rendered photos, EXIF GPS (noisy), focal length
//   gcp_list.txt         control points (output CRS, survey noise), target
//                        centres as measured in the images (OpenDroneMap
//                        convention: integers at pixel centres)
//   checkpoints.txt      check points, same format
//   gcp_coordinates.txt, check_coordinates.txt   the same points, coordinates
//                        only (what the GNSS rover gives: aerotri mark)
//   gps.csv              the same noisy GPS as the EXIF (name,lat,lon,alt)
//   geo.txt              the same again as OpenDroneMap's geo.txt (output
//                        CRS, EGM96 altitudes for a 2D CRS, accuracies)
//   measurements.txt     the model's tie points as image measurements
//                        (image point im_x im_y: aerotri adjust --measurements)
//   camera.txt           the true camera as a calibration certificate (px)
//   model/               the tie-point model in an arbitrary frame and scale
//                        (COLMAP text), as another tool would export it
//   truth/model/         exact cameras and points in ENU (COLMAP text)
//   truth/dem.tif        the terrain in the output CRS (GeoTIFF)
//   truth/ortho.tif      the ground's true colours (targets, roofs) in the
//                        output CRS at the GSD: what a true orthomosaic should be
//   truth/dsm.tif        with buildings: the terrain and the roofs
//   truth/marks.txt      every target's exact centre in every photo (control
//                        and checks, gcp_list.txt format)
//   truth/truth.json     origin, CRS, camera, GSD, noise levels
// GPS altitudes (EXIF and CSV) are EGM96 heights, as EXIF "above sea level".

#include <filesystem>
#include <string>

#include "libphoto/base/progress.h"
#include "libphoto/simulate/render.h"
#include "libphoto/simulate/synthetic_georef.h"

namespace aerotri {

struct SimulationOptions {
  SyntheticSurveyOptions survey;
  SyntheticGeorefOptions georef;
  bool render_images = true;
  int jpeg_quality = 88;
  double click_noise_px = 0.3;   // GCP measurement noise in the files
  double dem_resolution_m = 0.5;
  double truth_ortho_resolution_m = 0.0;  // 0: the GSD rounded to the millimetre
  // Flat-roofed box buildings (6-14 m wide, 4-8 m high) placed at random
  // away from the control and check targets; truth/dem.tif stays the bare
  // terrain, truth/dsm.tif adds the roofs, truth.json lists them.
  int num_buildings = 0;
  GroundCover ground_cover = GroundCover::kMixed;
  TargetPattern target_pattern = TargetPattern::kChecker;  // of every control and check target
  double sensor_width_mm = 6.4;  // for EXIF focal length in mm
  // DJI XMP gimbal angles in each JPEG (drone-dji:GimbalPitchDegree,
  // GimbalYawDegree, GimbalRollDegree): the true attitude with Gaussian
  // noise of gimbal_noise_deg on each angle.
  bool write_gimbal_xmp = false;
  double gimbal_noise_deg = 0.5;
  ProgressCallback progress;
};

void WriteSyntheticSurvey(const SimulationOptions& options, const std::filesystem::path& dir);

}  // namespace aerotri
