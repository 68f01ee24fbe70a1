// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Where camera GPS positions come from: the images' EXIF, or a file of
// positions and sigmas that overrides EXIF, in either of two formats:
//
// CSV: one line per image, `name,lat,lon,alt[,sigma_h,sigma_v]` (degrees,
// metres; commas, semicolons, tabs or spaces separate fields). '#' starts a
// comment; a first line starting with a non-numeric second field is a header.
//
// OpenDroneMap's geo.txt: a first line naming the CRS (EPSG:4326, a PROJ
// string, a WKT or "WGS84 UTM 16N"), then `image_name geo_x geo_y geo_z
// [yaw pitch roll] [horz_accuracy vert_accuracy] [extras...]` (geographic
// CRSs: x is the longitude). Angles are read and not used; accuracies (m)
// become the fix's sigmas. geo_z is ellipsoidal when the CRS has a vertical
// datum (e.g. EPSG:32616+5773 gives EGM96 heights converted by PROJ), else an
// altitude in the given reference, as EXIF altitudes are.
//
// Either way a UTF-8 byte-order mark and any line ending are accepted.

#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "georef/crs.h"
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
std::map<std::string, GpsFix> ReadGpsFile(const std::filesystem::path& path, AltitudeReference reference,
                                          double sigma_h_m, double sigma_v_m);

// ReadGpsFile's work on the text in memory (path names it in errors), with
// CRS resolution kept apart from tokenising: `resolve` is asked for a
// geo.txt's first line only when that line can be a CRS (no field
// separators, no number in second place) and answers the CRS, or nothing
// when it is not one (the file is then read as a CSV). ReadGpsFile resolves
// through PROJ (Crs::FromString); the fuzz target through a fixed table, so
// that the parsing is fuzzed at full speed rather than PROJ's name lookup.
using CrsResolver = std::function<std::optional<Crs>(const std::string& definition)>;
std::map<std::string, GpsFix> ParseGpsText(std::string text, const std::string& path, AltitudeReference reference,
                                           double sigma_h_m, double sigma_v_m, const CrsResolver& resolve);

}  // namespace aerotri
