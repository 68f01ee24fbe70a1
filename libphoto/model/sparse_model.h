// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The sparse survey model: camera groups, images with poses, 3D points (tie
// points, ground control points, check points) and their image observations.
//
// Frames: points and camera centres are in the adjustment frame: a local
// metric frame, normally ENU metres tangent at the survey's reference point
// (see georef/local_frame.h); a BAL problem keeps its own arbitrary frame.
// A pose holds the world-to-camera rotation and the camera centre in world:
//   point_in_cam = cam_from_world * (point_in_world - centre_in_world)
// with the camera frame +z forward, x right, y down (OpenCV). Keeping the
// centre as the parameter makes GPS priors direct.
// Observations are pixels with (0, 0) at the centre of the top-left pixel.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "camera_models/camera.h"

namespace aerotri {

struct Pose {
  Eigen::Quaterniond cam_from_world = Eigen::Quaterniond::Identity();
  Eigen::Vector3d centre_in_world = Eigen::Vector3d::Zero();

  Eigen::Vector3d CamFromWorld(const Eigen::Vector3d& point_in_world) const {
    return cam_from_world * (point_in_world - centre_in_world);
  }
  // Translation t of the x_cam = R X + t form (COLMAP, BAL).
  Eigen::Vector3d Translation() const {
    return -(cam_from_world * centre_in_world);
  }
  static Pose FromRotationTranslation(const Eigen::Quaterniond& cam_from_world,
                                      const Eigen::Vector3d& t) {
    Pose pose;
    pose.cam_from_world = cam_from_world.normalized();
    pose.centre_in_world = -(pose.cam_from_world.conjugate() * t);
    return pose;
  }
};

// A position prior in the adjustment frame with separate horizontal and
// vertical standard deviations (metres): GPS on a camera centre, a surveyed
// position on a control point.
struct PositionPrior {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double sigma_h_m = 1.0;
  double sigma_v_m = 1.0;
  // A full covariance (adjustment frame, m²), when the survey states its
  // sigmas on other axes (a projected CRS's x / y / z); sigma_h_m and
  // sigma_v_m then summarise it (largest horizontal, vertical).
  std::optional<Eigen::Matrix3d> covariance;
  // GPS priors under a drift model (BundleOptions::estimate_gps_drift): the
  // flight the photo belongs to (-1: no drift applies) and its capture time
  // minus the flight's mean time (s).
  int flight = -1;
  double time_from_flight_s = 0.0;
};

enum class PointRole {
  kTie,      // triangulated from images only
  kControl,  // ground control point: surveyed prior enters the adjustment
  kCheck,    // check point: never enters the adjustment, compared afterwards
};

// A rolling shutter's exposure of one photo: the rows are read top to
// bottom over readout_time_s while the camera moves at velocity (adjustment
// frame units per second). Row y is exposed at
//   t(y) = (y − (height − 1) / 2) · readout_time_s / height
// from the middle of the readout, when the camera is at
//   C(t) = C + t · velocity,
// C being the pose's centre: a pose is the camera at mid-readout. The
// camera's turning during the readout is not modelled (a stabilised or
// steadily flying camera turns by hundredths of a degree in 50 ms).
struct RollingShutterMotion {
  double readout_time_s = 0.0;  // first row to last
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();

  // The exposure time of image row y (px, aerotri convention) of an image
  // `height` rows tall, from mid-readout (s).
  double RowTime(double y, int height) const {
    return height > 0 ? (y - 0.5 * (height - 1)) * readout_time_s / height : 0.0;
  }
  // How far the camera centre is from the pose's at row y.
  Eigen::Vector3d CentreShift(double y, int height) const { return RowTime(y, height) * velocity; }
};

struct Image {
  int id = 0;            // external id (COLMAP IMAGE_ID, BAL camera index)
  std::string name;      // file name relative to the images folder
  int camera = 0;        // index into SparseModel::cameras
  Pose pose;
  bool registered = true;
  std::optional<PositionPrior> gps_prior;  // on the camera centre
  // Set for a rolling-shutter photo whose motion is known (else every row
  // is exposed at the pose, a global shutter).
  std::optional<RollingShutterMotion> rolling_shutter;

  // The pose at which image row y was exposed: the pose itself for a global
  // shutter.
  Pose PoseAtRow(double y, int height) const {
    Pose at = pose;
    if (rolling_shutter) at.centre_in_world += rolling_shutter->CentreShift(y, height);
    return at;
  }
};

// Where a world point appears in an image: for a rolling shutter, the row
// at which the moving camera sees it, found by fixed-point iteration (each
// step shrinks the error by the image motion during one row, a hundredth of
// a pixel per pixel on a drone); for a global shutter, the projection.
// *in_front (optional): the point lies in front of the camera.
Eigen::Vector2d ProjectIntoImage(const Camera& camera, const Image& image, const Eigen::Vector3d& point_in_world,
                                 bool* in_front = nullptr);

struct Point {
  int id = 0;  // external id (COLMAP POINT3D_ID, BAL point index)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::array<std::uint8_t, 3> color{{128, 128, 128}};
  PointRole role = PointRole::kTie;
  std::string name;                    // GCP / check-point name
  std::optional<PositionPrior> prior;  // surveyed position (control points)
};

struct Observation {
  int image = 0;  // index into SparseModel::images
  int point = 0;  // index into SparseModel::points
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // px
  int keypoint = -1;  // index of the image's keypoint, -1 when unknown
  // Standard deviation of this measurement (px); 0: the adjustment's sigma
  // for its kind (tie point or target mark).
  double sigma_px = 0.0;
};

struct SparseModel {
  std::vector<Camera> cameras;
  std::vector<Image> images;
  std::vector<Point> points;
  std::vector<Observation> observations;

  // Throws InvalidArgument naming the first broken reference or value.
  void Validate() const;
  // Number of observations per point / per image (index-aligned).
  std::vector<int> ObservationsPerPoint() const;
  std::vector<int> ObservationsPerImage() const;
  int NumRegisteredImages() const;
  // Keeps the points with keep[p] true (and their observations), in order.
  void KeepPoints(const std::vector<char>& keep);
};

}  // namespace aerotri
