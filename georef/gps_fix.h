// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A GNSS position of a camera centre, as the adjustment uses it: WGS84
// geodetic coordinates with ellipsoidal height and its standard deviations.
// Where such fixes come from (EXIF, XMP, a CSV) is the ingest library's
// business; what they mean is geodesy, so the type lives here, below both
// ingest and the adjuster.
//
// EXIF GPS altitude's reference differs by vendor: the EXIF standard says
// "above sea level", which DJI and most cameras write as EGM96-like heights;
// some RTK workflows write ellipsoidal heights. The reference is therefore an
// explicit choice; EGM96 heights become ellipsoidal through PROJ's
// egm96_15.gtx (h = H + N).

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>

#include "georef/local_frame.h"

namespace aerotri {

enum class AltitudeReference { kEgm96, kEllipsoid };

// Default a-priori sigmas of a consumer (non-RTK) GNSS fix, metres. One
// definition for every entry point (ingest, `adjust --gps-csv`, run).
inline constexpr double kDefaultGpsSigmaH = 3.0;
inline constexpr double kDefaultGpsSigmaV = 5.0;

// A GPS position of a camera centre: WGS84 latitude, longitude and
// ellipsoidal height, with its standard deviations (m).
struct GpsFix {
  Geodetic position;
  double sigma_h_m = kDefaultGpsSigmaH;
  double sigma_v_m = kDefaultGpsSigmaV;
  std::string source;  // "exif", "exif+rtk", "csv"
  // Capture time (seconds on the camera's clock, any epoch; only differences
  // are used: the GNSS drift model, flights split at long gaps). NaN: unknown.
  double time_s = std::numeric_limits<double>::quiet_NaN();
  // A camera position surveyed in a local engineering frame (a geo.txt whose
  // CRS line is LOCAL): its coordinates in the file's unit. position then
  // holds them on the frame's stand-in (Crs::IsLocal), good for distances
  // only; the adjustment places them in the control's local frame, and
  // refuses them beside geodetic control.
  std::optional<Eigen::Vector3d> local_xyz;
  double local_unit_m = 1.0;
};

// Converts an altitude in the given reference to WGS84 ellipsoidal height.
double EllipsoidalHeight(double lat_deg, double lon_deg, double altitude_m,
                         AltitudeReference reference);

}  // namespace aerotri
