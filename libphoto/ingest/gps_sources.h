// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Where camera GPS positions come from: the images' EXIF, or a CSV of
// positions and sigmas that overrides EXIF.
//
// EXIF GPS altitude's reference differs by vendor: the EXIF standard says
// "above sea level", which DJI and most cameras write as EGM96-like heights;
// some RTK workflows write ellipsoidal heights. The reference is therefore an
// explicit choice; EGM96 heights become ellipsoidal through PROJ's
// egm96_15.gtx (h = H + N).
//
// CSV: one line per image, `name,lat,lon,alt[,sigma_h,sigma_v]` (degrees,
// metres; commas, semicolons, tabs or spaces separate fields). '#' starts a
// comment; a first line starting with a non-numeric second field is a header.

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "georef/local_frame.h"

namespace aerotri {

enum class AltitudeReference { kEgm96, kEllipsoid };

// A GPS position of a camera centre: WGS84 latitude, longitude and
// ellipsoidal height, with its standard deviations (m).
struct GpsFix {
  Geodetic position;
  double sigma_h_m = 2.0;
  double sigma_v_m = 4.0;
  std::string source;  // "exif", "exif+rtk", "csv"
};

// Converts an altitude in the given reference to WGS84 ellipsoidal height.
double EllipsoidalHeight(double lat_deg, double lon_deg, double altitude_m,
                         AltitudeReference reference);

// Reads the EXIF GPS of each named image in images_dir. Images without GPS,
// missing or unreadable files are listed in *warnings, not fatal. DJI RTK
// standard deviations (XMP) replace the default sigmas when present.
std::map<std::string, GpsFix> GpsFromImages(const std::vector<std::string>& image_names,
                                            const std::filesystem::path& images_dir,
                                            AltitudeReference reference, double sigma_h_m,
                                            double sigma_v_m, std::vector<std::string>* warnings);

// Throws ParseError (file:line: expected ..., got ...) or IoError.
std::map<std::string, GpsFix> ReadGpsCsv(const std::filesystem::path& path,
                                         AltitudeReference reference, double sigma_h_m,
                                         double sigma_v_m);

}  // namespace aerotri
