// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ingest/gps_sources.h"

#include <charconv>
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
    if (m.rtk_std_lat_m && m.rtk_std_lon_m && m.rtk_std_hgt_m && *m.rtk_std_lat_m > 0 &&
        *m.rtk_std_lon_m > 0 && *m.rtk_std_hgt_m > 0) {
      fix.sigma_h_m = std::hypot(*m.rtk_std_lat_m, *m.rtk_std_lon_m) / std::sqrt(2.0);
      fix.sigma_v_m = *m.rtk_std_hgt_m;
      fix.source = "exif+rtk";
    }
    fixes[name] = fix;
  }
  return fixes;
}

std::map<std::string, GpsFix> ReadGpsCsv(const std::filesystem::path& path,
                                         AltitudeReference reference, double sigma_h_m,
                                         double sigma_v_m) {
  const std::string text = ReadTextFile(path);
  const std::string p = path.string();
  std::map<std::string, GpsFix> fixes;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  bool first = true;
  while (std::getline(in, line)) {
    ++number;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const std::vector<std::string> f = SplitFields(line);
    if (f.empty()) continue;
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

}  // namespace aerotri
