// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Orthomosaic: the adjusted photos projected through an elevation model
// onto the output CRS's grid, one view per ground cell, blended across seams.
//
//   1. Views. Each ground cell (x, y, surface z) is projected into every
//      photo (a rolling-shutter photo's, Image::rolling_shutter, from the
//      camera where it was when the cell's row was read); a photo sees it
//      when it falls inside the frame and is not hidden: a z-buffer of the
//      surface rendered into each photo (a quarter of its resolution) tests
//      occlusion. Among the photos that see it, the best is the closest to
//      nadir (cosine of the ray's angle from the vertical), slightly weighted
//      by the photo's sharpness (variance of the Laplacian against the
//      survey's median).
//   2. Seams, on a coarse grid (seam_cell_factor cells), for the whole area
//      at once: the best-view partition is widened by a band of
//      seam_band_cells, and OpenCV's graph-cut seam finder (colour and
//      gradient cost) moves each boundary inside that band to where the two
//      views agree. Exposure: OpenCV's per-channel gain compensator over the
//      views' overlaps.
//   3. Tiles (tile_size, with a margin for the blender), on all cores: each
//      cell takes the view of its coarse cell (or, where that view cannot
//      see it, the best one that can); the views are resampled (bilinear)
//      and blended by OpenCV's multi-band blender, so no seam leaves an
//      exposure step. Memory is bounded by the tile and a cache of decoded
//      photos.
//   4. The RGB + alpha GeoTIFF is written through GDAL tile by tile, then
//      made a Cloud-Optimised GeoTIFF (JPEG: the alpha becomes a mask band;
//      DEFLATE keeps it as a fourth band) with overviews.

#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "libphoto/base/progress.h"
#include "libphoto/export/raster.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct OrthoOptions {
  double resolution_m = 0.0;  // ground cell (CRS units); required
  int tile_size = 512;
  int tile_margin = 48;        // cells around a tile that the blender sees
  int blend_bands = 5;         // multi-band blender's pyramid depth
  int seam_cell_factor = 4;    // coarse seam grid, in ortho cells
  int seam_band_cells = 6;     // how far (coarse cells) a seam may move
  bool exposure_compensation = true;
  // Holes in the surface (no dense points: water, tree canopy, shadow) are
  // filled by GDAL's inverse-distance interpolation for drawing, so the
  // photos still cover them (positions there are only as good as the fill).
  bool fill_surface_holes = true;
  bool cog = true;
  std::string compress = "JPEG";  // JPEG or DEFLATE
  int jpeg_quality = 90;
  int num_threads = 0;
  std::size_t image_cache_bytes = std::size_t{768} << 20;
  std::filesystem::path work_dir;  // for the intermediate GeoTIFF; empty: beside the output
  std::map<std::string, std::string> metadata;  // GeoTIFF metadata items
  // A share of the drawing, for a workflow that runs it as separate jobs
  // (aerotri split): the share_index-th (from 0) of share_count runs of tile
  // rows. Views, seams and exposure are the whole survey's (every share
  // computes them alike), so the bands join without a seam; the share writes
  // its band to the path as a plain tiled GeoTIFF (RGBA, DEFLATE), nothing
  // when its run is empty (summary.band_height 0). AssembleOrthomosaic makes
  // the deliverable of the bands.
  int share_index = 0;
  int share_count = 1;
};

struct OrthoSummary {
  int width = 0, height = 0;
  int tiles = 0;
  int images_used = 0;             // photos that colour at least one cell
  double filled_fraction = 0.0;    // of the cells where the surface has data of its own
  long long cells_with_surface = 0;
  long long cells_filled = 0;
  long long surface_cells_interpolated = 0;  // holes of the surface filled for drawing
  std::vector<int> images;         // the photos (model image indices) that colour a cell
  int band_y = 0, band_height = 0;  // a share's band: rows of the whole grid
};

// CRS (x, y, z) to the model's world frame. The factory is called once per
// thread (PROJ objects are not shared across threads).
using CrsToWorld = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;
using CrsToWorldFactory = std::function<CrsToWorld()>;

// model: registered images, cameras in the pixels of the images that
// load_image returns (BGR, 8-bit). surface: DSM or DTM in the output CRS,
// whose WKT the ortho takes. Throws InvalidArgument for a bad option or an
// empty surface, IoError when GDAL cannot write.
void WriteOrthomosaic(const SparseModel& model, const std::function<cv::Mat(int image)>& load_image,
                      const Raster& surface, const CrsToWorldFactory& to_world, const OrthoOptions& options,
                      const std::filesystem::path& path, const ProgressCallback& progress = nullptr,
                      OrthoSummary* summary = nullptr);

// The deliverable (options.cog, compress, jpeg_quality) from the bands the
// shares of one orthomosaic wrote (empty ones left out), in any order:
// the file WriteOrthomosaic writes in one call, cell for cell.
void AssembleOrthomosaic(const std::vector<std::filesystem::path>& bands, const OrthoOptions& options,
                         const std::filesystem::path& path);

}  // namespace aerotri
