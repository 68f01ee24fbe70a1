// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ingest/gps_sources.h"

#include <Eigen/Core>
#include <algorithm>
#include <charconv>
#include <optional>
#include <cmath>
#include <sstream>

#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/ingest/image_metadata.h"

namespace aerotri {
namespace {

std::optional<double> ParseDouble(const std::string& token) {
  double value = 0.0;
  const auto [next, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || next != token.data() + token.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::vector<std::string> SplitFields(const std::string& line) {
  std::string s = line;
  for (char& c : s) {
    if (c == ',' || c == ';' || c == '\t') c = ' ';
  }
  std::istringstream in(s);
  std::vector<std::string> out;
  std::string t;
  while (in >> t) out.push_back(t);
  return out;
}

}  // namespace

std::map<std::string, GpsFix> GpsFromImages(const std::vector<std::string>& image_names,
                                            const std::filesystem::path& images_dir,
                                            AltitudeReference reference, double sigma_h_m,
                                            double sigma_v_m, std::vector<std::string>* warnings) {
  std::map<std::string, GpsFix> fixes;
  for (const std::string& name : image_names) {
    const auto path = images_dir / name;
    ImageMetadata m;
    try {
      m = ReadImageMetadata(path);
    } catch (const IoError& e) {
      if (warnings) warnings->push_back(std::string(e.what()) + "; no GPS prior for this image");
      continue;
    }
    if (!m.HasGps() || !m.gps_altitude_m) {
      if (warnings) warnings->push_back(path.string() + ": no EXIF GPS position; no GPS prior");
      continue;
    }
    GpsFix fix;
    fix.position = {*m.lat_deg, *m.lon_deg,
                    EllipsoidalHeight(*m.lat_deg, *m.lon_deg, *m.gps_altitude_m, reference)};
    fix.sigma_h_m = sigma_h_m;
    fix.sigma_v_m = sigma_v_m;
    fix.source = "exif";
    if (const auto stated = GpsSigmasStatedBy(m)) {
      fix.sigma_h_m = stated->h_m;
      fix.sigma_v_m = stated->v_m;
      fix.source = stated->source;
    }
    fixes[name] = fix;
  }
  return fixes;
}

namespace {

std::string Trimmed(const std::string& line) {
  const size_t a = line.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return line.substr(a, line.find_last_not_of(" \t\r") - a + 1);
}

// The CRS of an OpenDroneMap geo.txt, when `line` (the file's first
// meaningful line) is one: PROJ takes it, and it is not a CSV row or header.
std::optional<Crs> GeoTxtCrs(const std::string& line, const CrsResolver& resolve) {
  if (line.find_first_of(",;\t") != std::string::npos) return std::nullopt;
  std::istringstream words(line);
  std::string first, second;
  words >> first >> second;
  if (!second.empty() && ParseDouble(second)) return std::nullopt;  // "IMG_1.JPG 46.8 ..."
  return resolve(line);
}

// geo.txt: `image_name geo_x geo_y geo_z [yaw pitch roll] [horz_accuracy
// vert_accuracy] [extras...]` in `crs` (OpenDroneMap's documentation).
std::map<std::string, GpsFix> ReadGeoTxt(const std::vector<std::pair<int, std::string>>& lines, const Crs& crs,
                                         const std::string& p, int crs_line, AltitudeReference reference,
                                         double sigma_h_m, double sigma_v_m) {
  (void)crs_line;
  std::map<std::string, GpsFix> fixes;
  for (const auto& [number, line] : lines) {
    std::istringstream in(line);
    std::vector<std::string> f;
    for (std::string t; in >> t;) f.push_back(t);
    if (f.size() < 4) {
      throw ParseError(p, number, "expected 'image_name geo_x geo_y geo_z [yaw pitch roll] [horz_accuracy "
                                  "vert_accuracy]' (aerotri needs each camera's height), got " +
                                      std::to_string(f.size()) + " columns");
    }
    static const char* kNames[] = {"", "geo_x", "geo_y", "geo_z", "yaw", "pitch", "roll", "horz_accuracy",
                                   "vert_accuracy"};
    double v[9] = {0, 0, 0, 0, 0, 0, 0, sigma_h_m, sigma_v_m};
    // Columns 5-9 are numbers when present; a 10th and beyond are extras.
    const size_t numeric = std::min<size_t>(f.size(), 9);
    for (size_t i = 1; i < numeric; ++i) {
      const auto value = ParseDouble(f[i]);
      if (!value) {
        throw ParseError(p, number, std::string("expected a number for ") + kNames[i] + " (column " +
                                        std::to_string(i + 1) + "), got '" + f[i] + "'");
      }
      v[i] = *value;
    }
    if (numeric == 8) {
      throw ParseError(p, number, "expected both horz_accuracy and vert_accuracy (columns 8 and 9), got only one");
    }
    if (!(v[7] > 0.0) || !(v[8] > 0.0)) {
      throw ParseError(p, number, "expected positive accuracies (m), got " + f[7] + ", " + f[8]);
    }
    Geodetic g;
    try {
      g = crs.ToGeodetic(Eigen::Vector3d(v[1], v[2], v[3]));
    } catch (const CrsError& e) {
      throw ParseError(p, number, std::string("cannot convert the position to WGS84: ") + e.what());
    }
    if (!crs.IsLocal() && (!std::isfinite(g.lat_deg) || !std::isfinite(g.lon_deg) || std::abs(g.lat_deg) > 90.0)) {
      throw ParseError(p, number, "the position " + f[1] + " " + f[2] + " is not a place on Earth in " + crs.Name());
    }
    if (fixes.count(f[0])) throw ParseError(p, number, "image '" + f[0] + "' appears twice");
    GpsFix fix;
    // A CRS with a vertical datum gives ellipsoidal heights through PROJ; a
    // 2D one leaves geo_z an altitude in the --gps-altitude reference.
    if (crs.IsLocal()) {
      // No geodesy: the stand-in's position keeps distances for neighbour
      // search; the adjustment takes the frame's own coordinates.
      fix.position = g;
      fix.local_xyz = Eigen::Vector3d(v[1], v[2], v[3]);
      fix.local_unit_m = crs.LocalUnitMetres();
    } else {
      fix.position = {g.lat_deg, g.lon_deg,
                      crs.HasVerticalDatum() ? g.h_m : EllipsoidalHeight(g.lat_deg, g.lon_deg, v[3], reference)};
    }
    fix.sigma_h_m = v[7];
    fix.sigma_v_m = v[8];
    fix.source = "geo.txt";
    fixes[f[0]] = fix;
  }
  return fixes;
}

std::map<std::string, GpsFix> ReadCsvLines(const std::vector<std::pair<int, std::string>>& lines,
                                              const std::string& p, AltitudeReference reference, double sigma_h_m,
                                              double sigma_v_m) {
  std::map<std::string, GpsFix> fixes;
  bool first = true;
  for (const auto& [number, line] : lines) {
    const std::vector<std::string> f = SplitFields(line);
    if (first && f.size() >= 2 && !ParseDouble(f[1])) {
      first = false;
      continue;  // header
    }
    first = false;
    if (f.size() != 4 && f.size() != 6) {
      throw ParseError(p, number, "expected 4 or 6 fields 'name,lat,lon,alt[,sigma_h,sigma_v]', got " +
                                      std::to_string(f.size()));
    }
    static const char* kNames[] = {"", "lat", "lon", "alt", "sigma_h", "sigma_v"};
    double v[6] = {0, 0, 0, 0, sigma_h_m, sigma_v_m};
    for (size_t i = 1; i < f.size(); ++i) {
      const auto value = ParseDouble(f[i]);
      if (!value) {
        throw ParseError(p, number, std::string("expected a number for ") + kNames[i] + ", got '" +
                                        f[i] + "'");
      }
      v[i] = *value;
    }
    if (std::abs(v[1]) > 90.0 || std::abs(v[2]) > 180.0) {
      throw ParseError(p, number, "expected lat in [-90, 90] and lon in [-180, 180] degrees, got " +
                                      f[1] + ", " + f[2]);
    }
    if (!(v[4] > 0.0) || !(v[5] > 0.0)) {
      throw ParseError(p, number, "expected positive sigmas (m), got " + f[4] + ", " + f[5]);
    }
    if (fixes.count(f[0])) {
      throw ParseError(p, number, "image '" + f[0] + "' appears twice");
    }
    GpsFix fix;
    fix.position = {v[1], v[2], EllipsoidalHeight(v[1], v[2], v[3], reference)};
    fix.sigma_h_m = v[4];
    fix.sigma_v_m = v[5];
    fix.source = "csv";
    fixes[f[0]] = fix;
  }
  return fixes;
}

}  // namespace

std::map<std::string, GpsFix> ReadGpsFile(const std::filesystem::path& path, AltitudeReference reference,
                                          double sigma_h_m, double sigma_v_m) {
  const CrsResolver proj = [](const std::string& definition) -> std::optional<Crs> {
    try {
      return Crs::FromString(definition);
    } catch (const CrsError&) {
      return std::nullopt;
    }
  };
  return ParseGpsText(ReadTextFile(path), path.string(), reference, sigma_h_m, sigma_v_m, proj);
}

std::map<std::string, GpsFix> ParseGpsText(std::string text, const std::string& p, AltitudeReference reference,
                                           double sigma_h_m, double sigma_v_m, const CrsResolver& resolve) {
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);  // a UTF-8 byte-order mark
  for (size_t k = 0; k < text.size(); ++k) {                   // CR alone ends a line too
    if (text[k] == '\r' && (k + 1 == text.size() || text[k + 1] != '\n')) text[k] = '\n';
  }
  std::vector<std::pair<int, std::string>> lines;  // (line number, content without comment)
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    line = Trimmed(line);
    if (!line.empty()) lines.emplace_back(number, line);
  }
  if (!lines.empty()) {
    if (const auto crs = GeoTxtCrs(lines.front().second, resolve)) {
      const int crs_line = lines.front().first;
      lines.erase(lines.begin());
      return ReadGeoTxt(lines, *crs, p, crs_line, reference, sigma_h_m, sigma_v_m);
    }
  }
  return ReadCsvLines(lines, p, reference, sigma_h_m, sigma_v_m);
}

}  // namespace aerotri
