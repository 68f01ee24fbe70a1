// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// JPEG output with EXIF, through GDAL's JPEG driver (which writes EXIF_*
// metadata items into an EXIF segment, GPS included). Atomic: written to a
// temporary name, then renamed.

#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <string>

namespace aerotri {

// image: 8-bit BGR (OpenCV order) or grey. exif: GDAL item names
// ("EXIF_GPSLatitude" = "(46) (30) (12.5)", ...). quality in [1, 100].
void WriteJpegWithExif(const std::filesystem::path& path, const cv::Mat& image,
                       const std::map<std::string, std::string>& exif, int quality = 90);

// EXIF rational triple for degrees: "(46) (30) (12.3456)".
std::string ExifDms(double degrees);

}  // namespace aerotri
