// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Bare earth from a photogrammetric cloud: ground classification and a
// digital terrain model (DTM).
//
// Classification is the Simple Morphological Filter (SMRF; Pingel, Clarke
// and McBride 2013, ISPRS J. 77:21-30), written here on OpenCV's
// morphology rather than taken from the Point Cloud Library: PCL's
// ProgressiveMorphologicalFilter is Zhang et al.'s older filter, works on
// PCL's own cloud types (a copy of every point) and would add Debian's
// largest dependency for some 100 lines. SMRF is also what PDAL and
// OpenDroneMap use, so its parameters mean to a user what they mean there:
//   1. a minimum surface on a grid of `cell_m` (a low percentile per cell
//      rather than the minimum: a stereo cloud has low outliers), holes filled;
//   2. openings by discs of growing radius up to `max_window_m`; a cell whose
//      opened surface drops by more than `slope` x the radius step is an object;
//   3. the surface of the remaining cells, interpolated under the objects,
//      is provisional ground;
//   4. a point is ground when it lies within `elevation_threshold_m` +
//      `elevation_scalar` x (local slope of that surface) of it.
// Isolated points (fewer than `noise_min_neighbours` others in the 3 x 3 x 3
// voxels of half a cell around them) and points far below the ground are
// noise.
//
// Classes are ASPRS LAS 1.4's: 1 unclassified (above ground: buildings,
// vegetation), 2 ground, 7 low noise (isolated, or below the ground), 18
// high noise (isolated, above the ground).

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <vector>

#include "libphoto/export/raster.h"

namespace aerotri {

enum AsprsClass : std::uint8_t { kUnclassified = 1, kGround = 2, kLowNoise = 7, kHighNoise = 18 };

struct GroundFilterOptions {
  double cell_m = 0.5;                 // minimum-surface grid
  double max_window_m = 18.0;          // largest object (building) to remove
  double slope = 0.15;                 // rise / run of the steepest terrain kept
  double elevation_threshold_m = 0.3;  // ground band around the surface
  double elevation_scalar = 1.25;      // widens the band on slopes
  int noise_min_neighbours = 3;        // points in the 3 x 3 cells around one
  double noise_below_m = 2.0;          // lower than the ground by more: noise
};

struct GroundFilterSummary {
  long long ground = 0, above = 0, noise = 0;
  int grid_width = 0, grid_height = 0;
};

// One ASPRS class per point (xyz in a projected CRS, metres).
std::vector<std::uint8_t> ClassifyGround(const std::vector<Eigen::Vector3d>& xyz,
                                         const GroundFilterOptions& options,
                                         GroundFilterSummary* summary = nullptr);

// ClassifyGround in steps, for a cloud read tile by tile (cloud_tiles.h).
// The grid and the noise voxels are laid from the whole cloud's bounds, so a
// tile that brings its neighbours within Reach() of the points it classifies
// (and of the cells it owns) gets the classes the whole cloud would.
class GroundFilter {
 public:
  GroundFilter(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const GroundFilterOptions& options);

  // How far around a point its noise test and its cell look (metres).
  double Reach() const;
  // Isolated points, counting their neighbours among xyz only.
  std::vector<bool> Isolated(const std::vector<Eigen::Vector3d>& xyz) const;
  // Step 1 for the cells whose centre `owns` accepts (null: all): a low
  // percentile of the heights of xyz's points in them, isolated ones aside.
  void AddMinimumSurface(const std::vector<Eigen::Vector3d>& xyz, const std::vector<bool>& isolated,
                         const std::function<bool(const Eigen::Vector2d&)>& owns);
  // Steps 2 and 3, once every cell has been added.
  void FinishSurface();
  // Step 4: one point's class; counted in *summary when given.
  std::uint8_t Classify(const Eigen::Vector3d& p, bool isolated, GroundFilterSummary* summary) const;

  int grid_width() const { return nx_; }
  int grid_height() const { return ny_; }

 private:
  long long CellOf(const Eigen::Vector3d& p) const;
  Eigen::Vector2d CellCentre(long long cell) const;

  GroundFilterOptions o_;
  Eigen::Vector3d lo_, hi_;
  int nx_ = 0, ny_ = 0;
  std::vector<float> zmin_, ground_, slope_;  // row-major grids, nx_ x ny_
};

struct DtmSummary {
  long long cells_ground = 0;        // with ground points
  long long cells_interpolated = 0;  // under objects, from the ground around
};

// A DTM on the DSM's grid: the median height of ground points per cell,
// interpolated (GDAL FillNodata) under objects and in gaps, and only where
// the DSM has data, so it never reaches beyond the surveyed surface.
Raster RasterizeDtm(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::uint8_t>& classes,
                    const Raster& dsm, const std::filesystem::path& work_dir = {},
                    DtmSummary* summary = nullptr);
// RasterizeDtm's last step, for a DTM whose cells hold the median ground
// heights (SetCellMedians over the ground points, on the DSM's grid).
void FinishDtm(Raster* dtm, const Raster& dsm, const std::filesystem::path& work_dir = {},
               DtmSummary* summary = nullptr);

}  // namespace aerotri
