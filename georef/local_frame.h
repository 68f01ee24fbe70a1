// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The adjustment frame: a local east-north-up Cartesian frame (metres)
// tangent to the WGS84 ellipsoid at a reference point of the survey.
// Delegates to GeographicLib::LocalCartesian (Karney); nothing is re-derived.
//
// Geodetic coordinates are latitude and longitude in degrees and ellipsoidal
// height in metres (WGS84, EPSG:4979). ECEF is EPSG:4978 metres.

#include <Eigen/Core>
#include <memory>

namespace GeographicLib {
class LocalCartesian;
}

namespace aerotri {

struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double h_m = 0.0;  // above the WGS84 ellipsoid
};

class LocalFrame {
 public:
  // Throws InvalidArgument when latitude is outside [-90, 90] or a value is
  // not finite.
  explicit LocalFrame(const Geodetic& origin);
  ~LocalFrame();
  LocalFrame(const LocalFrame& other);
  LocalFrame& operator=(const LocalFrame& other);

  const Geodetic& origin() const { return origin_; }

  Eigen::Vector3d EnuFromGeodetic(const Geodetic& g) const;
  Geodetic GeodeticFromEnu(const Eigen::Vector3d& enu) const;
  Eigen::Vector3d EnuFromEcef(const Eigen::Vector3d& ecef) const;
  Eigen::Vector3d EcefFromEnu(const Eigen::Vector3d& enu) const;

  static Eigen::Vector3d EcefFromGeodetic(const Geodetic& g);
  static Geodetic GeodeticFromEcef(const Eigen::Vector3d& ecef);

 private:
  Geodetic origin_;
  std::unique_ptr<GeographicLib::LocalCartesian> local_;
};

}  // namespace aerotri
