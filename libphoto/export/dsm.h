// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <filesystem>

// Digital surface model from a point cloud in a projected output CRS: each
// cell takes the median height of the points that fall in it (robust to the
// odd stray point), holes are filled up to a distance with GDAL's inverse-
// distance FillNodata inside the data's outline only (the morphological
// closing of the cells with data: edges and lone points do not grow into
// discs), and the raster is written through GDAL (GeoTIFF with
// overviews, or a Cloud-Optimised GeoTIFF) with CRS, geotransform and nodata.

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "libphoto/export/raster.h"

namespace aerotri {

struct DsmOptions {
  double resolution_m = 0.1;       // cell size (CRS units)
  double fill_max_distance_m = 2.0;  // holes up to this far from data are filled; 0: none
  double nodata = -9999.0;
  // Folder for GDAL's fill-nodata work files (large rasters); empty: the
  // system's temporary folder. Never the current directory.
  std::filesystem::path work_dir;
};

struct DsmSummary {
  int width = 0, height = 0;
  long long cells_with_data = 0;
  long long cells_filled = 0;
};

Raster RasterizeDsm(const std::vector<Eigen::Vector3d>& xyz, const std::string& wkt,
                    const DsmOptions& options, DsmSummary* summary = nullptr);

// RasterizeDsm in steps, for a cloud read tile by tile (cloud_tiles.h):
// the grid over the cloud's bounds, every cell nodata;
Raster DsmGrid(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, const std::string& wkt,
               const DsmOptions& options);
// each cell whose centre `owns` accepts (null: every cell) set to the median
// height of the points `use` accepts (null: all) that fall in it, so a tile
// that brings every point of the cells it owns sets them as the whole cloud
// would; returns the cells set;
long long SetCellMedians(Raster* raster, const std::vector<Eigen::Vector3d>& xyz,
                         const std::function<bool(size_t)>& use,
                         const std::function<bool(const Eigen::Vector2d&)>& owns);
// then the holes filled, as RasterizeDsm fills them.
void FillDsmHoles(Raster* raster, const DsmOptions& options, DsmSummary* summary = nullptr);

// The raster's values with nodata cells up to max_distance_px from data
// filled by GDAL's inverse-distance FillNodata (work files in work_dir, or
// the system's temporary folder when empty); smoothing_iterations passes of
// GDAL's 3 x 3 smoothing over the filled cells soften its star-shaped
// artefacts across wide holes.
std::vector<float> FilledNodata(const Raster& raster, double max_distance_px,
                                const std::filesystem::path& work_dir = {}, int smoothing_iterations = 0);

// Bilinear height at (x, y) in the raster's CRS; std::nullopt outside the
// raster or next to nodata.
std::optional<double> SampleRaster(const Raster& raster, double x, double y);

}  // namespace aerotri
