// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Initial focal length in pixels from what an image's EXIF says, in order of
// trust:
//  1. focal length (mm) x focal-plane resolution (px/mm), scaled by the
//     stored width over EXIF's pixel width (photos are often resized);
//  2. focal length (mm) over the sensor width of a known camera model
//     (a small table of common drone cameras), times the longer image side;
//  3. the 35 mm equivalent focal length over 36 mm, times the longer side;
//  4. nothing known: 0.85 x the longer side (a typical drone wide angle).
// The source is reported so that a surveyor knows what was assumed; the
// adjustment refines the value anyway.

#include <optional>
#include <string>

namespace aerotri {

struct ExifOptics {
  std::string make;
  std::string model;
  std::optional<double> focal_mm;
  std::optional<double> focal_35mm;
  std::optional<double> focal_plane_px_per_mm;
  std::optional<int> exif_pixel_width;
  int width = 0;   // px, of the stored image
  int height = 0;
};

// Which of the four rules gave the value. The first two measure the focal
// length (a prior worth holding the adjustment to); the last two only guess.
enum class FocalBasis { kFocalPlane, kSensorTable, kEquivalent35mm, kGuess };

struct FocalEstimate {
  double focal_px = 0.0;  // for the stored image size
  FocalBasis basis = FocalBasis::kGuess;
  std::string source;     // for people: the rule and its EXIF values
  // The pixel pitch at the stored image size (mm) where EXIF states it (the
  // focal-plane resolution) or the sensor is known; 0 otherwise (a 35 mm
  // equivalent says nothing physical about the sensor).
  double pixel_size_mm = 0.0;
  bool Measured() const { return basis == FocalBasis::kFocalPlane || basis == FocalBasis::kSensorTable; }
};

FocalEstimate FocalFromExif(const ExifOptics& optics);

// Sensor width (mm) of a known camera model, e.g. DJI "FC300S" -> 6.17.
std::optional<double> KnownSensorWidthMm(const std::string& make, const std::string& model);

}  // namespace aerotri
