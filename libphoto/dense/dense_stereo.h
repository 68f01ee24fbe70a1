// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Dense surface from the adjusted cameras by rectified pairwise semi-global
// matching (Hirschmüller 2008, OpenCV StereoSGBM), fused into one coloured
// cloud with a multi-view consistency test.
//
//  1. Each registered image is paired with the neighbours (two by default)
//     that share the most sparse points at a triangulation angle between 3
//     and 25 degrees, and with the best one across the strip when those two
//     are both along it; an image with none at those angles takes its best
//     at up to 55 degrees.
//  2. The pair is rectified by Fusiello's construction (common rotation with
//     x along the baseline), through the exact Brown model of each camera, so
//     that disparity is horizontal whatever the flight direction. The
//     rectified frame holds the whole of the first photo, and the second is
//     shifted onto it so that the disparity search starts at 0. A
//     rolling-shutter photo (Image::rolling_shutter) is rectified as the
//     global-shutter camera at its mid-readout pose would have seen the
//     pair's median-depth plane: each rectified ray meets the plane and is
//     found at the row whose camera saw it.
//  3. SGBM disparities (range from the sparse points, left-right check) are
//     turned into points in the adjustment frame (ENU).
//  4. Each depth map's points go to a file; they are then fused tile by tile
//     in a voxel grid at the dense resolution, and a voxel is kept only when
//     at least min_views depth maps put a point in it or in the voxels just
//     above and below it (agreement_voxels), which removes the blunders of single pairs; where
//     one depth map alone saw the ground there is nothing to agree with and
//     its points are kept (single_map_where_alone). Memory is bounded by one image pair and one
//     tile of voxels, whatever the survey's size.
//
// Why pairwise SGM rather than multi-view plane sweep: on the sample survey
// it reconstructs the terrain to a fraction of a GSD with >95 % coverage in
// seconds on two cores (figures in the README of sample_surveys/).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "libphoto/base/progress.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct DenseOptions {
  double resolution_m = 0.0;  // voxel size; 0: the median GSD of the images
  int min_views = 2;          // depth maps that must agree on a voxel
  int agreement_voxels = 1;   // ... or on the voxels this far above or below it
  // Where a single depth map has points in a 16 x 16-voxel cell (ground seen
  // by one pair of photos only, as at a block's rim), keep them: there is no
  // second map to agree or disagree.
  bool single_map_where_alone = true;
  int partners_per_image = 2; // depth maps per image (its best-matching neighbours)
  // One more partner across the strip (baseline >= 45 deg from the best
  // partner's) when none of the best is: ground seen from two strips.
  bool partner_across = true;
  double min_angle_deg = 3.0;
  double max_angle_deg = 25.0;
  // For the partner across the strip, and for a photo with no neighbour at
  // the preferred angles (sparse exposures, a strip's end at a turn): at
  // 64 m above ground a fixed-wing's return strip, exposed every 55 m, has
  // its consecutive photos 47 degrees apart.
  double max_angle_across_deg = 55.0;
  int block_size = 5;         // SGBM matching window (px)
  double image_scale = 1.0;   // of the working-resolution images
  int num_threads = 0;
  // Where each image's depth points are kept (<image>.pts): fusion reads them
  // tile by tile, and an interrupted run recomputes only what is missing.
  std::filesystem::path work_dir;
  // Tile side in voxels. Memory ~ its square: every depth point in a tile is
  // held (32 bytes) while it is fused, one tile per thread. The number of
  // depth points per voxel column is the number of depth maps that see it
  // (the overlap), whatever the GSD or the survey's size, so a fixed side
  // bounds fusion's memory: at 512 a tile of the sample survey holds at most
  // about 3 million (the dense stage's peak fell from 1.33 GB at 1,500 to
  // 0.66 GB). A multiple of 16, so that the 16 x 16-voxel cells of the
  // lone-map rule never straddle two tiles (no seams).
  long long tile_voxels = 512;
};

struct DenseCloud {
  std::vector<Eigen::Vector3d> positions;  // adjustment frame (ENU metres)
  std::vector<std::array<std::uint8_t, 3>> colours;
  std::vector<std::uint16_t> views;  // supporting depth maps per point
  double resolution_m = 0.0;
};

struct DenseSummary {
  int pairs = 0;
  int pairs_failed = 0;
  long long depth_points = 0;
  long long fused_points = 0;
  int tiles = 0;
  double resolution_m = 0.0;
};

// Where the fused cloud goes, tile by tile, so that no stage need hold all
// of it: prepare(tile) runs on the fusing thread as soon as the tile is
// fused (a conversion to the output CRS, in parallel), then consume(tile)
// once per tile with points, one at a time, in tile order (the same cloud
// every run).
struct FusedTileSink {
  std::function<void(DenseCloud*)> prepare;  // optional
  std::function<void(DenseCloud&&)> consume;
};

// images[i] is the working-resolution photo (BGR) of model.images[i]'s file,
// loaded on demand by load_image(i). Only registered images are used.
void ComputeDenseCloud(const SparseModel& model, const std::function<cv::Mat(int)>& load_image,
                       const DenseOptions& options, const ProgressCallback& progress, const FusedTileSink& sink,
                       DenseSummary* summary);
// The same work in shares, for a workflow that runs them as separate jobs
// (aerotri split): share index (from 0) of count.
struct DenseShare {
  int index = 0;
  int count = 1;
};
// Steps 1-3 for a share of the pairs (a contiguous run of them in image
// order), each pair's depth map into options.work_dir; a pair whose file is
// there already is kept (an interrupted run, or another job's).
void ComputeDepthMaps(const SparseModel& model, const std::function<cv::Mat(int)>& load_image,
                      const DenseOptions& options, const DenseShare& share, const ProgressCallback& progress,
                      DenseSummary* summary);
// The depth-map files ComputeDepthMaps writes for a share (made or not).
std::vector<std::filesystem::path> DepthMapPaths(const SparseModel& model, const DenseOptions& options,
                                                 const DenseShare& share);
// Step 4 for a share of the fusion tiles (a contiguous run of them in tile
// order, the runs balanced by their depth points), once every share's depth
// maps are in options.work_dir. The shares in index order hand their sinks
// the tiles, in the order, that ComputeDenseCloud hands its one sink: the
// same cloud, whatever the number of shares.
void FuseModelDepthMaps(const SparseModel& model, const DenseOptions& options, const DenseShare& share,
                        const ProgressCallback& progress, const FusedTileSink& sink, DenseSummary* summary);
// The same, gathered into one cloud (tests, small surveys).
DenseCloud ComputeDenseCloud(const SparseModel& model,
                             const std::function<cv::Mat(int)>& load_image,
                             const DenseOptions& options, const ProgressCallback& progress,
                             DenseSummary* summary);

// Step 4 alone: fuses depth-point files (as ComputeDenseCloud writes them
// into work_dir) at voxel size res under options' agreement rules.
DenseCloud FuseDepthMaps(const std::vector<std::filesystem::path>& files, double res, const DenseOptions& options,
                         DenseSummary* summary);
// Writes one depth map's points (adjustment frame) and colours in the file
// format FuseDepthMaps reads, atomically. With tile_voxels > 0 the records
// are filed by fusion tile at voxel size res (as ComputeDenseCloud writes
// them, so that fusion reads each tile's records only); fusion with another
// grid, or of an untiled file, reads the whole file for every tile it meets.
void WriteDepthMap(const std::filesystem::path& path, const std::vector<Eigen::Vector3d>& points,
                   const std::vector<std::array<std::uint8_t, 3>>& colours, double res = 0.0,
                   long long tile_voxels = 0);

// Median ground sample distance (m) of the registered images: depth of their
// sparse points over focal length.
double MedianGsd(const SparseModel& model);

}  // namespace aerotri
