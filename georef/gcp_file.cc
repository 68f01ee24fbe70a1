// SPDX-License-Identifier: BSD-3-Clause
#include "georef/gcp_file.h"

#include <charconv>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>

#include "georef/crs.h"
#include "georef/local_frame.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {
namespace {

std::vector<std::string> SplitWhitespace(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  std::string token;
  while (in >> token) out.push_back(token);
  return out;
}

std::optional<double> ParseNumber(const std::string& token) {
  double value = 0.0;
  const char* begin = token.data();
  // A leading '+' (surveyors' exports write "+384944.8"); from_chars refuses it.
  if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+') ++begin;
  const char* end = token.data() + token.size();
  const auto [next, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || next != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

// The key=value extras after a line's fixed columns (from column `first`);
// the first bare word there is the point's name.
struct PointExtras {
  std::string name;
  std::optional<double> sigma_h, sigma_v, sigma_px;
  std::optional<Eigen::Vector3d> sigma_xyz;
  void ApplyTo(GroundPoint* point) const {
    if (sigma_h) point->sigma_h_m = sigma_h;
    if (sigma_v) point->sigma_v_m = sigma_v;
    if (sigma_xyz) point->sigma_xyz_m = sigma_xyz;
  }
};

PointExtras ParseExtras(const std::vector<std::string>& cols, size_t first, const std::string& p, int number) {
  PointExtras out;
  std::optional<double> sigma_axis[3];
  for (size_t c = first; c < cols.size(); ++c) {
    const std::string& extra = cols[c];
    const size_t eq = extra.find('=');
    if (eq != std::string::npos) {
      const std::string key = extra.substr(0, eq);
      std::optional<double>* target = key == "sigma_h"    ? &out.sigma_h
                                      : key == "sigma_v"  ? &out.sigma_v
                                      : key == "sigma_x"  ? &sigma_axis[0]
                                      : key == "sigma_y"  ? &sigma_axis[1]
                                      : key == "sigma_z"  ? &sigma_axis[2]
                                      : key == "sigma_px" ? &out.sigma_px
                                                          : nullptr;
      if (target) {
        const auto value = ParseNumber(extra.substr(eq + 1));
        if (!value || !(*value > 0.0) || !std::isfinite(*value)) {
          throw ParseError(p, number, "expected a positive number of " +
                                          std::string(key == "sigma_px" ? "pixels" : "metres") + " for " + key +
                                          ", got '" + extra.substr(eq + 1) + "'");
        }
        *target = *value;
      }
      continue;
    }
    if (c == first) out.name = extra;
  }
  const int axes = sigma_axis[0].has_value() + sigma_axis[1].has_value() + sigma_axis[2].has_value();
  if (axes != 0 && axes != 3) {
    throw ParseError(p, number, "expected sigma_x, sigma_y and sigma_z together, got " + std::to_string(axes) +
                                    " of them");
  }
  if (axes == 3) out.sigma_xyz = Eigen::Vector3d(*sigma_axis[0], *sigma_axis[1], *sigma_axis[2]);
  return out;
}

// geo_z: a number, or "nan" / "-" for a point surveyed in plan only.
std::optional<double> ParseHeight(const std::string& token, bool* no_height) {
  std::string z = token;
  for (char& c : z) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  *no_height = z == "nan" || z == "-";
  if (*no_height) return std::numeric_limits<double>::quiet_NaN();
  return ParseNumber(token);
}

// A line of a coordinates-only file: "name x y z [extras]" (whitespace) or
// PIX4D's "label,x,y,z[,acc_h,acc_v]". std::nullopt when the line is not
// one (a measurement line).
std::optional<std::vector<std::string>> CoordinateColumns(const std::string& line) {
  if (line.find(',') != std::string::npos) {
    std::vector<std::string> cols;
    std::string cell;
    std::istringstream in(line);
    while (std::getline(in, cell, ',')) cols.push_back(Trim(cell));
    if (!line.empty() && line.back() == ',') cols.push_back("");
    return cols;
  }
  std::vector<std::string> cols = SplitWhitespace(line);
  // A name first (not a number), then three coordinates and extras only.
  if (cols.size() < 4 || ParseNumber(cols[0])) return std::nullopt;
  for (size_t c = 4; c < cols.size(); ++c) {
    if (cols[c].find('=') == std::string::npos) return std::nullopt;
  }
  return cols;
}

GroundPoint ReadCoordinateLine(const std::vector<std::string>& cols, bool csv, const std::string& p, int number) {
  static const char* kExpected = "'name x y z [sigma_h= sigma_v= | sigma_x= sigma_y= sigma_z=]' or PIX4D's "
                                 "'label,x,y,z[,acc_h,acc_v]'";
  if (cols.size() < 4 || (csv && cols.size() > 6)) {
    throw ParseError(p, number, std::string("expected ") + kExpected + ", got " + std::to_string(cols.size()) +
                                    (csv ? " comma-separated fields" : " columns"));
  }
  GroundPoint point;
  point.name = cols[0];
  point.first_line = number;
  if (point.name.empty()) throw ParseError(p, number, "expected a point name in the first field, got an empty one");
  static const char* kNames[] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    bool no_height = false;
    const auto value = i == 2 ? ParseHeight(cols[3], &no_height) : ParseNumber(cols[i + 1]);
    if (!value) {
      throw ParseError(p, number, std::string("expected a number for ") + kNames[i] + " (field " +
                                      std::to_string(i + 2) + ")" + (i == 2 ? " or 'nan' (no surveyed height)" : "") +
                                      ", got '" + cols[i + 1] + "'");
    }
    point.xyz[i] = *value;
    if (i == 2) point.horizontal_only = no_height;
  }
  if (csv) {
    static const char* kAcc[] = {"acc_h", "acc_v"};
    for (size_t c = 4; c < cols.size(); ++c) {
      if (cols[c].empty()) continue;
      const auto value = ParseNumber(cols[c]);
      if (!value || !(*value > 0.0)) {
        throw ParseError(p, number, std::string("expected a positive number of metres for ") + kAcc[c - 4] +
                                        " (field " + std::to_string(c + 1) + "), got '" + cols[c] + "'");
      }
      (c == 4 ? point.sigma_h_m : point.sigma_v_m) = *value;
    }
  } else {
    ParseExtras(cols, 4, p, number).ApplyTo(&point);
  }
  return point;
}

}  // namespace

GcpFile ReadGcpFile(const std::filesystem::path& path, PixelOrigin origin) {
  std::string text = ReadTextFile(path);
  // A UTF-8 byte-order mark (spreadsheet exports) is not part of the CRS.
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
  // Old Mac line endings (CR alone) end lines too; CR LF stays one ending.
  for (size_t k = 0; k < text.size(); ++k) {
    if (text[k] == '\r' && (k + 1 == text.size() || text[k + 1] != '\n')) text[k] = '\n';
  }
  const std::string p = path.string();
  GcpFile file;
  file.path = p;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  std::map<std::string, size_t> by_name;
  const double shift = origin == PixelOrigin::kCorner ? 0.5 : 0.0;
  static const char* kColumns = "'geo_x geo_y geo_z im_x im_y image_name [gcp_name]'";
  int first_point_line = 0;

  while (std::getline(in, line)) {
    ++number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    if (file.crs.empty()) {
      file.crs = trimmed;
      file.crs_line = number;
      if (SplitWhitespace(trimmed).size() >= 6 && ParseNumber(SplitWhitespace(trimmed)[0])) {
        throw ParseError(p, number, "expected a CRS on the first line (e.g. EPSG:32632), got "
                                    "a measurement line");
      }
      continue;
    }
    // The first point line decides the file's kind: marks (pixel columns)
    // or coordinates only; the kinds do not mix.
    const std::optional<std::vector<std::string>> coordinates = CoordinateColumns(trimmed);
    if (first_point_line == 0) {
      first_point_line = number;
      file.coordinates_only = coordinates.has_value();
      // PIX4D's CSV may open with a header row (label,x,y,z,...).
      if (coordinates && trimmed.find(',') != std::string::npos && coordinates->size() >= 4 &&
          !ParseNumber((*coordinates)[1]) && !ParseNumber((*coordinates)[2])) {
        first_point_line = 0;
        continue;
      }
    }
    if (file.coordinates_only) {
      if (!coordinates) {
        throw ParseError(p, number, "expected a coordinates-only line 'name x y z [sigmas]' as on line " +
                                        std::to_string(first_point_line) + ", got a line with pixel columns; give "
                                        "the marks in a file of their own");
      }
      GroundPoint point = ReadCoordinateLine(*coordinates, trimmed.find(',') != std::string::npos, p, number);
      if (const auto it = by_name.find(point.name); it != by_name.end()) {
        throw ParseError(p, number, "point '" + point.name + "' is listed twice (first on line " +
                                        std::to_string(file.points[it->second].first_line) + ")");
      }
      by_name[point.name] = file.points.size();
      file.points.push_back(std::move(point));
      continue;
    }
    const std::vector<std::string> cols = SplitWhitespace(trimmed);
    if (cols.size() < 6) {
      throw ParseError(p, number, "expected at least 6 columns " + std::string(kColumns) +
                                      ", got " + std::to_string(cols.size()));
    }
    static const char* kNames[] = {"geo_x", "geo_y", "geo_z", "im_x", "im_y"};
    double v[5];
    bool no_height = false;
    for (int i = 0; i < 5; ++i) {
      if (i == 2) {
        std::string z = cols[2];
        for (char& c : z) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        if (z == "nan" || z == "-") {
          no_height = true;
          v[2] = std::numeric_limits<double>::quiet_NaN();
          continue;
        }
      }
      const auto value = ParseNumber(cols[i]);
      if (!value) {
        throw ParseError(p, number, std::string("expected a number for ") + kNames[i] +
                                        " (column " + std::to_string(i + 1) + ")" +
                                        (i == 2 ? " or 'nan' (no surveyed height)" : "") + ", got '" + cols[i] + "'");
      }
      v[i] = *value;
    }
    // The image's outer edge: -0.5 when integers are pixel centres, 0 when
    // they are pixel corners.
    const double edge = origin == PixelOrigin::kCentre ? -0.5 : 0.0;
    if (v[3] < edge || v[4] < edge) {
      throw ParseError(p, number, std::string("expected pixel coordinates >= ") +
                                      (edge < 0 ? "-0.5 (the top-left pixel's outer edge)" : "0") +
                                      ", got im_x " + cols[3] + " im_y " + cols[4]);
    }
    const Eigen::Vector3d xyz(v[0], v[1], v[2]);
    PointExtras extras = ParseExtras(cols, 6, p, number);
    std::string name = extras.name;
    if (name.empty()) {
      std::ostringstream key;
      key << std::setprecision(12) << "point@" << xyz.x() << "," << xyz.y() << "," << xyz.z();
      name = key.str();
    }
    auto it = by_name.find(name);
    if (it == by_name.end()) {
      GroundPoint point;
      point.name = name;
      point.xyz = xyz;
      point.horizontal_only = no_height;
      point.first_line = number;
      by_name[name] = file.points.size();
      file.points.push_back(point);
      it = by_name.find(name);
    }
    GroundPoint& point = file.points[it->second];
    // One point, one position: to a millimetre (1e-8 for what may be
    // degrees), not relatively (1e-6 of a UTM northing is 5 m).
    const bool degrees = std::abs(xyz.x()) <= 360.0 && std::abs(xyz.y()) <= 360.0;
    const double tol_xy = degrees ? 1e-8 : 1e-3;
    const bool same_z = point.horizontal_only || no_height ? point.horizontal_only == no_height
                                                           : std::abs(point.xyz.z() - xyz.z()) <= 1e-3;
    if (std::abs(point.xyz.x() - xyz.x()) > tol_xy || std::abs(point.xyz.y() - xyz.y()) > tol_xy || !same_z) {
      throw ParseError(p, number, "point '" + name + "' has other coordinates here than on line " +
                                      std::to_string(point.first_line));
    }
    extras.ApplyTo(&point);
    point.measurements.push_back({cols[5], Eigen::Vector2d(v[3] - shift, v[4] - shift), number, extras.sigma_px});
  }
  if (file.crs.empty()) throw ParseError(p, 0, "empty file: expected a CRS on the first line");
  if (file.points.empty()) {
    throw ParseError(p, file.crs_line, "no point lines after the CRS line: expected lines " + std::string(kColumns) +
                                           ", or coordinates only ('name x y z')");
  }
  return file;
}

std::string GcpCoordinatesText(const GroundPoint& point) {
  std::ostringstream out;
  out << std::setprecision(12) << point.xyz.x() << " " << point.xyz.y() << " " << point.xyz.z();
  return out.str();
}

std::string GcpSigmasText(const GroundPoint& point) {
  std::ostringstream out;
  out << std::setprecision(12);
  if (point.sigma_h_m) out << " sigma_h=" << *point.sigma_h_m;
  if (point.sigma_v_m) out << " sigma_v=" << *point.sigma_v_m;
  if (point.sigma_xyz_m) {
    out << " sigma_x=" << point.sigma_xyz_m->x() << " sigma_y=" << point.sigma_xyz_m->y()
        << " sigma_z=" << point.sigma_xyz_m->z();
  }
  return out.str();
}

void WriteGcpFile(const GcpFile& file, const std::filesystem::path& path) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << file.crs << "\n";
    for (const GroundPoint& point : file.points) {
      const std::string coordinates = GcpCoordinatesText(point), sigmas = GcpSigmasText(point);
      for (const GcpMeasurement& m : point.measurements) {
        out << coordinates << " " << std::setprecision(8) << m.xy_px.x() << " " << m.xy_px.y() << " "
            << m.image << " " << point.name << sigmas;
        if (m.sigma_px) out << " sigma_px=" << std::setprecision(12) << *m.sigma_px;
        out << "\n";
      }
    }
  });
}

void CheckGcpFileCrs(const GcpFile& file) {
  try {
    Crs::FromString(file.crs);
  } catch (const CrsError& e) {
    throw ParseError(file.path, file.crs_line, std::string("the CRS line is not a CRS PROJ knows: ") + e.what());
  }
}

namespace {

// A surveyed point in metres about a reference: ENU through WGS84, or a
// local frame's own coordinates; none where the CRS cannot place it.
std::optional<Eigen::Vector3d> MetresOf(const GroundPoint& p, const Crs& crs, const std::optional<LocalFrame>& frame) {
  if (!frame) return p.xyz;
  Eigen::Vector3d xyz = p.xyz;
  if (p.horizontal_only) xyz.z() = 0.0;
  try {
    return frame->EnuFromGeodetic(crs.ToGeodetic(xyz));
  } catch (const Error&) {
    return std::nullopt;
  }
}

Eigen::Vector2d SigmasOf(const GroundPoint& p, double default_h, double default_v) {
  if (p.sigma_xyz_m) return {std::max(p.sigma_xyz_m->x(), p.sigma_xyz_m->y()), p.sigma_xyz_m->z()};
  return {p.sigma_h_m.value_or(default_h), p.sigma_v_m.value_or(default_v)};
}

}  // namespace

void CheckChecksIndependent(const GcpFile& control, const GcpFile& checks, double default_sigma_h_m,
                            double default_sigma_v_m) {
  if (control.points.empty() || checks.points.empty()) return;
  const Crs control_crs = Crs::FromString(control.crs), check_crs = Crs::FromString(checks.crs);
  const bool local = control_crs.IsLocal() || check_crs.IsLocal();
  if (local && control.crs != checks.crs) return;  // frames that cannot meet: refused elsewhere
  std::optional<LocalFrame> frame;
  if (!local) {
    for (const GroundPoint& p : control.points) {
      Eigen::Vector3d xyz = p.xyz;
      if (p.horizontal_only) xyz.z() = 0.0;
      try {
        frame.emplace(control_crs.ToGeodetic(xyz));
        break;
      } catch (const Error&) {
      }
    }
    if (!frame) return;
  }
  std::vector<std::string> pairs;
  for (const GroundPoint& k : checks.points) {
    const std::optional<Eigen::Vector3d> at_k = MetresOf(k, check_crs, frame);
    for (const GroundPoint& c : control.points) {
      if (c.name == k.name) {
        pairs.push_back(k.name + " (the same name)");
        break;
      }
      const std::optional<Eigen::Vector3d> at_c = MetresOf(c, control_crs, frame);
      if (!at_k || !at_c) continue;
      const Eigen::Vector2d sk = SigmasOf(k, default_sigma_h_m, default_sigma_v_m);
      const Eigen::Vector2d sc = SigmasOf(c, default_sigma_h_m, default_sigma_v_m);
      const Eigen::Vector3d d = *at_k - *at_c;
      const bool heights = !k.horizontal_only && !c.horizontal_only;
      if (d.head<2>().norm() <= 3.0 * std::hypot(sk.x(), sc.x()) &&
          (!heights || std::abs(d.z()) <= 3.0 * std::hypot(sk.y(), sc.y()))) {
        char text[96];
        std::snprintf(text, sizeof text, " (%.3f m from control point ", d.norm());
        pairs.push_back(k.name + text + c.name + ")");
        break;
      }
    }
  }
  if (pairs.empty()) return;
  std::string list;
  for (size_t n = 0; n < pairs.size() && n < 10; ++n) list += (n ? ", " : "") + pairs[n];
  if (pairs.size() > 10) list += " (and " + std::to_string(pairs.size() - 10) + " more)";
  throw UsageError(checks.path + ": " + std::to_string(pairs.size()) + " of its " +
                   std::to_string(checks.points.size()) + " check points are control points of " + control.path +
                   " too: " + list + ". A check point tests the survey only if the adjustment never saw it; give "
                   "independent check points, or leave these out of one of the files");
}

}  // namespace aerotri
