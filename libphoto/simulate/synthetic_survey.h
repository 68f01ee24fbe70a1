// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Synthetic drone surveys with known truth, for tests, benchmarks and the
// sample survey (the COLMAP SynthesizeDataset / OpenSfM synthetic-scene idea).
//
// Frame: ENU metres around the survey's reference point. The terrain is a
// smooth relief z = TerrainHeight(x, y); a lawn-mower flight at a set height
// above ground looks near nadir with a Brown camera; tie points lie on the
// terrain; ground control and check points lie on the terrain on a regular
// pattern. Every observation is the true projection plus Gaussian pixel
// noise. All randomness comes from options.seed, so a failure reproduces.

#include <cstdint>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct SyntheticSurveyOptions {
  std::uint32_t seed = 1;

  // Flight.
  double area_width_m = 240.0;    // east-west extent of the area
  double area_height_m = 180.0;   // north-south extent
  double flight_height_m = 80.0;  // above the mean terrain
  double forward_overlap = 0.75;
  double side_overlap = 0.65;
  double attitude_sigma_deg = 2.0;  // random tilt and heading jitter
  // The camera's pitch as a gimbal states it (GimbalAttitude): −90 looks
  // straight down; −60 leans 30° towards the image's top, which points
  // north on the first strip and south on the next (lawn-mower), so that an
  // oblique block looks both ways.
  double gimbal_pitch_deg = -90.0;
  // A rolling shutter: rows read top to bottom over readout_time_s while the
  // drone flies along its strip at flight_speed_mps (east on the first
  // strip, west on the next). 0: a global shutter.
  double readout_time_s = 0.0;
  double flight_speed_mps = 12.0;

  // Camera (4000 x 3000 px, 3000 px focal length; moderate Brown distortion).
  int width = 4000;
  int height = 3000;
  std::vector<double> brown_params = {3000.0, 2012.0, 1490.0, -0.08, 0.05,
                                      -0.01,  0.0005, -0.0003};

  // Terrain relief amplitude (m).
  double relief_m = 12.0;

  // Scene.
  int num_tie_points = 3000;
  double pixel_noise_px = 0.3;
  int num_control_points = 8;
  int num_check_points = 6;
};

struct SyntheticSurvey {
  // exact poses, intrinsics, points; exact observations; a rolling
  // shutter's motion on each image (Image::rolling_shutter)
  SparseModel truth;
  SparseModel observed;  // same structure, noisy observations (poses = truth)
  double gsd_m = 0.0;    // ground sample distance at the flight height
};

// Height of the synthetic terrain (ENU up, metres) at (east, north).
double TerrainHeight(double east_m, double north_m, double relief_m);

SyntheticSurvey MakeSyntheticSurvey(const SyntheticSurveyOptions& options);

}  // namespace aerotri
