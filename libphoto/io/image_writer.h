// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// JPEG output with EXIF, through GDAL's JPEG driver (which writes EXIF_*
// metadata items into an EXIF segment, GPS included). Atomic: written to a
// temporary name, then renamed.

#include <filesystem>

#include <Eigen/Core>
#include <map>
#include <opencv2/core.hpp>
#include <string>

namespace aerotri {

// image: 8-bit BGR (OpenCV order) or grey. exif: GDAL item names
// ("EXIF_GPSLatitude" = "(46) (30) (12.5)", ...). quality in [1, 100].
// xmp: an XMP packet (<x:xmpmeta ...>...</x:xmpmeta>) written as the
// standard APP1 segment after the EXIF one (GDAL's JPEG driver writes none;
// it reads it back into the xml:XMP domain); empty: none. At most 65,000
// bytes.
void WriteJpegWithExif(const std::filesystem::path& path, const cv::Mat& image,
                       const std::map<std::string, std::string>& exif, int quality = 90,
                       const std::string& xmp = "");

// An XMP packet with a DJI drone's gimbal angles (drone-dji:GimbalPitchDegree,
// GimbalYawDegree, GimbalRollDegree; degrees), as DJI cameras write them.
std::string DjiGimbalXmp(double pitch_deg, double yaw_deg, double roll_deg);

// An XMP packet with a rolling shutter's readout and the camera's velocity
// in Pix4D's camera tags, as Parrot's Sequoia writes them:
// Camera:LineReadoutTime in microseconds (an integer) and
// Camera:IMULinearVelocity "east,north,vertical" in m/s.
std::string RollingShutterXmp(double readout_time_s, const Eigen::Vector3d& velocity_enu_mps);

// EXIF rational triple for degrees: "(46) (30) (12.3456)".
std::string ExifDms(double degrees);

}  // namespace aerotri
