// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ingest/ingest.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>

#include "camera_models/exif_intrinsics.h"
#include "libphoto/base/error.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/ingest/image_metadata.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;

void IngestOptions::Check() const {
  if (images_dir.empty()) throw InvalidArgument("ingest: no photo folder given");
  if (!(gps_sigma_h_m > 0.0) || !std::isfinite(gps_sigma_h_m)) {
    throw InvalidArgument("--gps-sigma-h: expected a positive number of metres, got " +
                          std::to_string(gps_sigma_h_m));
  }
  if (!(gps_sigma_v_m > 0.0) || !std::isfinite(gps_sigma_v_m)) {
    throw InvalidArgument("--gps-sigma-v: expected a positive number of metres, got " +
                          std::to_string(gps_sigma_v_m));
  }
  if (max_dimension < 0) {
    throw InvalidArgument("--max-dimension: expected 0 (full size) or a positive number of pixels, got " +
                          std::to_string(max_dimension));
  }
}

namespace {

// The GPS fix of one photo: the CSV's row, else EXIF (RTK sigmas when tagged).
// The XMP a photo carries about its camera, tag by tag, the vendors named.
json CameraSays(const ImageMetadata& m) {
  json j = json::object();
  if (m.xmp_sources.empty()) return j;
  j["sources"] = m.xmp_sources;
  auto put = [&](const char* key, const std::optional<double>& v) {
    if (v) j[key] = *v;
  };
  put("flight_pitch_deg", m.flight_pitch_deg);
  put("flight_roll_deg", m.flight_roll_deg);
  put("flight_yaw_deg", m.flight_yaw_deg);
  if (m.flight_speed_x_mps && m.flight_speed_y_mps && m.flight_speed_z_mps) {
    j["flight_speed_mps"] = {*m.flight_speed_x_mps, *m.flight_speed_y_mps, *m.flight_speed_z_mps};
  }
  put("calibrated_focal_px", m.calibrated_focal_px);
  put("calibrated_cx_px", m.calibrated_cx_px);
  put("calibrated_cy_px", m.calibrated_cy_px);
  put("rtk_std_lat_m", m.rtk_std_lat_m);
  put("rtk_std_lon_m", m.rtk_std_lon_m);
  put("rtk_std_hgt_m", m.rtk_std_hgt_m);
  put("camera_yaw_deg", m.camera_yaw_deg);
  put("camera_pitch_deg", m.camera_pitch_deg);
  put("camera_roll_deg", m.camera_roll_deg);
  put("gps_xy_accuracy_m", m.gps_xy_accuracy_m);
  put("gps_z_accuracy_m", m.gps_z_accuracy_m);
  put("line_readout_time_s", m.line_readout_time_s);
  if (!m.imu_linear_velocity_mps.empty()) j["imu_linear_velocity_mps"] = m.imu_linear_velocity_mps;
  put("perspective_focal_mm", m.perspective_focal_mm);
  if (!m.principal_point_mm.empty()) j["principal_point_mm"] = m.principal_point_mm;
  if (!m.perspective_distortion.empty()) j["perspective_distortion"] = m.perspective_distortion;
  return j;
}

std::optional<GpsFix> FixOf(const std::string& name, const ImageMetadata& m,
                            const std::map<std::string, GpsFix>& csv, const IngestOptions& o) {
  if (const auto it = csv.find(name); it != csv.end()) {
    GpsFix f = it->second;
    if (!std::isfinite(f.time_s) && m.capture_time_s) f.time_s = *m.capture_time_s;
    return f;
  }
  if (!m.HasGps() || !m.gps_altitude_m || (*m.lat_deg == 0.0 && *m.lon_deg == 0.0)) return std::nullopt;
  GpsFix f;
  f.position = {*m.lat_deg, *m.lon_deg, EllipsoidalHeight(*m.lat_deg, *m.lon_deg, *m.gps_altitude_m, o.gps_altitude)};
  f.sigma_h_m = o.gps_sigma_h_m;
  f.sigma_v_m = o.gps_sigma_v_m;
  f.source = "exif";
  if (m.capture_time_s) f.time_s = *m.capture_time_s;
  if (const auto stated = GpsSigmasStatedBy(m)) {
    f.sigma_h_m = stated->h_m;
    f.sigma_v_m = stated->v_m;
    f.source = stated->source;
  }
  return f;
}

// A JPEG cut short (an interrupted copy, a full card) still decodes: libjpeg
// pads it with grey and says "Premature end of JPEG file" without a name.
// Its end-of-image marker (FF D9) is then missing from the file's tail
// (some cameras pad after it with 00 or FF bytes). "" when whole or not a JPEG.
std::string JpegTruncation(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext != ".jpg" && ext != ".jpeg") return "";
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return "";
  const std::streamoff size = in.tellg();
  const std::streamoff tail = std::min<std::streamoff>(size, 4096);
  std::string bytes(static_cast<size_t>(tail), '\0');
  in.seekg(size - tail);
  if (!in.read(bytes.data(), tail)) return "";
  size_t end = bytes.size();
  while (end > 0 && (bytes[end - 1] == '\0' || bytes[end - 1] == '\xFF')) --end;  // padding
  if (end >= 2 && bytes[end - 2] == '\xFF' && bytes[end - 1] == '\xD9') return "";
  return "truncated JPEG: it does not end with the end-of-image marker FF D9 (" + std::to_string(size) +
         " bytes; an interrupted copy?)";
}

}  // namespace

namespace {

// The image files of a folder, sorted; entries that cannot be followed (a
// symbolic link loop or a missing target) are said, never fatal.
std::vector<fs::path> ImageFilesIn(const fs::path& dir, std::vector<std::string>* dead_links) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!IsImageFileName(entry.path())) continue;
    std::error_code ec;
    const bool regular = entry.is_regular_file(ec);
    if (ec) {
      dead_links->push_back(entry.path().string() + ": " + ec.message() + " (a symbolic link loop or a missing "
                            "target); skipped");
    } else if (regular) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

// A camera group for a key, with its EXIF focal estimate at the working
// size; a focal length not measured is said in *warnings.
CameraGroup NewCameraGroup(const std::string& key, const ImageMetadata& m, int ww, int wh,
                           std::vector<std::string>* warnings) {
  ExifOptics optics;
  optics.make = m.make;
  optics.model = m.model;
  optics.focal_mm = m.focal_mm;
  optics.focal_35mm = m.focal_35mm;
  optics.focal_plane_px_per_mm = m.focal_plane_px_per_mm;
  optics.exif_pixel_width = m.exif_pixel_width;
  optics.width = m.width;
  optics.height = m.height;
  const FocalEstimate focal = FocalFromExif(optics);
  CameraGroup g;
  g.key = key;
  g.make = m.make;
  g.model = m.model;
  g.working_width = ww;
  g.working_height = wh;
  g.camera = Camera::Create(CameraModelId::kBrown, focal.focal_px * ww / m.width, ww, wh);
  g.focal_source = focal.source;
  g.focal_measured = focal.Measured();
  g.pixel_size_mm = focal.pixel_size_mm * m.width / ww;
  // The camera's own factory calibration, where it states one: the start of
  // every adjustment and, as a measured focal length, its prior. A stated
  // focal length more than 10 % from the EXIF-measured one belongs to
  // another image size or unit: said, not used.
  const auto stated = CalibrationStatedBy(m, focal.pixel_size_mm);
  if (stated && focal.Measured() && std::abs(stated->focal_px / focal.focal_px - 1.0) > 0.10) {
    char text[400];
    std::snprintf(text, sizeof text,
                  "camera '%s %s': %s give a focal length of %.1f px, %.0f %% from the EXIF-measured %.1f px (%s); "
                  "not used",
                  m.make.c_str(), m.model.c_str(), stated->source.c_str(), stated->focal_px,
                  100.0 * (stated->focal_px / focal.focal_px - 1.0), focal.focal_px, focal.source.c_str());
    warnings->push_back(text);
  } else if (stated) {
    const double scale = static_cast<double>(ww) / m.width;
    std::vector<double>& p = g.camera.params;
    p[0] = stated->focal_px * scale;
    p[1] = (stated->cx_px + 0.5) * scale - 0.5;
    p[2] = (stated->cy_px + 0.5) * scale - 0.5;
    for (size_t k = 0; k < stated->distortion.size() && 3 + k < p.size(); ++k) p[3 + k] = stated->distortion[k];
    g.focal_source = stated->source;
    g.focal_measured = true;
    g.calibration_stated = true;
    return g;
  }
  if (!focal.Measured()) warnings->push_back("camera '" + m.make + " " + m.model + "': " + focal.source);
  return g;
}

}  // namespace

IngestRecord IngestSurveyImages(const IngestOptions& o, const ProgressCallback& progress) {
  o.Check();
  if (!fs::is_directory(o.images_dir)) throw IoError(o.images_dir.string(), "not a folder of images");
  std::vector<std::string> dead_links;  // a loop or a missing target: said, never fatal
  const std::vector<fs::path> files = ImageFilesIn(o.images_dir, &dead_links);
  if (files.empty()) {
    throw InvalidArgument(o.images_dir.string() + ": no images (.jpg, .jpeg, .tif, .tiff) found");
  }
  std::map<std::string, GpsFix> csv;
  if (!o.gps_csv.empty()) csv = ReadGpsFile(o.gps_csv, o.gps_altitude, o.gps_sigma_h_m, o.gps_sigma_v_m);
  // CSV names are matched to file names exactly: one that matches nothing is
  // said, and a file that matches no photo at all is an error, not ignored.
  std::vector<std::string> unmatched;
  {
    std::set<std::string> names;
    for (const fs::path& f : files) names.insert(f.filename().string());
    for (const auto& [name, fix] : csv) {
      if (!names.count(name)) unmatched.push_back(name);
    }
  }
  const auto first_names = [](const std::vector<std::string>& v) {
    std::string out;
    for (size_t k = 0; k < v.size() && k < 5; ++k) out += (k ? ", " : "") + std::string("'") + v[k] + "'";
    return out + (v.size() > 5 ? " (and " + std::to_string(v.size() - 5) + " more)" : "");
  };
  if (!csv.empty() && unmatched.size() == csv.size()) {
    throw InvalidArgument(o.gps_csv.string() + ": none of its " + std::to_string(csv.size()) + " names (" +
                          first_names(unmatched) + ") is a photo in " + o.images_dir.string() + " (" +
                          "'" + files.front().filename().string() + "', ...); names must equal the file names");
  }

  IngestRecord r;
  r.warnings = dead_links;
  if (!unmatched.empty()) {
    r.warnings.push_back(o.gps_csv.string() + ": " + std::to_string(unmatched.size()) + " of " +
                         std::to_string(csv.size()) + " names match no photo: " + first_names(unmatched));
  }
  r.images_dir = fs::absolute(o.images_dir);
  r.working_max_dimension = o.max_dimension;
  std::map<std::string, int> group_of_key;
  // The group of a camera key, created with its EXIF focal estimate.
  auto group_for = [&](const std::string& key, const ImageMetadata& m, int ww, int wh) {
    auto [it, inserted] = group_of_key.emplace(key, static_cast<int>(r.groups.size()));
    if (inserted) r.groups.push_back(NewCameraGroup(key, m, ww, wh, &r.warnings));
    ++r.groups[it->second].images;
    return it->second;
  };

  std::vector<std::pair<size_t, ImageMetadata>> anonymous;
  std::vector<std::string> without_gps;
  for (size_t k = 0; k < files.size(); ++k) {
    IngestedImage im;
    im.name = files[k].filename().string();
    ImageMetadata m;
    try {
      m = ReadImageMetadata(files[k]);
    } catch (const IoError& e) {
      im.problem = std::string("unreadable: ") + e.what();
      r.warnings.push_back(std::string(e.what()) + "; skipped");
      r.images.push_back(im);
      continue;
    }
    if (const std::string cut = JpegTruncation(files[k]); !cut.empty()) {
      im.problem = cut;
      r.warnings.push_back(files[k].string() + ": " + cut + "; skipped");
      r.images.push_back(im);
      continue;
    }
    im.usable = true;
    im.width = m.width;
    im.height = m.height;
    std::tie(im.working_width, im.working_height) = WorkingImageSize(m.width, m.height, o.max_dimension);
    im.scale = static_cast<double>(m.width) / im.working_width;
    im.make = m.make;
    im.model = m.model;
    im.focal_mm = m.focal_mm;
    im.relative_altitude_m = m.relative_altitude_m;
    im.gimbal_pitch_deg = m.gimbal_pitch_deg;
    im.gimbal_yaw_deg = m.gimbal_yaw_deg;
    im.capture_time_s = m.capture_time_s;
    im.camera_says = CameraSays(m);
    im.gps = FixOf(im.name, m, csv, o);
    if (im.gps) {
      ++r.images_with_gps;
    } else {
      without_gps.push_back(im.name);
    }
    // A photo that says nothing of its camera is placed once every photo is read.
    if (m.make.empty() && m.model.empty() && !m.focal_mm && !m.focal_35mm) {
      anonymous.push_back({r.images.size(), m});
    } else {
      std::ostringstream key;
      key << m.make << "|" << m.model << "|" << std::setprecision(4) << m.focal_mm.value_or(0.0) << "|"
          << im.working_width << "x" << im.working_height;
      im.group = group_for(key.str(), m, im.working_width, im.working_height);
    }
    r.images.push_back(im);
    ReportProgress(progress, static_cast<double>(k + 1) / files.size(), im.name);
  }
  // A set flown without GPS is one fact, not one per photo.
  if (r.images_with_gps == 0 && without_gps.size() > 1) {
    r.warnings.push_back("none of the " + std::to_string(without_gps.size()) +
                         " photos has a GPS position (EXIF or CSV): the survey is placed by its control alone, or "
                         "not at all");
  } else {
    for (const std::string& name : without_gps) r.warnings.push_back(name + ": no GPS position (EXIF or CSV)");
  }
  for (const auto& [index, m] : anonymous) {
    IngestedImage& im = r.images[index];
    int match = -1, count = 0;
    for (size_t g = 0; g < r.groups.size(); ++g) {
      if (r.groups[g].working_width == im.working_width && r.groups[g].working_height == im.working_height) {
        match = static_cast<int>(g);
        ++count;
      }
    }
    if (count == 1) {
      im.group = match;
      ++r.groups[match].images;
      r.warnings.push_back(im.name + ": no EXIF camera information; assumed to be the " + r.groups[match].make +
                           " " + r.groups[match].model + " of the other photos of this size");
    } else {
      std::ostringstream key;
      key << "unknown camera|" << im.working_width << "x" << im.working_height;
      im.group = group_for(key.str(), m, im.working_width, im.working_height);
    }
  }
  return r;
}

json ToJson(const IngestRecord& r) {
  json images = json::array();
  for (const IngestedImage& i : r.images) {
    json im;
    im["name"] = i.name;
    im["usable"] = i.usable;
    if (!i.usable) {
      im["problem"] = i.problem;
      images.push_back(im);
      continue;
    }
    im["width"] = i.width;
    im["height"] = i.height;
    im["working_width"] = i.working_width;
    im["working_height"] = i.working_height;
    im["scale"] = i.scale;
    im["make"] = i.make;
    im["model"] = i.model;
    if (i.focal_mm) im["focal_mm"] = *i.focal_mm;
    if (i.relative_altitude_m) im["relative_altitude_m"] = *i.relative_altitude_m;
    if (i.gimbal_pitch_deg) im["gimbal_pitch_deg"] = *i.gimbal_pitch_deg;
    if (i.gimbal_yaw_deg) im["gimbal_yaw_deg"] = *i.gimbal_yaw_deg;
    if (i.capture_time_s) im["capture_time_s"] = *i.capture_time_s;
    if (!i.camera_says.empty()) im["camera_says"] = i.camera_says;
    if (i.gps) {
      im["gps"] = {{"lat_deg", i.gps->position.lat_deg}, {"lon_deg", i.gps->position.lon_deg},
                   {"h_m", i.gps->position.h_m},         {"sigma_h_m", i.gps->sigma_h_m},
                   {"sigma_v_m", i.gps->sigma_v_m},       {"source", i.gps->source}};
      if (std::isfinite(i.gps->time_s)) im["gps"]["time_s"] = i.gps->time_s;
    } else {
      im["gps"] = nullptr;
    }
    im["group"] = i.group;
    images.push_back(im);
  }
  json groups = json::array();
  for (const CameraGroup& g : r.groups) {
    groups.push_back({{"key", g.key},
                      {"make", g.make},
                      {"model", g.model},
                      {"working_width", g.working_width},
                      {"working_height", g.working_height},
                      {"camera_model", "BROWN"},
                      {"params", g.camera.params},
                      {"focal_source", g.focal_source},
                      {"focal_measured", g.focal_measured},
                      {"calibration_stated", g.calibration_stated},
                      {"images", g.images}});
    if (g.pixel_size_mm > 0) groups.back()["pixel_size_mm"] = g.pixel_size_mm;
  }
  json doc;
  doc["schema_version"] = IngestRecord::kSchemaVersion;
  doc["images_dir"] = r.images_dir.string();
  doc["options"] = r.options;
  doc["working_max_dimension"] = r.working_max_dimension;
  doc["images"] = images;
  doc["groups"] = groups;
  doc["warnings"] = r.warnings;
  doc["images_with_gps"] = r.images_with_gps;
  // Which vendors' XMP the photos carry, and in how many.
  json camera_metadata = json::object();
  for (const IngestedImage& i : r.images) {
    for (const json& source : i.camera_says.value("sources", json::array())) {
      camera_metadata[source.get<std::string>()] = camera_metadata.value(source.get<std::string>(), 0) + 1;
    }
  }
  doc["camera_metadata"] = camera_metadata;
  return doc;
}

IngestRecord IngestRecordFromJson(const json& doc, const std::string& path) {
  const int version = doc.is_object() ? doc.value("schema_version", 1) : 0;
  if (version < 1 || version > IngestRecord::kSchemaVersion) {
    throw ParseError(path, 0,
                     "not an ingest record of schema 1.." + std::to_string(IngestRecord::kSchemaVersion) +
                         " (schema_version " + std::to_string(version) + "): delete it to rerun the ingest stage");
  }
  IngestRecord r;
  try {
    r.images_dir = doc.value("images_dir", std::string());
    r.working_max_dimension = doc.value("working_max_dimension", 0);
    r.options = doc.value("options", json());
    r.images_with_gps = doc.value("images_with_gps", 0);
    for (const json& w : doc.value("warnings", json::array())) r.warnings.push_back(w.get<std::string>());
    for (const json& g : doc.at("groups")) {
      CameraGroup c;
      c.key = g.value("key", std::string());
      c.make = g.value("make", std::string());
      c.model = g.value("model", std::string());
      c.working_width = g.at("working_width");
      c.working_height = g.at("working_height");
      c.camera.id = static_cast<int>(r.groups.size()) + 1;
      c.camera.model = CameraModelId::kBrown;
      c.camera.width = c.working_width;
      c.camera.height = c.working_height;
      c.camera.params = g.at("params").get<std::vector<double>>();
      c.focal_source = g.value("focal_source", std::string());
      // Schema 1 kept only the sentence; its measured rules both began so.
      c.focal_measured = g.contains("focal_measured") ? g.at("focal_measured").get<bool>()
                                                      : c.focal_source.rfind("EXIF focal length", 0) == 0;
      c.images = g.value("images", 0);
      c.pixel_size_mm = g.value("pixel_size_mm", 0.0);
      c.calibration_stated = g.value("calibration_stated", false);
      r.groups.push_back(c);
    }
    for (const json& j : doc.at("images")) {
      IngestedImage im;
      im.name = j.at("name");
      im.usable = j.at("usable");
      im.problem = j.value("problem", std::string());
      im.width = j.value("width", 0);
      im.height = j.value("height", 0);
      im.working_width = j.value("working_width", 0);
      im.working_height = j.value("working_height", 0);
      im.scale = j.value("scale", 1.0);
      im.make = j.value("make", std::string());
      im.model = j.value("model", std::string());
      auto opt = [&j](const char* key) -> std::optional<double> {
        if (j.contains(key) && j.at(key).is_number()) return j.at(key).get<double>();
        return std::nullopt;
      };
      im.focal_mm = opt("focal_mm");
      im.relative_altitude_m = opt("relative_altitude_m");
      im.gimbal_pitch_deg = opt("gimbal_pitch_deg");
      im.gimbal_yaw_deg = opt("gimbal_yaw_deg");
      im.capture_time_s = opt("capture_time_s");
      im.camera_says = j.value("camera_says", json::object());
      if (j.contains("gps") && !j.at("gps").is_null()) {
        const json& g = j.at("gps");
        GpsFix f;
        f.position = {g.at("lat_deg"), g.at("lon_deg"), g.at("h_m")};
        f.sigma_h_m = g.at("sigma_h_m");
        f.sigma_v_m = g.at("sigma_v_m");
        f.source = g.at("source");
        if (g.contains("time_s") && g.at("time_s").is_number()) f.time_s = g.at("time_s");
        im.gps = f;
      }
      im.group = j.value("group", -1);
      if (im.usable && (im.group < 0 || im.group >= static_cast<int>(r.groups.size()))) {
        throw ParseError(path, 0, "image '" + im.name + "' names camera group " + std::to_string(im.group) +
                                      " of " + std::to_string(r.groups.size()) +
                                      ": delete it to rerun the ingest stage");
      }
      r.images.push_back(im);
    }
  } catch (const json::exception& e) {
    throw ParseError(path, 0, std::string("not a complete ingest record (") + e.what() +
                                  "): delete it to rerun the ingest stage");
  }
  return r;
}

}  // namespace aerotri
