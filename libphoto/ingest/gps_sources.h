// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Where camera GPS positions come from: the images' EXIF, or a CSV of
// positions and sigmas that overrides EXIF.
//
// CSV: one line per image, `name,lat,lon,alt[,sigma_h,sigma_v]` (degrees,
// metres; commas, semicolons, tabs or spaces separate fields). '#' starts a
// comment; a first line starting with a non-numeric second field is a header.

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "georef/gps_fix.h"

namespace aerotri {

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
