// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/model/gimbal_attitude.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace aerotri {

GimbalAttitude AttitudeOf(const Pose& pose) {
  const Eigen::Vector3d axis = pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  // The image's top: −y of the camera frame, in the world.
  const Eigen::Vector3d top = pose.cam_from_world.conjugate() * Eigen::Vector3d(0.0, -1.0, 0.0);
  GimbalAttitude a;
  a.yaw_deg = std::atan2(top.x(), top.y()) * 180.0 / M_PI;
  // The elevation in the vertical plane of the heading, as a gimbal without
  // roll turns: below -90 when the axis leans back, behind the image's top
  // (GimbalAxis is its inverse); a sideways lean (roll) is not in it.
  const Eigen::Vector2d forward = top.head<2>().norm() > 0.0 ? top.head<2>().normalized() : Eigen::Vector2d(0, 1);
  a.pitch_deg = std::atan2(axis.z(), axis.head<2>().dot(forward)) * 180.0 / M_PI;
  if (a.pitch_deg > 90.0) a.pitch_deg -= 360.0;  // keep (-270, 90]: looking down is about -90
  return a;
}

Eigen::Vector3d GimbalAxis(const GimbalAttitude& a) {
  const double p = a.pitch_deg * M_PI / 180.0, y = a.yaw_deg * M_PI / 180.0;
  return {std::cos(p) * std::sin(y), std::cos(p) * std::cos(y), std::sin(p)};
}

Eigen::Vector3d DownInCamera(const GimbalAttitude& a) {
  const double p = a.pitch_deg * M_PI / 180.0;
  return {0.0, std::cos(p), -std::sin(p)};
}

double GimbalRollOf(const Pose& pose) {
  const Eigen::Vector3d right = pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitX();
  return -std::asin(std::clamp(right.z(), -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace aerotri
