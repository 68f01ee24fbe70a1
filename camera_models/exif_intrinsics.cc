// SPDX-License-Identifier: BSD-3-Clause
#include "camera_models/exif_intrinsics.h"

#include <algorithm>
#include <cctype>
#include <cstdio>

namespace aerotri {
namespace {

std::string Upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
  return s;
}

std::string Format(const char* fmt, double a, double b) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), fmt, a, b);
  return buf;
}

}  // namespace

std::optional<double> KnownSensorWidthMm(const std::string& make, const std::string& model) {
  // Manufacturer sensor widths (1/2.3" = 6.17 mm, 1" = 13.2 mm, 4/3 = 17.3 mm).
  static const std::pair<const char*, double> kTable[] = {
      {"FC300S", 6.17},  {"FC300X", 6.17},   {"FC300C", 6.17},  {"FC330", 6.17},
      {"FC220", 6.17},   {"FC2103", 6.17},   {"FC6310", 13.2},  {"FC6310S", 13.2},
      {"FC6310R", 13.2}, {"FC6510", 13.2},   {"FC6520", 17.3},  {"FC3170", 6.4},
      {"FC7203", 6.17},  {"FC3411", 13.2},   {"FC3582", 9.7},   {"L1D-20C", 13.2},
      {"FC7303", 6.4},   {"ZENMUSEP1", 35.9}, {"M3E", 17.3},    {"FC8482", 9.7},
  };
  const std::string m = Upper(model);
  for (const auto& [name, width] : kTable) {
    if (m == name) return width;
  }
  (void)make;
  return std::nullopt;
}

FocalEstimate FocalFromExif(const ExifOptics& o) {
  const int longer = std::max(o.width, o.height);
  FocalEstimate e;
  if (o.focal_mm && o.focal_plane_px_per_mm && *o.focal_mm > 0 && *o.focal_plane_px_per_mm > 0) {
    const double resize = (o.exif_pixel_width && *o.exif_pixel_width > 0)
                              ? static_cast<double>(o.width) / *o.exif_pixel_width
                              : 1.0;
    e.focal_px = *o.focal_mm * *o.focal_plane_px_per_mm * resize;
    e.pixel_size_mm = 1.0 / (*o.focal_plane_px_per_mm * resize);
    e.basis = FocalBasis::kFocalPlane;
    e.source = Format("EXIF focal length %.2f mm and focal-plane resolution (%.1f px/mm)",
                      *o.focal_mm, *o.focal_plane_px_per_mm);
    return e;
  }
  if (o.focal_mm && *o.focal_mm > 0) {
    if (const auto sensor = KnownSensorWidthMm(o.make, o.model)) {
      e.focal_px = *o.focal_mm / *sensor * longer;
      e.pixel_size_mm = *sensor / longer;
      e.basis = FocalBasis::kSensorTable;
      e.source = Format("EXIF focal length %.2f mm, known sensor width %.2f mm", *o.focal_mm, *sensor);
      return e;
    }
  }
  if (o.focal_35mm && *o.focal_35mm > 0) {
    e.focal_px = *o.focal_35mm / 36.0 * longer;
    e.basis = FocalBasis::kEquivalent35mm;
    e.source = Format("EXIF 35 mm equivalent focal length %.0f mm over a %.0f mm frame width",
                      *o.focal_35mm, 36.0);
    return e;
  }
  e.focal_px = 0.85 * longer;
  e.source = "no usable EXIF focal length: assumed 0.85 x the longer image side";
  return e;
}

}  // namespace aerotri
