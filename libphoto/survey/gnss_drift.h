// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What keeps a drifting GPS from tilting a block: the nadir attitude of a
// survey flight, and a linear-in-time model of the GNSS error.
//
// A consumer drone's EXIF altitude often climbs or sinks by tens of metres
// over a flight (barometric or GNSS drift) while the drone flies level. A
// similarity fitted to those positions turns the drift into a tilt: strips
// are flown one after the other, so height error linear in time is height
// error linear across the block. Two facts break the tie:
//  * a nadir survey's photos look down: their mean optical axis, which the
//    tie points fix relative to the block, is the block's vertical
//    (ViewingGeometry, FitLevelledSimilarity; in the adjustment an attitude
//    prior per image, BundleOptions::attitude_prior_sigma_deg); an oblique
//    survey's gimbal pitches say where down is in each photo
//    (MeasureGimbalVertical), to the same end;
//  * the GPS error then shows as a trend in capture time (FitDriftTrend),
//    estimated in the adjustment per flight (BundleOptions::
//    estimate_gps_drift) instead of bending the block.
//
// Frames: model frames are any right-handed frame of the reconstruction;
// the datum frame is the adjustment's ENU (metres, z up). Times in seconds.

#include <Eigen/Core>
#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "georef/similarity.h"
#include "libphoto/model/gimbal_attitude.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

// Photos grouped into flights by capture time: a gap longer than
// max(120 s, 20 times the median interval) starts a new flight (a battery
// change). Index-aligned with the input; a NaN time gets flight -1.
struct FlightTimes {
  std::vector<int> flight;
  std::vector<double> dt_s;         // time minus its flight's mean time
  std::vector<double> duration_s;   // per flight
  std::vector<int> images;          // per flight
  int NumFlights() const { return static_cast<int>(duration_s.size()); }
};
FlightTimes SplitFlights(const std::vector<double>& times_s);

// The direction a camera looks (its optical axis, +z of the OpenCV camera
// frame) in the world frame of the pose.
Eigen::Vector3d OpticalAxisInWorld(const Pose& pose);

// The viewing geometry of the registered images in the model's own frame:
// whether the block is a nadir survey, so that its mean optical axis may be
// taken as the vertical. Nadir: the axes gather within 15° (median angle
// from their mean), the camera centres span a plane (the flight level: one
// line of cameras could as well be a walk past a facade), and the mean axis
// is within 15° of its normal.
struct ViewingGeometry {
  int images = 0;
  Eigen::Vector3d mean_axis = Eigen::Vector3d::Zero();  // unit, model frame
  double spread_deg = 0.0;          // median angle of the axes from their mean
  bool plane_measured = false;      // centres span two dimensions
  double axis_to_flight_plane_normal_deg = 0.0;
  bool nadir = false;
  std::string reason;               // why (not)
};
ViewingGeometry MeasureViewingGeometry(const SparseModel& model);

// Tilt of each registered image's optical axis from straight down (degrees),
// in an up-is-z frame; summarised by median, mean axis and largest.
// With the ground's mean slope: the angle from level of the plane fitted to
// the tie points (least squares, orthogonal), which a tilted block tilts
// with it.
struct TiltStats {
  int images = 0;
  double mean_axis_tilt_deg = 0.0;  // of the mean optical axis: the block's tilt
  double median_deg = 0.0;
  double max_deg = 0.0;
  int ground_points = 0;            // tie points in the plane fit (3 or more, else no slope)
  double ground_slope_deg = 0.0;
};
TiltStats MeasureTilt(const SparseModel& model);

// The adjusted cameras (model in an ENU frame: x east, y north, z up)
// against their gimbals. Pitch: |adjusted − gimbal| elevation of the optical
// axis. Yaw: the heading of the image's top, after removing the mean
// signed difference (a compass or declination bias common to the flight);
// only for images looking down more than 45°, where the top's heading is
// well defined whatever the roll.
struct GimbalAgreement {
  int images = 0;                 // registered images with gimbal angles
  // The angle between straight down and the mean of the photos' verticals
  // (DownInCamera of each gimbal pitch, turned by the adjusted attitude into
  // ENU): the block's tilt against its gimbals, which each photo's own
  // jitter (a degree or two) averages out of; free of the compass, so as
  // good for oblique photos as for nadir ones.
  double block_tilt_deg = 0.0;
  double pitch_median_deg = 0.0;
  double pitch_max_deg = 0.0;
  std::string pitch_worst_image;
  int yaw_images = 0;
  double yaw_bias_deg = 0.0;      // circular mean of adjusted − gimbal heading
  double yaw_median_deg = 0.0;    // |difference − bias|
  double yaw_max_deg = 0.0;
};
// The vertical of a block, in its own frame, from its gimbal pitches: each
// photo's DownInCamera turned into the model frame, averaged. Usable where 6
// or more registered photos have gimbal angles and their verticals agree
// within 10° (median angle from the mean): the tie points fix the photos'
// attitudes relative to each other, so the verticals of a level block
// agree to the gimbals' pitch error and roll (a degree or two), while
// angles that do not describe the camera (a body's attitude, a gimbal
// without stabilisation) scatter.
struct GimbalVertical {
  int images = 0;
  Eigen::Vector3d down_in_model = Eigen::Vector3d::Zero();  // unit
  double spread_deg = 0.0;
  bool usable = false;
  std::string reason;
};
GimbalVertical MeasureGimbalVertical(const SparseModel& model, const std::map<std::string, GimbalAttitude>& gimbal);
GimbalAgreement CompareWithGimbal(const SparseModel& model_enu, const std::map<std::string, GimbalAttitude>& gimbal);

// Similarity from the model frame to ENU that turns down_in_model (the mean
// optical axis) to −U and fits the rest to the GPS horizontally only: scale,
// heading and E, N translation by a robust 2D similarity (2-point samples,
// inliers within threshold_m, least-squares refit); U translation the median
// height difference. Its residuals keep the GPS height errors whole (none is
// absorbed by a tilt). std::nullopt with fewer than 2 distinct positions.
std::optional<SimilarityFit> FitLevelledSimilarity(const std::vector<Eigen::Vector3d>& from,
                                                   const std::vector<Eigen::Vector3d>& to,
                                                   const Eigen::Vector3d& down_in_model, double threshold_m);

// A linear trend in time of GPS-minus-camera residuals (E, N, U), per flight:
// slope by least squares (after trimming residuals beyond 4 robust
// deviations of a first fit), its standard error from the scatter about the
// line, and significant where the slope is beyond 5 standard errors and the
// drift over the flight beyond 3 prior sigmas (sigma_h for E, N; sigma_v for U).
struct DriftTrend {
  struct Flight {
    int images = 0;
    double duration_s = 0.0;
    Eigen::Vector3d rate_m_per_s = Eigen::Vector3d::Zero();
    Eigen::Vector3d rate_sigma = Eigen::Vector3d::Zero();
    Eigen::Vector3d scatter_m = Eigen::Vector3d::Zero();  // RMS about the line
  };
  std::vector<Flight> flights;
  std::array<bool, 3> significant_axes = {false, false, false};
  bool Significant() const { return significant_axes[0] || significant_axes[1] || significant_axes[2]; }
};
DriftTrend FitDriftTrend(const std::vector<Eigen::Vector3d>& residuals, const FlightTimes& flights,
                         double sigma_h_m, double sigma_v_m);

}  // namespace aerotri
