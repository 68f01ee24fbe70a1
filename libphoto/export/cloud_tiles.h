// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A point cloud too large to hold, and its products written tile by tile.
//
// A 1,000-photo survey fuses some 300 million points: 9 GB as doubles
// before any product is made of them. TiledCloud keeps them on disk instead,
// in square tiles of the output CRS, each with a halo (the points of its
// neighbours within halo_m of its edges). WriteCloudProducts then makes the
// LAS and PLY files, the DSM and the ground classes and DTM in two passes
// over the tiles, holding one tile per thread and the rasters:
//  1. each tile sets the DSM cells and ground-filter cells whose centres lie
//     in it (the halo brings every point of those cells) and tests its points
//     for isolation (the halo brings their neighbours);
//  2. after the DSM's holes are filled and the ground surface is built over
//     the whole grid, each tile classifies its points, sets its DTM cells and
//     appends its own points to the LAS and PLY files, tiles in order.
// Every cell is owned by exactly one tile and sees every point the whole
// cloud would give it, so the products are those of RasterizeDsm,
// ClassifyGround and RasterizeDtm on the whole cloud (tests hold them
// equal); only the order of the points in the files differs.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "libphoto/base/progress.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/raster.h"
#include "libphoto/export/terrain.h"

namespace aerotri {

struct CloudTile {
  long long tx = 0, ty = 0;
  std::vector<Eigen::Vector3d> xyz;
  std::vector<std::array<std::uint8_t, 3>> rgb;
  std::size_t own = 0;  // the first `own` points are the tile's, the rest its halo
};

class TiledCloud {
 public:
  // Tiles of tile_m metres in dir (created; its earlier tile files removed).
  TiledCloud(const std::filesystem::path& dir, double tile_m, double halo_m);
  ~TiledCloud();  // the tile files are scratch: removed with the object
  TiledCloud(const TiledCloud&) = delete;
  TiledCloud& operator=(const TiledCloud&) = delete;

  // Points in the output CRS, one colour each; call from one thread at a time.
  void Add(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::array<std::uint8_t, 3>>& rgb);
  // After the last Add: the buffers to disk.
  void Finish();

  std::uint64_t count() const { return count_; }
  const Eigen::Vector3d& lo() const { return lo_; }
  const Eigen::Vector3d& hi() const { return hi_; }
  double tile_m() const { return tile_m_; }
  double halo_m() const { return halo_m_; }
  std::size_t num_tiles() const { return tiles_.size(); }
  // Tile k (in row order of tile indices), its own points first.
  CloudTile Read(std::size_t k) const;
  // Whether the tile (tx, ty) owns the point or cell centre xy.
  bool Owns(long long tx, long long ty, const Eigen::Vector2d& xy) const;
  // Deletes the tile files and the folder now.
  void Remove();

 private:
  struct Buffers {
    std::vector<char> own, halo;
    std::uint64_t own_count = 0, halo_count = 0;
  };
  std::filesystem::path File(long long tx, long long ty, bool halo) const;
  void Append(long long tx, long long ty, bool halo, const char* record);
  void FlushTile(long long tx, long long ty, Buffers* b, std::size_t at_least);

  std::filesystem::path dir_;
  double tile_m_ = 0, halo_m_ = 0;
  std::map<std::pair<long long, long long>, Buffers> buffers_;
  std::vector<std::pair<long long, long long>> tiles_;  // after Finish
  std::uint64_t count_ = 0;
  Eigen::Vector3d lo_ = Eigen::Vector3d::Constant(1e300), hi_ = Eigen::Vector3d::Constant(-1e300);
};

struct CloudProductOptions {
  DsmOptions dsm;                // resolution, fill, work folder
  bool classify = true;          // ground classes and the DTM (a projected CRS)
  GroundFilterOptions ground;
  unsigned threads = 1;
  std::string las_wkt;           // OGC WKT1, for LAS readers
  std::string raster_wkt;        // the rasters' CRS
  std::string crs_name;          // for the PLY header
};

// The halo a TiledCloud needs for these products.
double CloudProductsHalo(const CloudProductOptions& options);

struct CloudProducts {
  Raster dsm;
  DsmSummary dsm_summary;
  GroundFilterSummary ground;
  bool has_dtm = false;  // classified, with ground points
  Raster dtm;
  DtmSummary dtm_summary;
};

// Writes las and ply (atomically; an empty path: not that file; las may be
// .las, .laz or .copc.laz) and returns
// the DSM and DTM rasters.
CloudProducts WriteCloudProducts(const TiledCloud& cloud, const std::filesystem::path& las,
                                 const std::filesystem::path& ply, const CloudProductOptions& options,
                                 const ProgressCallback& progress = {});

}  // namespace aerotri
