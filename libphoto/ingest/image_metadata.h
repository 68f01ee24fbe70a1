// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What an image file tells about its capture, read through GDAL's JPEG (and
// TIFF) drivers: EXIF (GPS, focal length, make / model, sizes) and, where
// present, what the camera says about itself in XMP:
//  - DJI (drone-dji namespace, as DJI's image processing guides and
//    ExifTool's DJI table name the tags): relative altitude, gimbal and
//    flight attitudes, flight speeds, RTK standard deviations, the factory
//    calibration (CalibratedFocalLength, CalibratedOpticalCenterX/Y, px);
//  - Parrot Sequoia / Anafi and other writers of Pix4D's camera XMP tags
//    (namespace http://pix4d.com/camera/1.0/, prefix Camera; Pix4D's
//    "Camera XMP tags" specification): the camera's attitude from its IMU,
//    GPS accuracies, the IMU's linear velocity, the rolling shutter's
//    readout time, the factory calibration.
// Nothing is invented: a missing tag stays std::nullopt and the caller says
// what it assumed instead.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

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
  std::optional<double> flight_pitch_deg, flight_roll_deg, flight_yaw_deg;  // the aircraft's attitude
  std::optional<double> flight_speed_x_mps, flight_speed_y_mps, flight_speed_z_mps;
  std::optional<double> calibrated_focal_px, calibrated_cx_px, calibrated_cy_px;

  // Pix4D camera XMP (Parrot). Attitude of the camera in degrees: yaw
  // clockwise from north, pitch and roll 0 for a camera looking straight
  // down.
  std::optional<double> camera_yaw_deg, camera_pitch_deg, camera_roll_deg;
  std::optional<double> gps_xy_accuracy_m, gps_z_accuracy_m;  // the receiver's stated accuracy
  std::optional<double> line_readout_time_s;  // LineReadoutTime (written in microseconds)
  std::vector<double> imu_linear_velocity_mps;  // IMULinearVelocity: 3 values, m/s
  std::optional<double> perspective_focal_mm;  // PerspectiveFocalLength
  std::vector<double> principal_point_mm;      // PrincipalPoint: x, y
  std::vector<double> perspective_distortion;  // PerspectiveDistortion: k1, k2, k3, p1, p2

  bool HasGps() const { return lat_deg && lon_deg; }
  // Vendors whose XMP the photo carries ("DJI", "Parrot / Pix4D camera tags"); empty: none read.
  std::vector<std::string> xmp_sources;
};

// The GPS sigmas the photo states (DJI RTK standard deviations, else the
// Pix4D camera tags' GPS accuracies), floored at 5 mm, with their source
// ("exif+rtk", "exif+accuracy"); nullopt when it states none.
struct StatedGpsSigmas {
  double h_m = 0, v_m = 0;
  std::string source;
};
std::optional<StatedGpsSigmas> GpsSigmasStatedBy(const ImageMetadata& m);

// The rolling shutter a photo states: the camera's velocity east and north
// and the readout time. nullopt unless the photo states its velocity:
// - Pix4D camera tags (Parrot): the first two values of IMULinearVelocity,
//   east and north, as the tracks of Parrot Sequoia photos' GPS positions
//   show them (no published description fixes the axes; the third value's
//   sign is not established either, and is left out: under 1 m/s, it moves
//   a camera by under 5 cm in a 50 ms readout); the readout from
//   LineReadoutTime;
// - DJI: FlightXSpeed and FlightYSpeed, north and east, read as DJI's Mobile
//   SDK defines the aircraft's velocity (x north, y east, z down; DJI
//   publishes no description of the XMP tags themselves); the vertical
//   speed left out as above. A hovering capture states zero.
// Without a stated readout, the known-camera table's (readout_table.h);
// else 0 (--rolling-shutter estimate can still find it). `source` says
// where the velocity and the readout come from.
struct StatedRollingShutter {
  double readout_time_s = 0.0;  // 0: not known
  double east_mps = 0.0, north_mps = 0.0;
  std::string source;
};
std::optional<StatedRollingShutter> RollingShutterStatedBy(const ImageMetadata& m);

// The factory calibration a photo states, in the stored image's pixels
// (aerotri's convention: 0 is the centre of the first pixel):
// - Pix4D camera tags (Parrot Sequoia, Anafi): PerspectiveFocalLength and
//   PrincipalPoint in mm from the sensor's top-left corner, divided by the
//   pixel pitch (pixel_size_mm, from EXIF's focal-plane resolution; without
//   it nothing is stated), and PerspectiveDistortion's R1, R2, R3, T1, T2
//   as Brown's k1, k2, k3, p1, p2 (Pix4D's perspective model is Brown's on
//   normalised coordinates);
// - DJI: CalibratedFocalLength and CalibratedOpticalCenterX / Y, in pixels
//   from the image's corner (no distortion: DewarpData is not read).
// nullopt when the photo states no focal length this way.
struct StatedCalibration {
  double focal_px = 0.0, cx_px = 0.0, cy_px = 0.0;
  std::vector<double> distortion;  // k1, k2, k3, p1, p2; empty: not stated
  std::string source;              // the tags, for people
};
std::optional<StatedCalibration> CalibrationStatedBy(const ImageMetadata& m, double pixel_size_mm);

// Throws IoError naming the path when GDAL cannot open the file as an image
// (missing, corrupt, not an image).
ImageMetadata ReadImageMetadata(const std::filesystem::path& path);

// "YYYY:MM:DD HH:MM:SS" (EXIF) and optional sub-second digits as seconds
// since 1970-01-01 on the same clock; nullopt when malformed or blank.
std::optional<double> ExifDateTimeSeconds(const std::string& datetime, const std::string& subsec = "");

// True for names aerotri treats as photos (.jpg, .jpeg, .tif, .tiff, any case).
bool IsImageFileName(const std::filesystem::path& path);

}  // namespace aerotri
