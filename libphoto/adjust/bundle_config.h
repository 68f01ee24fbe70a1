// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The bundle adjuster's choices as data, decided before any Ceres problem is
// built (the role of COLMAP's BundleAdjustmentConfig): which images, camera
// groups and points take part in one solve, which intrinsic parameters vary,
// which images share one block with their intrinsics, and what holds the
// gauge (the seven freedoms of position, orientation and scale that
// reprojection alone leaves open). AdjustBundle configures each solve with
// ConfigureBundle and then only builds and solves what the configuration says.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

enum class BundleGauge {
  // Three or more non-collinear priors (GPS, control) fix the datum: no
  // parameter is held.
  kPriors,
  // No priors: image A's pose is held fixed; the scale (to which
  // reprojection is blind) is restored from the baseline A–B after the solve.
  kFixedImage,
  // No priors and image A has a camera group of its own (BAL): every block
  // varies (holding A's merged block would cost Ceres its uniform camera
  // blocks); A's pose and the A–B baseline are restored exactly afterwards.
  kFreeNetwork,
  // Priors too few or collinear: A's rotation is held; the priors give the
  // scale when they hold two distinct positions, else the A–B baseline is
  // restored after the solve.
  kHeldRotation,
  // No priors fix the datum, but two or more images with distinct centres
  // are held by the caller (BundleOptions::held_poses): they hold position,
  // orientation and scale; nothing is restored.
  kHeldImages,
};

std::string ToString(BundleGauge gauge);

struct BundleConfig {
  // Index-aligned with the model's images, cameras and points.
  std::vector<char> image_used;
  std::vector<char> camera_used;
  std::vector<char> point_used;
  // Adjusted images per camera group.
  std::vector<int> images_of_camera;
  int num_images = 0;
  int num_points = 0;
  int num_observations = 0;  // reprojection residuals
  int skipped_points = 0;    // tie points with a single observation

  // GPS and control prior positions taking part (what fixes the datum).
  std::vector<Eigen::Vector3d> prior_positions;
  BundleGauge gauge = BundleGauge::kPriors;
  int image_a = -1;             // the image whose pose or rotation the gauge holds
  int image_b = -1;             // the far end of the baseline from A
  double baseline_m = 0.0;      // |C_B − C_A| before the solve
  bool restore_scale = false;   // the baseline A–B is restored after the solve

  // Per image: its pose held at its value (BundleOptions::held_poses).
  std::vector<char> held;

  // Per camera group: the intrinsic parameters that vary (sorted indices).
  std::vector<std::vector<int>> refined;
  // Per image: its pose and its camera group's intrinsics are one block
  // [q(4), C(3), intrinsics] (a group of its own with something to refine,
  // no GPS prior, not the held image).
  std::vector<char> merged;

  bool AnyMerged() const;
  bool HoldsRotationOf(int image) const;
  bool HoldsCentreOf(int image) const;
  // The parameters of camera group c held at their values.
  std::vector<int> ConstantParams(const SparseModel& model, int c) const;
  // What anchors the datum, in words (BundleSummary::gauge).
  std::string Describe(const SparseModel& model, int num_gps, int num_gcp, bool offset_estimated) const;
};

// The intrinsic parameters of one camera that options.refine_intrinsics
// (and refine_params) selects, sorted; a name the model lacks is not refined.
std::vector<int> RefinedParams(const Camera& camera, const BundleOptions& options);

// True when the positions span a plane (not a line or a point).
bool PriorsFixDatum(const std::vector<Eigen::Vector3d>& positions);

// The configuration of one solve of model under options: registered images
// observing a usable point (a tie point seen twice, a control point with a
// prior seen once, a check point only with check_points_in_bundle), the
// gauge, the intrinsics that vary (min_images_to_refine_intrinsics,
// held_params) and the merged blocks.
BundleConfig ConfigureBundle(const SparseModel& model, const BundleOptions& options);

}  // namespace aerotri
