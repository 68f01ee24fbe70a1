// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Incremental structure from motion (the Snavely / COLMAP scheme):
//  1. an initial pair with many matches and enough parallax: relative pose
//     from the essential matrix (five-point RANSAC on undistorted rays),
//     triangulation, two-view bundle adjustment;
//  2. repeatedly the unregistered image that sees the most triangulated
//     tracks is registered by PnP RANSAC (P3P), its new tracks are
//     triangulated with angle and reprojection checks;
//  3. optionally a local bundle adjustment around each new image (it and
//     its most connected neighbours vary, the images around them held), and
//     a global one (robust loss, outlier rejection) whenever the model has grown by a
//     set fraction, self-calibrating focal length and radial distortion once
//     enough images are in, then again at the end with every intrinsic
//     parameter.
// Images that fail are retried after each adjustment. Images still left out
// but with a GPS position are then rescued by guided matching: the model is
// related to the GPS frame by a robust similarity, the image's pose predicted
// from its GPS position and its capture-order neighbours' attitude, the
// model's points projected into it and matched only to features near their
// predicted position (which lets weakly textured frames, such as bare
// fields, register), then PnP as usual. The result says, per image, whether
// it registered and why not.
//
// Photos left out that share tie points among themselves (at least
// kMinComponentImages of them, e.g. strips on the far side of a field bare
// of texture) form a further component: reconstructed on their own from the
// main model's calibration and placed in its frame through both models'
// similarity to the GPS (or, for a single strip, levelled by its mean
// optical axis and fitted in plan). The seam between components is then held
// by GPS alone; without GPS a component cannot be placed and its photos are
// left out, each saying so.
//
// Registrations are checked against the GPS as the model grows (after each
// global adjustment), so that a false registration on repetitive fields is
// caught when it happens: once the block is a nadir survey spanning a plane,
// the model is levelled by its mean optical axis (an oblique block by its
// photos' gimbal pitches, where given: MeasureGimbalVertical) and fitted to
// the GPS horizontally (a drifting GPS altitude cannot tilt that fit); an image
// lying more than gps_check_m from its GPS position, whose GPS position
// agrees with its capture-order neighbours' (so the fix is not the one in
// error), is de-registered and named. It may come back only through guided
// matching from its GPS position, whose pose must agree with that position;
// a second failure leaves it out for good. A GPS fix that jumps away from
// its neighbours' is the GPS's error: the image stays, and georeferencing
// judges the fix.
//
// With MapperOptions::gps_priors the GPS does more than check: once the
// registered images' fixes span the block (not one line), the model is moved
// into the GPS frame by a robust similarity, and from then on every global
// adjustment carries each fix as a prior on its camera centre, with the
// photo's stated sigmas (MapperPriors), and each rolling-shutter photo's
// motion during readout (its stated velocity is in that frame). A model that
// starts to fold or bend, which tie points alone can let happen on weak,
// flat, rolling-shutter blocks, is held to where the aircraft was. A fix
// farther from its camera than the anchoring's threshold when it could first
// enter enters no prior (a GPS blunder, or a false registration that the
// GPS check then judges). Where the photos state their attitude too, the
// mapper starts from the fixes and attitudes instead of an image pair
// (MapperOptions::start_from_priors).

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "libphoto/base/progress.h"
#include "libphoto/features/features.h"
#include "libphoto/matching/matching.h"
#include "libphoto/model/gimbal_attitude.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct MapperOptions {
  int min_pnp_inliers = 15;
  double max_reprojection_px = 4.0;         // working resolution
  double min_triangulation_angle_deg = 1.5;
  double init_min_median_angle_deg = 2.0;
  int init_candidates = 40;
  // Guided matching of images left out (needs GPS).
  bool gps_rescue = true;
  double rescue_search_radius_px = 250.0;  // offset search, working resolution
  // Horizontal distance (m) beyond which a registered image disagrees with
  // its GPS position (see the header); 0: no check.
  double gps_check_m = 25.0;
  // Intermediate global adjustments of a model with more registered images
  // than this solve the normal equations by conjugate gradients on the
  // Schur complement (Schur-Jacobi preconditioner) instead of a sparse
  // Cholesky factorisation: they only have to hold the growing model
  // together, and an exact solve's cost per image grows with the block.
  // The final adjustment is always exact. 0: every adjustment exact (the
  // default: at 513 photos the iterative solves took 4 % longer,
  // bench/README.md).
  int iterative_above_images = 0;
  // Local adjustment after each registration: the new image and the
  // registered images sharing the most tie points with it (this many in
  // all) vary with every point they see, the other images seeing those
  // points held; intrinsics held. 0: none (the default: at 513 photos they
  // cut the global adjustments' time by a third, and cost as much again;
  // bench/README.md).
  int local_adjust_images = 0;
  int local_adjust_iterations = 6;  // solver iterations of a local adjustment
  // A global adjustment runs whenever the registered images have grown by
  // this fraction since the last one (and while the model is small).
  double global_adjust_growth = 0.25;
  // Global adjustments screen with the Huber loss (stopped at a relative
  // cost change of 1e-5) and, once the blunders beyond
  // max_reprojection_px are out, estimate by least squares
  // (BundleOptions::least_squares_after_screening): Huber's re-weighting
  // crawls along a block's weak directions for as many iterations as it is
  // allowed, more as the block grows. false: Huber in every solve.
  bool global_adjust_screening = true;

  // Anchor the model to the GPS (see the header) once this many registered
  // images with GPS span the block; false: the GPS only checks.
  bool gps_priors = false;
  int gps_prior_min_images = 5;
  // With gps_priors: where three or more photos state a GPS fix and an
  // attitude (MapperPriors::attitude), start from them instead of an image
  // pair: each such photo placed where they say, its tracks triangulated,
  // and the block adjusted with the fixes and the attitudes' tilt as priors,
  // its residuals screened from coarse to fine (100, 20 px, then
  // max_reprojection_px); photos that keep too few tie points are taken out
  // and registered by PnP like the rest. On flat ground seen nadir the
  // relative pose of an image pair is nearly degenerate, and a model that
  // starts from one can be wrong from its first photos.
  bool start_from_priors = true;

  int num_threads = 0;
  // Focal-length priors per camera group (see BundleOptions).
  std::vector<double> focal_prior_px;
  ProgressCallback progress;

  // Throws InvalidArgument naming the option, its value and the range.
  void Check() const;
};

// What the photos state of themselves beyond their GPS position, for the
// anchored mapper (MapperOptions::gps_priors); index-aligned with the
// images, missing entries: none.
struct MapperPriors {
  // The GPS fix's standard deviations (m); missing or 0: 5 m and 10 m.
  std::vector<double> gps_sigma_h_m, gps_sigma_v_m;
  // The rolling shutter's readout time and the camera's velocity in the GPS
  // (ENU) frame; applied once the model is in that frame.
  std::vector<std::optional<RollingShutterMotion>> rolling_shutter;
  // The camera's attitude as the photo states it (cam_from_world in the GPS
  // ENU frame): with a GPS fix, where the mapper places the photo to start
  // from (MapperOptions::start_from_priors).
  std::vector<std::optional<Eigen::Quaterniond>> attitude;
  // The stated attitudes' tilt sigma (degrees), the prior on each placed
  // photo's down direction.
  double attitude_sigma_deg = 10.0;
};

struct ImageRegistration {
  bool registered = false;
  std::string why_not;
  int correspondences = 0;  // 2D-3D at the last attempt
  int inliers = 0;
};

struct MapperResult {
  SparseModel model;  // all images (registered flag set), points, observations
  std::vector<ImageRegistration> images;
  int num_tracks = 0;
  int dropped_inconsistent_tracks = 0;
  std::string initial_pair;
  int global_adjustments = 0;
  double adjustment_s = 0.0;  // wall time spent in the global adjustments
  int adjustment_iterations = 0;  // solver iterations of the global adjustments
  int local_adjustments = 0;
  double local_adjustment_s = 0.0;
  // Images de-registered because their pose disagreed with their GPS
  // position (each named in images[i].why_not while left out).
  std::vector<std::string> gps_deregistered;
  // Per image: 0 for the main model, k for the k-th further component (a
  // group of photos with tie points among themselves but none to the main
  // model, reconstructed on its own and placed by its GPS); -1 when not
  // registered.
  std::vector<int> component;
  // Registered photos per component (main model first).
  std::vector<int> component_images;
  // The last global adjustment held the focal length at its EXIF /
  // certificate value: the block is nadir photos of flat ground at one
  // altitude, which cannot determine it.
  bool focal_held = false;
  // With MapperOptions::gps_priors: the registered images when the model
  // was moved into the GPS frame and its fixes became priors (0: never; the
  // model is then in a frame of its own).
  int gps_anchored_at_images = 0;
  // Photos whose rolling shutter the anchored adjustments modelled.
  int rolling_shutter_images = 0;
};

// Smallest further component that is kept.
constexpr int kMinComponentImages = 3;

// cameras: one per camera group (working-resolution pixels, initial
// intrinsics); camera_of_image indexes them; names are the image names.
MapperResult ReconstructIncremental(const std::vector<std::string>& names,
                                    const std::vector<int>& camera_of_image,
                                    const std::vector<Camera>& cameras,
                                    const std::vector<ImageFeatures>& features,
                                    const std::vector<PairMatches>& matches,
                                    const MapperOptions& options,
                                    const std::vector<std::optional<Eigen::Vector3d>>& gps_enu = {},
                                    const std::map<std::string, GimbalAttitude>& gimbal = {},
                                    const MapperPriors& priors = {});

}  // namespace aerotri
