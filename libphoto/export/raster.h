// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Single-band float rasters (elevation models) written through GDAL as
// GeoTIFF or Cloud-Optimised GeoTIFF, with CRS, geotransform and nodata set;
// atomically (temporary name, then rename).
//
// Geotransform: GDAL's (x0, dx, 0, y0, 0, -dy): (x0, y0) is the outer corner
// of the top-left pixel (GDAL's "area" convention), rows run south.

#include <array>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace aerotri {

struct Raster {
  int width = 0;
  int height = 0;
  std::array<double, 6> geotransform{{0, 1, 0, 0, 0, -1}};
  std::string wkt;  // CRS
  double nodata = -9999.0;
  std::vector<float> values;  // row-major, height x width

  float& at(int x, int y) { return values[static_cast<size_t>(y) * width + x]; }
  float at(int x, int y) const { return values[static_cast<size_t>(y) * width + x]; }
  // Centre of pixel (x, y) in CRS units.
  double X(double px) const { return geotransform[0] + (px + 0.5) * geotransform[1]; }
  double Y(double py) const { return geotransform[3] + (py + 0.5) * geotransform[5]; }
};

struct RasterWriteOptions {
  bool cog = false;       // Cloud-Optimised GeoTIFF (COG driver)
  bool overviews = true;  // internal overviews (always with COG)
  std::string compress = "DEFLATE";
  // Dataset metadata items (GDAL_METADATA; gdalinfo lists them).
  std::map<std::string, std::string> metadata;
};

void WriteRaster(const Raster& raster, const std::filesystem::path& path,
                 const RasterWriteOptions& options = {});
Raster ReadRaster(const std::filesystem::path& path);

}  // namespace aerotri
