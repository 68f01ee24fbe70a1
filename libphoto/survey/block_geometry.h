// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The geometry of a photo block as far as self-calibration and accuracy
// depend on it:
//
//  * the signals of a weak block (MeasureBlockGeometry). On nadir photos of
//    flat ground flown at one altitude the image scale is f / H: focal length
//    and flying height are one unknown, and the principal point is one with
//    the cameras' horizontal position (Δc ≈ ΔX f / H). Terrain relief (depth
//    varying within each image), flying-height variation and oblique views
//    separate them. These are reported; what the adjustment refines is
//    decided from the intrinsics' measured precision (bundle covariance).
//  * a dome test (FitDome): vertical residuals of independent points
//    regressed on squared radial distance from the block centre, the
//    classic symptom of a wrong radial distortion on a nadir block (James and
//    Robson 2014, "Mitigating systematic error in topographic models derived
//    from UAV and ground-based image networks").
//
// Frames: the model in a metric ENU frame (after the initial similarity);
// ratios are unitless, lengths in metres.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

struct BlockGeometry {
  int images = 0;                     // registered
  double median_depth_m = 0.0;        // camera-to-ground distance (median over images)
  double relief_ratio = 0.0;          // median over images of std(depth) / median(depth)
  // Median over images of the depths' scatter about the plane that fits
  // them best (1/depth linear in the normalised image coordinates), over
  // the median depth: the ground's relief within a photo without what a
  // tilted camera or a sloping field add, which a plane is. Of a plane's
  // photos the focal length is one unknown with the depth, however tilted.
  double roughness_ratio = 0.0;
  double height_variation_ratio = 0.0;  // std of camera heights / median depth
  double tilt_p90_deg = 0.0;          // 90th percentile of optical axes' angle from nadir
  double gsd_m = 0.0;                 // median depth / focal length
  double gps_sigma_v_m = 0.0;         // median vertical sigma of the GPS priors (0: none)
  // Nadir photos of flat ground at one altitude: the depths in each photo
  // within kPlanarRoughnessRatio of a plane, flying-height variation under
  // 5 % of the flying height, views within 15 deg of nadir.
  bool nadir_flat_single_altitude = false;
};

// Roughness (BlockGeometry::roughness_ratio) under which a block's photos
// are of a plane as far as the focal length goes. Measured: 0.0015-0.002 on
// a rendered crop-row survey (1.5 m of relief under a 50 m flight), whose f
// wandered from 520 to 982 px when refined, and on a synthetic block with
// 0.3 m of relief under 60 m; 0.004-0.008 on the real Brighton Beach set,
// whose photos determine f (1140 px, against an EXIF value of 936 that its
// 16:9 crop makes wrong); 0.009-0.013 over 12 m of relief under 60 m.
inline constexpr double kPlanarRoughnessRatio = 0.003;

// Measures a model in a metric, up-is-z frame (tie points only); with
// `down`, in any frame whose vertical that is (e.g. a nadir block's mean
// optical axis in an SfM model's own frame, where lengths are in its units
// and only the ratios mean anything).
BlockGeometry MeasureBlockGeometry(const SparseModel& model,
                                   const Eigen::Vector3d& down = -Eigen::Vector3d::UnitZ());

struct DomeTest {
  std::string source;       // "check points", "GPS", or "" when too few points
  int points = 0;
  double radius_m = 0.0;    // of the block (farthest camera from its centre)
  // dz = a + b x + c y + amplitude r² / R² (the plane takes the datum's
  // shift and tilt): the block's edge minus its centre (m).
  double amplitude_m = 0.0;
  double amplitude_sigma_m = 0.0;
  double t = 0.0;           // amplitude / its sigma
  // |t| beyond Student's t with points - 4 degrees of freedom at kDomeAlpha
  // (3.0 for many points; 19.2 for 6, where the residuals' scatter rests on
  // two degrees of freedom and |t| >= 3 would be a 10 % false alarm).
  double t_critical = 0.0;
  bool significant = false;
};

// The dome test's two-sided level: that of |z| >= 3 for a normal variate.
inline constexpr double kDomeAlpha = 0.0026997960632601866;

// The two-sided Student-t critical value: P(|T| > t) = alpha with dof
// degrees of freedom (at least 1).
double StudentTCriticalValue(int dof, double alpha);

// xy: horizontal positions (E, N) of the points, dz their vertical residuals;
// centre and radius_m: the block's. Needs 6 points or more.
DomeTest FitDome(const std::vector<Eigen::Vector2d>& xy, const std::vector<double>& dz,
                 const Eigen::Vector2d& centre, double radius_m, const std::string& source);

}  // namespace aerotri
