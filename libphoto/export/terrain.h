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

}  // namespace aerotri
