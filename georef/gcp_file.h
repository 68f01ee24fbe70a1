// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Ground control and check-point files in OpenDroneMap's gcp_list.txt format:
//
//   EPSG:32632                       <- first line: a CRS (anything PROJ takes)
//   geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extra ...]
//
// geo_x, geo_y are in the CRS's normalised axis order (easting, northing; or
// longitude, latitude for a geographic CRS); geo_z is ellipsoidal for a 2D
// CRS and orthometric for a compound one (EPSG:32632+5773). Blank lines and
// lines starting with '#' are skipped. Extras (key=value, after the name)
// state the stochastic model:
//   sigma_h=0.02 sigma_v=0.03             the point's survey sigmas (metres)
//   sigma_x=0.02 sigma_y=0.02 sigma_z=0.04  the same on the CRS's own axes
//                                         (all three; they win over h / v)
//   sigma_px=0.5                          this measurement's image sigma (px)
// Other extras are ignored. Without a name, lines with identical coordinates
// are one point. A control point surveyed in plan only (a handheld GNSS
// whose heights are worthless, a map-digitised corner) has geo_z "nan" (or
// "-"): GroundPoint::horizontal_only, its height left to the adjustment.
//
// Pixels: OpenDroneMap reads these files through OpenSfM, whose pixel
// coordinates put the centre of the top-left pixel at (0, 0) (OpenSfM
// doc/source/geometry.rst; normalized = (x + 0.5 − w/2) / max(w, h)), as
// aerotri and OpenCV do: PixelOrigin::kCentre, the default, reads them as
// they are. COLMAP (and tools that measure from the image's outer corner)
// put that centre at (0.5, 0.5): PixelOrigin::kCorner subtracts 0.5.
//
// Coordinates only (what a GNSS rover gives, before anyone has marked the
// targets in the photos): the CRS line, then one line per point
//
//   name x y z [sigma_h=0.02 sigma_v=0.03 | sigma_x= sigma_y= sigma_z=]
//
// or PIX4D's comma-separated "label,x,y,z[,acc_h,acc_v]" (accuracies in
// metres; a header row is skipped). GcpFile::coordinates_only is then set
// and every point has no measurements: `aerotri mark` (and `run`) find the
// targets in the photos. A file is one kind or the other.
//
// Errors: ParseError "file:line: what was expected, got what".

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace aerotri {

enum class PixelOrigin { kCorner, kCentre };

struct GcpMeasurement {
  std::string image;      // file name as written
  Eigen::Vector2d xy_px;  // aerotri convention (centre of top-left pixel = 0, 0)
  int line = 0;
  std::optional<double> sigma_px;  // its image sigma, when the file states one
};

struct GroundPoint {
  std::string name;
  Eigen::Vector3d xyz;  // in the file's CRS, normalised axis order; z NaN when horizontal_only
  bool horizontal_only = false;  // geo_z "nan" or "-": no surveyed height
  std::optional<double> sigma_h_m;
  std::optional<double> sigma_v_m;
  std::optional<Eigen::Vector3d> sigma_xyz_m;  // on the CRS's axes
  std::vector<GcpMeasurement> measurements;
  int first_line = 0;
};

struct GcpFile {
  std::string path;
  std::string crs;  // the first line
  int crs_line = 0;  // its line number (comments and blank lines may precede it)
  bool coordinates_only = false;  // surveyed positions without marks in the photos
  std::vector<GroundPoint> points;
};

GcpFile ReadGcpFile(const std::filesystem::path& path,
                    PixelOrigin origin = PixelOrigin::kCentre);

// Checks that PROJ knows the file's CRS line (ReadGcpFile only tokenises, so
// that parsing stays cheap); throws ParseError naming the file and the line.
void CheckGcpFileCrs(const GcpFile& file);

// Check points are independent of the control: none has a control point's
// name, and none lies within 3 sigma of a control point (horizontally, and
// vertically where both have heights; each point's sigmas from its file,
// else the defaults), compared in metres through WGS84 (in a local frame,
// in its own coordinates). Throws UsageError naming the pairs: the control
// file passed again as the check file would judge the control against
// itself and report that as independent accuracy.
void CheckChecksIndependent(const GcpFile& control, const GcpFile& checks, double default_sigma_h_m,
                            double default_sigma_v_m);

// Writes points back in the same format (OpenDroneMap's pixel convention,
// PixelOrigin::kCentre), atomically.
void WriteGcpFile(const GcpFile& file, const std::filesystem::path& path);

// The fields of a gcp_list.txt line that WriteGcpFile writes for a point:
// "x y z" (12 significant digits), and its sigmas (" sigma_h=… sigma_v=…",
// empty when the file gave none). The review page (libphoto/report/
// review_page.h) writes its lines from them.
std::string GcpCoordinatesText(const GroundPoint& point);
std::string GcpSigmasText(const GroundPoint& point);

}  // namespace aerotri
