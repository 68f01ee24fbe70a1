// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A synthetic survey placed at a real geodetic location, with what a
// surveyor would bring to it: noisy GPS positions of the camera centres, a
// control-point file and a check-point file in a projected CRS (with survey
// noise), and the tie-point model alone (what a reconstruction would give).

#include <map>

#include "georef/gcp_file.h"
#include "georef/gps_fix.h"
#include "libphoto/simulate/synthetic_survey.h"

namespace aerotri {

struct SyntheticGeorefOptions {
  Geodetic origin{46.5, 7.5, 500.0};  // ENU origin of the truth (WGS84)
  std::string crs = "EPSG:32632";     // of the control files
  double gps_sigma_h_m = 2.0;         // noise added to, and sigma of, GPS
  double gps_sigma_v_m = 4.0;
  double gcp_noise_m = 0.01;          // survey noise of control / check points
  // Capture times: one photo every seconds_per_photo in flight order, from
  // start_time_s (2026-06-01 10:00:00 on the camera's clock).
  double seconds_per_photo = 2.0;
  double start_time_s = 1780308000.0;
  // A GNSS / barometric drift of the GPS positions, growing linearly in time
  // from zero at the first photo to gps_drift_m (E, N, U) at the last (a
  // consumer drone's altitude climbing by tens of metres over a flight).
  Eigen::Vector3d gps_drift_m = Eigen::Vector3d::Zero();
  std::uint32_t seed = 1;
};

struct SyntheticGeoref {
  SyntheticSurvey survey;               // truth in ENU of options.origin
  std::map<std::string, GpsFix> gps;    // by image name
  GcpFile control;                      // measurements: noisy observations
  GcpFile checks;
  SparseModel tie_model;                // observed, tie points only
};

SyntheticGeoref MakeSyntheticGeoref(const SyntheticSurveyOptions& survey_options,
                                    const SyntheticGeorefOptions& options);

}  // namespace aerotri
