// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A camera's attitude as a drone's gimbal states it (DJI XMP), and its
// relation to a pose. Frames: the pose's world frame is ENU (x east, y
// north, z up); the camera frame is OpenCV's (x right, y down the image, z
// along the optical axis).

#include <Eigen/Core>

#include "libphoto/model/sparse_model.h"

namespace aerotri {

// A camera's attitude as its gimbal reports it (DJI XMP drone-dji:
// GimbalPitchDegree / GimbalYawDegree): pitch the elevation of the optical
// axis (−90 straight down, 0 level, below −90 leaning back, behind the
// image's top), yaw the heading of the image's top (degrees clockwise from
// north). Without roll: a sideways lean is not expressed. Independent of
// the photos and the GPS positions: what tells a tilted block from a level
// one on real flights.
struct GimbalAttitude {
  double pitch_deg = -90.0;
  double yaw_deg = 0.0;
};

// The adjusted elevation and heading of one pose (ENU), as a gimbal reports them.
GimbalAttitude AttitudeOf(const Pose& pose_enu);
// The optical axis (ENU, unit) a gimbal attitude states.
Eigen::Vector3d GimbalAxis(const GimbalAttitude& a);
// The world's down in the frame of a camera whose gimbal states a (roll
// zero, as a stabilised gimbal holds it): (0, cos p, −sin p) for pitch p,
// (0, 0, 1) looking straight down. Independent of the yaw, so of a
// compass's bias: what the pitch alone says about the camera's vertical.
Eigen::Vector3d DownInCamera(const GimbalAttitude& a);
// The roll a gimbal would report for a pose (degrees; positive: the image's
// right side down): the elevation of the camera's x axis, negated.
double GimbalRollOf(const Pose& pose_enu);

}  // namespace aerotri
