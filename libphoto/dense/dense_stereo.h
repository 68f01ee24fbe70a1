// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Dense surface from the adjusted cameras by rectified pairwise semi-global
// matching (Hirschmüller 2008, OpenCV StereoSGBM), fused into one coloured
// cloud with a multi-view consistency test.
//
//  1. Each registered image is paired with the neighbours (two by default)
//     that share the most sparse points at a triangulation angle between 3
//     and 25 degrees.
//  2. The pair is rectified by Fusiello's construction (common rotation with
//     x along the baseline), through the exact Brown model of each camera, so
//     that disparity is horizontal whatever the flight direction.
//  3. SGBM disparities (range from the sparse points, left-right check) are
//     turned into points in the adjustment frame (ENU).
//  4. Each depth map's points go to a file; they are then fused tile by tile
//     in a voxel grid at the dense resolution, and a voxel is kept only when
//     at least min_views depth maps put a point in it, which removes the
//     blunders of single pairs. Memory is bounded by one image pair and one
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
  int partners_per_image = 2; // depth maps per image (its best-matching neighbours)
  double min_angle_deg = 3.0;
  double max_angle_deg = 25.0;
  int block_size = 5;         // SGBM matching window (px)
  double image_scale = 1.0;   // of the working-resolution images
  int num_threads = 0;
  // Where each image's depth points are kept (<image>.pts): fusion reads them
  // tile by tile, and an interrupted run recomputes only what is missing.
  std::filesystem::path work_dir;
  long long tile_voxels = 1500;  // tile side in voxels (memory ~ its square)
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

// images[i] is the working-resolution photo (BGR) of model.images[i]'s file,
// loaded on demand by load_image(i). Only registered images are used.
DenseCloud ComputeDenseCloud(const SparseModel& model,
                             const std::function<cv::Mat(int)>& load_image,
                             const DenseOptions& options, const ProgressCallback& progress,
                             DenseSummary* summary);

// Median ground sample distance (m) of the registered images: depth of their
// sparse points over focal length.
double MedianGsd(const SparseModel& model);

}  // namespace aerotri
