// SPDX-License-Identifier: BSD-3-Clause
#include "georef/local_frame.h"

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <cmath>
#include <string>

#include "libphoto/base/error.h"

namespace aerotri {

LocalFrame::LocalFrame(const Geodetic& origin) : origin_(origin) {
  if (!std::isfinite(origin.lat_deg) || !std::isfinite(origin.lon_deg) ||
      !std::isfinite(origin.h_m) || std::abs(origin.lat_deg) > 90.0) {
    throw InvalidArgument("local frame origin: expected latitude in [-90, 90] deg and finite "
                          "longitude / height, got lat " + std::to_string(origin.lat_deg) +
                          " lon " + std::to_string(origin.lon_deg) + " h " +
                          std::to_string(origin.h_m));
  }
  local_ = std::make_unique<GeographicLib::LocalCartesian>(
      origin.lat_deg, origin.lon_deg, origin.h_m, GeographicLib::Geocentric::WGS84());
}

LocalFrame::~LocalFrame() = default;

LocalFrame::LocalFrame(const LocalFrame& other)
    : origin_(other.origin_),
      local_(std::make_unique<GeographicLib::LocalCartesian>(*other.local_)) {}

LocalFrame& LocalFrame::operator=(const LocalFrame& other) {
  if (this != &other) {
    origin_ = other.origin_;
    local_ = std::make_unique<GeographicLib::LocalCartesian>(*other.local_);
  }
  return *this;
}

Eigen::Vector3d LocalFrame::EnuFromGeodetic(const Geodetic& g) const {
  Eigen::Vector3d enu;
  local_->Forward(g.lat_deg, g.lon_deg, g.h_m, enu.x(), enu.y(), enu.z());
  return enu;
}

Geodetic LocalFrame::GeodeticFromEnu(const Eigen::Vector3d& enu) const {
  Geodetic g;
  local_->Reverse(enu.x(), enu.y(), enu.z(), g.lat_deg, g.lon_deg, g.h_m);
  return g;
}

Eigen::Vector3d LocalFrame::EnuFromEcef(const Eigen::Vector3d& ecef) const {
  return EnuFromGeodetic(GeodeticFromEcef(ecef));
}

Eigen::Vector3d LocalFrame::EcefFromEnu(const Eigen::Vector3d& enu) const {
  return EcefFromGeodetic(GeodeticFromEnu(enu));
}

Eigen::Vector3d LocalFrame::EcefFromGeodetic(const Geodetic& g) {
  Eigen::Vector3d ecef;
  GeographicLib::Geocentric::WGS84().Forward(g.lat_deg, g.lon_deg, g.h_m, ecef.x(),
                                             ecef.y(), ecef.z());
  return ecef;
}

Geodetic LocalFrame::GeodeticFromEcef(const Eigen::Vector3d& ecef) {
  Geodetic g;
  GeographicLib::Geocentric::WGS84().Reverse(ecef.x(), ecef.y(), ecef.z(), g.lat_deg,
                                             g.lon_deg, g.h_m);
  return g;
}

}  // namespace aerotri
