// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Coordinate reference systems through PROJ: anything PROJ accepts
// ("EPSG:32632", the compound "EPSG:32632+5773", WKT, PROJ strings).
//
// Every conversion goes through WGS84 geodetic coordinates (EPSG:4979:
// latitude, longitude in degrees, ellipsoidal height in metres). Axis order is
// normalised for people: easting, northing for projected CRSs, longitude,
// latitude for geographic ones (proj_normalize_for_visualization). A 2D CRS
// (EPSG:32632) leaves heights ellipsoidal; a compound CRS with a geoid model
// (EPSG:32632+5773, EGM96) gives orthometric heights through the grid
// egm96_15.gtx of Debian's proj-data. The network is never used: a missing
// grid is a CrsError, never a silent "ballpark" height.

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>

#include "georef/local_frame.h"

namespace aerotri {

class Crs {
 public:
  // Throws CrsError naming the definition and what PROJ said. "LOCAL" (any
  // case) or an engineering CRS's WKT (ENGCRS / LOCAL_CS) is a local
  // Cartesian frame: see IsLocal().
  static Crs FromString(const std::string& definition);
  // The WGS84 UTM zone of a point (EPSG:326zz north, 327zz south), with
  // Norway's and Svalbard's exceptions as GeographicLib's UTMUPS defines them.
  static Crs UtmFor(const Geodetic& g);

  const std::string& definition() const;
  std::string Name() const;
  std::string Wkt() const;    // WKT2:2019
  std::string WktV1() const;  // OGC WKT 1 (GDAL flavour), what LAS 1.4 readers expect
  bool IsGeographic() const;
  bool IsGeocentric() const;  // ECEF X, Y, Z: no horizontal / vertical axes
  // A local engineering frame: Cartesian x (east), y (north), z (up) in the
  // file's length unit, with no geodetic meaning. It converts through an
  // exact stand-in: the ENU frame tangent at LocalGeodeticOrigin(), on which
  // (x, y, z) − origin() in metres lie, so an adjustment in that ENU frame
  // is an adjustment in the file's own coordinates (no curvature, no
  // projection). Geodetic positions (GPS) have no place in it.
  bool IsLocal() const;
  double LocalUnitMetres() const;  // metres per file unit
  // The same local frame with its coordinates' origin moved to `origin`
  // (file units): keeps the stand-in's coordinates small.
  Crs LocalAt(const Eigen::Vector3d& origin) const;
  static Geodetic LocalGeodeticOrigin() { return {0.0, 0.0, 0.0}; }
  // True for a compound CRS or one with a vertical axis (heights are not
  // ellipsoidal).
  bool HasVerticalDatum() const;

  // x, y, z in this CRS (normalised axis order) from WGS84 geodetic.
  Eigen::Vector3d FromGeodetic(const Geodetic& g) const;
  Geodetic ToGeodetic(const Eigen::Vector3d& xyz) const;

  Crs(const Crs&) = default;
  Crs& operator=(const Crs&) = default;
  ~Crs();

  struct Impl;

 private:
  explicit Crs(std::shared_ptr<Impl> impl);
  std::shared_ptr<Impl> impl_;
};

// EGM96 geoid undulation N (metres) at a position, through PROJ and the
// egm96_15.gtx grid: ellipsoidal h = orthometric H + N. Throws CrsError when
// the grid is missing.
double Egm96Undulation(double lat_deg, double lon_deg);

}  // namespace aerotri
