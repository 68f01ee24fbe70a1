// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Vector deliverables through OGR (GeoPackage).
//
// Contour lines of an elevation model, written as a GeoPackage through GDAL
// (GDALContourGenerateEx, OGR): one layer "contours" of line strings with
// the CRS set, an `elevation` attribute (metres) and `index` (1 on every
// index_every-th contour, the labelled heavier lines of a map).
//
// A photogrammetric model carries a ripple of a few centimetres that turns
// 1 m contours into thousands of fragments; the surface is first smoothed
// by a Gaussian whose width follows the interval (smoothing_sigma_m, by
// default the larger of three cells and twice the interval), nodata-aware
// (normalised convolution: no cell is pulled towards nodata), and lines
// shorter than min_length_m are dropped.

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "libphoto/export/raster.h"

namespace aerotri {

struct ContourOptions {
  double interval_m = 0.0;         // 0: a round number near a twentieth of the relief
  int index_every = 5;
  double smoothing_sigma_m = -1.0;  // < 0: automatic (see above); 0: none
  double min_length_m = -1.0;       // < 0: four times the smoothing width
};

struct ContourSummary {
  double interval_m = 0.0;
  double smoothing_sigma_m = 0.0;
  long long lines = 0;
  long long dropped_short = 0;
};

// The interval ContourOptions{} would choose for the raster.
double AutomaticContourInterval(const Raster& surface);

void WriteContours(const Raster& surface, const std::filesystem::path& path, const ContourOptions& options,
                   ContourSummary* summary = nullptr);

// A GeoPackage layer of 3D points (e.g. camera centres) with text and number
// attributes, the CRS set and a description (gpkg_contents), atomically. A
// NaN number is written as null.
struct GpkgPoint {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::vector<std::string> text;
  std::vector<double> numbers;
};
void WritePointsGpkg(const std::filesystem::path& path, const std::string& layer, const std::string& wkt,
                     const std::string& description, const std::vector<std::string>& text_fields,
                     const std::vector<std::string>& number_fields, const std::vector<GpkgPoint>& points);

}  // namespace aerotri
