// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What an image file tells about its capture, read through GDAL's JPEG (and
// TIFF) drivers: EXIF (GPS, focal length, make / model, sizes) and, where
// present, DJI XMP tags (relative altitude, gimbal angles, RTK standard
// deviations). Nothing is invented: a missing tag stays std::nullopt and the
// caller says what it assumed instead.

#include <filesystem>
#include <optional>
#include <string>

namespace aerotri {

struct ImageMetadata {
  std::string path;
  int width = 0;   // px, of the file as stored
  int height = 0;  // px
  std::string make;
  std::string model;
  std::string datetime_original;
  // DateTimeOriginal (with SubSecTimeOriginal) in seconds since 1970-01-01
  // of the camera's clock, whose time zone EXIF does not say: for time
  // differences within a survey.
  std::optional<double> capture_time_s;

  // GPS (WGS84 latitude / longitude; altitude as written, its reference is
  // the caller's choice: EXIF says "above sea level", vendors differ).
  std::optional<double> lat_deg;
  std::optional<double> lon_deg;
  std::optional<double> gps_altitude_m;
  std::optional<double> gps_dop;

  // Optics.
  std::optional<double> focal_mm;
  std::optional<double> focal_35mm;
  // Focal-plane resolution in pixels per millimetre, for the width of
  // exif_pixel_width (sensors are often resized afterwards).
  std::optional<double> focal_plane_px_per_mm;
  std::optional<int> exif_pixel_width;

  // DJI XMP.
  std::optional<double> relative_altitude_m;
  std::optional<double> gimbal_pitch_deg;
  std::optional<double> gimbal_yaw_deg;
  std::optional<double> gimbal_roll_deg;
  std::optional<double> rtk_std_lat_m;
  std::optional<double> rtk_std_lon_m;
  std::optional<double> rtk_std_hgt_m;

  bool HasGps() const { return lat_deg && lon_deg; }
};

// Throws IoError naming the path when GDAL cannot open the file as an image
// (missing, corrupt, not an image).
ImageMetadata ReadImageMetadata(const std::filesystem::path& path);

// "YYYY:MM:DD HH:MM:SS" (EXIF) and optional sub-second digits as seconds
// since 1970-01-01 on the same clock; nullopt when malformed or blank.
std::optional<double> ExifDateTimeSeconds(const std::string& datetime, const std::string& subsec = "");

// True for names aerotri treats as photos (.jpg, .jpeg, .tif, .tiff, any case).
bool IsImageFileName(const std::filesystem::path& path);

}  // namespace aerotri
