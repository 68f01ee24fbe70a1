// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/pipeline/workspace.h"

#include <ctime>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/base/parallel.h"
#include "libphoto/ingest/image_metadata.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;

void Log(const PipelineOptions& o, const std::string& message) {
  if (o.log) o.log(message);
}

ProgressCallback StageProgress(const PipelineOptions& o, const std::string& stage) {
  return o.progress ? o.progress(stage) : ProgressCallback();
}

namespace {
// The stage's resident peak, through the resets its phases make (the
// georeference stage times its own).
std::unique_ptr<PeakRssSpan>& StageSpan() {
  static std::unique_ptr<PeakRssSpan> span;
  return span;
}
}  // namespace

std::chrono::steady_clock::time_point BeginStage() {
  // The heap's free pages back to the kernel first: what an earlier stage
  // freed but glibc kept would otherwise count in this stage's peak.
  ReleaseFreedMemory();
  StageSpan().reset();
  StageSpan() = std::make_unique<PeakRssSpan>();
  return std::chrono::steady_clock::now();
}

void RecordTiming(const PipelineOptions& o, const std::string& stage, double seconds) {
  const fs::path path = o.workspace / "timings.json";
  json timings = json::object();
  if (fs::exists(path)) {
    try {
      timings = json::parse(ReadTextFile(path));
    } catch (const std::exception&) {
      timings = json::object();
    }
  }
  const PeakRssSpan* span = StageSpan().get();
  timings[stage] = {{"wall_s", seconds},
                    {"peak_rss_mb", span ? span->PeakMb() : PeakRssMb()},
                    {"process_peak_rss_mb", ProcessPeakRssMb()},
                    {"peak_rss_scope", span && span->Own() ? "stage" : "process"}};
  WriteTextFileAtomically(path, timings.dump(2) + "\n");
}

unsigned Threads(const PipelineOptions& o) { return ThreadCount(o.num_threads); }

json ReadJson(const fs::path& path, const char* stage) {
  if (!fs::exists(path)) {
    throw IoError(path.string(), std::string("missing: run the ") + stage + " stage first");
  }
  try {
    return json::parse(ReadTextFile(path));
  } catch (const json::exception& e) {
    throw ParseError(path.string(), 0, std::string("corrupt JSON (") + e.what() + "); delete it to redo the stage");
  }
}

// The working-resolution size ExtractFeatures / LoadWorkingImage produce.
fs::path FeaturePath(const PipelineOptions& o, const std::string& name) {
  return o.workspace / "features" / (name + ".sift");
}

IngestOptions IngestStageOptions(const PipelineOptions& o) {
  IngestOptions i;
  i.images_dir = o.images_dir;
  i.gps_altitude = o.gps_altitude;
  i.gps_sigma_h_m = o.gps_sigma_h_m;
  i.gps_sigma_v_m = o.gps_sigma_v_m;
  i.gps_csv = o.gps_csv;
  i.max_dimension = o.features.max_dimension;
  return i;
}

std::filesystem::path IngestView::ImagesDir(const PipelineOptions& o) const {
  return record.images_dir.empty() ? o.images_dir : record.images_dir;
}

std::map<std::string, GimbalAttitude> IngestView::GimbalAngles() const {
  std::map<std::string, GimbalAttitude> gimbal;
  for (const IngestedImage& im : record.images) {
    if (im.gimbal_pitch_deg && im.gimbal_yaw_deg) gimbal[im.name] = {*im.gimbal_pitch_deg, *im.gimbal_yaw_deg};
  }
  return gimbal;
}

std::map<std::string, RollingShutterMotion> IngestView::RollingShutters(std::string* source) const {
  std::map<std::string, RollingShutterMotion> motion;
  std::vector<std::string> sources;
  for (const IngestedImage& im : record.images) {
    // What ingest recorded of the tags, read as the photo states them.
    const nlohmann::json& says = im.camera_says;
    ImageMetadata m;
    m.make = im.make;
    m.model = im.model;
    m.width = im.width;
    m.height = im.height;
    if (says.contains("line_readout_time_s")) m.line_readout_time_s = says["line_readout_time_s"].get<double>();
    if (says.contains("imu_linear_velocity_mps")) m.imu_linear_velocity_mps = says["imu_linear_velocity_mps"].get<std::vector<double>>();
    if (says.contains("flight_speed_mps")) {
      const auto speed = says["flight_speed_mps"].get<std::vector<double>>();
      if (speed.size() == 3) {
        m.flight_speed_x_mps = speed[0];
        m.flight_speed_y_mps = speed[1];
        m.flight_speed_z_mps = speed[2];
      }
    }
    if (const auto stated = RollingShutterStatedBy(m)) {
      motion[im.name] = {stated->readout_time_s, Eigen::Vector3d(stated->east_mps, stated->north_mps, 0.0)};
      if (std::find(sources.begin(), sources.end(), stated->source) == sources.end()) sources.push_back(stated->source);
    }
  }
  source->clear();
  for (const std::string& s : sources) *source += (source->empty() ? "" : " | ") + s;
  return motion;
}

std::optional<Geodetic> IngestView::EnuOrigin() const {
  Geodetic mean{0.0, 0.0, 0.0};
  int n = 0;
  for (size_t i = 0; i < gps.size(); ++i) {
    if (!gps[i] || !usable[i]) continue;
    mean.lat_deg += gps[i]->position.lat_deg;
    mean.lon_deg += gps[i]->position.lon_deg;
    mean.h_m += gps[i]->position.h_m;
    ++n;
  }
  if (n == 0) return std::nullopt;
  return Geodetic{mean.lat_deg / n, mean.lon_deg / n, mean.h_m / n};
}

IngestView LoadIngest(const PipelineOptions& o) {
  const fs::path path = o.workspace / "ingest.json";
  // Read once per process while the file is unchanged (its size and
  // modification time): every stage of a run asks for it.
  struct Cached {
    std::uintmax_t size = 0;
    fs::file_time_type time;
    IngestView view;
  };
  static std::mutex mutex;
  static std::map<std::string, Cached> cache;
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  const fs::file_time_type time = ec ? fs::file_time_type() : fs::last_write_time(path, ec);
  const std::string key = fs::absolute(path).lexically_normal().string();
  if (!ec) {
    std::lock_guard<std::mutex> lock(mutex);
    const auto it = cache.find(key);
    if (it != cache.end() && it->second.size == size && it->second.time == time) return it->second.view;
  }
  IngestView v;
  v.record = IngestRecordFromJson(ReadJson(path, "ingest"), path.string());
  for (const CameraGroup& g : v.record.groups) {
    v.cameras.push_back(g.camera);
    v.focal_prior_px.push_back(g.focal_measured ? g.camera.focal_px() : 0.0);
  }
  for (const IngestedImage& im : v.record.images) {
    v.names.push_back(im.name);
    v.usable.push_back(im.usable);
    v.scale.push_back(im.scale);
    v.group.push_back(im.group);
    v.gps.push_back(im.gps);
  }
  if (!ec) {
    std::lock_guard<std::mutex> lock(mutex);
    cache[key] = {size, time, v};
  }
  return v;
}

std::vector<ImageFeatures> LoadFeatures(const PipelineOptions& o, IngestView* ingest) {
  std::vector<ImageFeatures> features(ingest->names.size());
  for (size_t i = 0; i < ingest->names.size(); ++i) {
    if (!ingest->usable[i]) continue;
    const fs::path path = FeaturePath(o, ingest->names[i]);
    if (!fs::exists(path)) {
      ingest->usable[i] = false;  // decoding failed in the features stage
      continue;
    }
    features[i] = ReadFeatures(path);
  }
  return features;
}


std::string ContentHash(const std::filesystem::path& path) {
  if (path.empty()) return "";
  if (!std::filesystem::exists(path)) return "missing";
  const std::string data = ReadTextFile(path);
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : data) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

nlohmann::json IngestFingerprint(const PipelineOptions& o) {
  return {{"max_dimension", o.features.max_dimension},  // every image's scale, the cameras' pixels
          {"gps_altitude", o.gps_altitude == AltitudeReference::kEllipsoid ? "ellipsoid" : "egm96"},
          {"gps_sigma_h_m", o.gps_sigma_h_m},
          {"gps_sigma_v_m", o.gps_sigma_v_m},
          {"gps_csv", ContentHash(o.gps_csv)}};
}

nlohmann::json FeatureFingerprint(const PipelineOptions& o) {
  return {{"max_dimension", o.features.max_dimension},
          {"max_features", o.features.max_features},
          {"contrast_threshold", o.features.contrast_threshold}};
}

nlohmann::json MatchFingerprint(const PipelineOptions& o) {
  const MatchOptions& m = o.matching;
  return {{"features", ContentHash(o.workspace / "features" / "options.json")},
          {"ratio", m.ratio},
          {"min_inliers", m.min_inliers},
          {"max_epipolar_px", m.max_epipolar_px},
          {"gps_neighbours", m.gps_neighbours},
          {"exhaustive_up_to", m.exhaustive_up_to},
          {"flann_checks", m.flann_checks}};
}

nlohmann::json ReconstructFingerprint(const PipelineOptions& o) {
  const MapperOptions& m = o.mapper;
  return {{"matches", ContentHash(o.workspace / "matches.json")},
          {"min_pnp_inliers", m.min_pnp_inliers},
          {"max_reprojection_px", m.max_reprojection_px},
          {"min_triangulation_angle_deg", m.min_triangulation_angle_deg},
          {"init_min_median_angle_deg", m.init_min_median_angle_deg},
          {"init_candidates", m.init_candidates},
          {"gps_rescue", m.gps_rescue},
          {"rescue_search_radius_px", m.rescue_search_radius_px},
          {"local_adjust_images", m.local_adjust_images},
          {"local_adjust_iterations", m.local_adjust_iterations},
          {"global_adjust_growth", m.global_adjust_growth},
          {"global_adjust_screening", m.global_adjust_screening},
          {"iterative_above_images", m.iterative_above_images},
          {"gps_priors", m.gps_priors},
          {"gps_prior_min_images", m.gps_prior_min_images},
          {"rolling_shutter", m.gps_priors && o.georef.model_rolling_shutter}};
}

namespace {

// A record's field, or ParseError naming the file and the field.
template <typename T>
T Field(const nlohmann::json& doc, const char* key, const std::string& path) {
  if (!doc.is_object() || !doc.contains(key)) throw ParseError(path, 0, std::string("missing field '") + key + "'");
  try {
    return doc.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    throw ParseError(path, 0, std::string("field '") + key + "' has the wrong type: " + doc.at(key).dump());
  }
}

void CheckSchema(const nlohmann::json& doc, int known, const std::string& path) {
  // Files written before records had a version are version 1.
  const int version = doc.is_object() ? doc.value("schema_version", 1) : 0;
  if (version != known) {
    throw ParseError(path, 0, "schema_version " + std::to_string(version) + " is not one this aerotri reads (" +
                                  std::to_string(known) + "): rerun the stage with --force");
  }
}

}  // namespace

nlohmann::json ToJson(const MatchRecord& r) {
  nlohmann::json images = nlohmann::json::array();
  for (const MatchRecord::Image& im : r.images) {
    images.push_back({{"name", im.name},
                      {"features", im.features},
                      {"verified_pairs", im.verified_pairs},
                      {"verified_matches", im.verified_matches}});
  }
  return {{"schema_version", MatchRecord::kSchemaVersion},
          {"strategy", r.strategy},
          {"candidate_pairs", r.candidate_pairs},
          {"verified_pairs", r.verified_pairs},
          {"images", images},
          {"options", r.options}};
}

MatchRecord MatchRecordFromJson(const nlohmann::json& doc, const std::string& path) {
  CheckSchema(doc, MatchRecord::kSchemaVersion, path);
  MatchRecord r;
  r.strategy = Field<std::string>(doc, "strategy", path);
  r.candidate_pairs = Field<int>(doc, "candidate_pairs", path);
  r.verified_pairs = Field<int>(doc, "verified_pairs", path);
  for (const auto& im : Field<nlohmann::json>(doc, "images", path)) {
    r.images.push_back({Field<std::string>(im, "name", path), Field<int>(im, "features", path),
                        Field<int>(im, "verified_pairs", path), Field<int>(im, "verified_matches", path)});
  }
  r.options = doc.value("options", nlohmann::json());
  return r;
}

nlohmann::json ToJson(const ReconstructionRecord& r) {
  nlohmann::json images = nlohmann::json::array();
  for (const ReconstructionRecord::Image& im : r.images) {
    nlohmann::json j = {{"name", im.name}, {"registered", im.registered}};
    if (!im.registered) j["why_not"] = im.why_not;
    if (im.registered && im.component >= 0) j["component"] = im.component;
    images.push_back(j);
  }
  return {{"schema_version", ReconstructionRecord::kSchemaVersion},
          {"initial_pair", r.initial_pair},
          {"tracks", r.tracks},
          {"dropped_inconsistent_tracks", r.dropped_inconsistent_tracks},
          {"global_adjustments", r.global_adjustments},
          {"adjustment_s", r.adjustment_s},
          {"adjustment_iterations", r.adjustment_iterations},
          {"local_adjustments", r.local_adjustments},
          {"local_adjustment_s", r.local_adjustment_s},
          {"registered", r.registered},
          {"focal_held", r.focal_held},
          {"gps_anchored_at_images", r.gps_anchored_at_images},
          {"rolling_shutter_images", r.rolling_shutter_images},
          {"component_images", r.component_images},
          {"images", images},
          {"options", r.options}};
}

ReconstructionRecord ReconstructionRecordFromJson(const nlohmann::json& doc, const std::string& path) {
  CheckSchema(doc, ReconstructionRecord::kSchemaVersion, path);
  ReconstructionRecord r;
  r.initial_pair = Field<std::string>(doc, "initial_pair", path);
  r.tracks = Field<int>(doc, "tracks", path);
  r.dropped_inconsistent_tracks = doc.value("dropped_inconsistent_tracks", 0);
  r.global_adjustments = doc.value("global_adjustments", 0);
  r.adjustment_s = doc.value("adjustment_s", 0.0);
  r.adjustment_iterations = doc.value("adjustment_iterations", 0);
  r.local_adjustments = doc.value("local_adjustments", 0);
  r.local_adjustment_s = doc.value("local_adjustment_s", 0.0);
  r.registered = Field<int>(doc, "registered", path);
  r.focal_held = doc.value("focal_held", false);
  r.gps_anchored_at_images = doc.value("gps_anchored_at_images", 0);
  r.rolling_shutter_images = doc.value("rolling_shutter_images", 0);
  r.component_images = doc.value("component_images", std::vector<int>{r.registered});
  for (const auto& im : Field<nlohmann::json>(doc, "images", path)) {
    ReconstructionRecord::Image image;
    image.name = Field<std::string>(im, "name", path);
    image.registered = Field<bool>(im, "registered", path);
    image.why_not = im.value("why_not", "");
    image.component = im.value("component", -1);
    r.images.push_back(image);
  }
  r.options = doc.value("options", nlohmann::json());
  return r;
}

MatchRecord LoadMatchRecord(const PipelineOptions& o) {
  const fs::path path = o.workspace / "matches.json";
  return MatchRecordFromJson(ReadJson(path, "match"), path.string());
}

ReconstructionRecord LoadReconstructionRecord(const PipelineOptions& o) {
  const fs::path path = o.workspace / "reconstruction.json";
  return ReconstructionRecordFromJson(ReadJson(path, "reconstruct"), path.string());
}

nlohmann::json GeoreferenceFingerprint(const PipelineOptions& o) {
  const GeoreferenceOptions& g = o.georef;
  std::string refine = g.auto_refine ? "auto" : ToString(g.bundle.refine_intrinsics);
  for (const auto& p : g.bundle.refine_params) refine += "," + p;
  return {{"ingest", ContentHash(o.workspace / "ingest.json")},
          {"gcp", ContentHash(o.gcp)},
          {"checkpoints", ContentHash(o.checkpoints)},
          {"camera_file", ContentHash(o.camera_file)},
          {"gcp_pixel_origin", o.gcp_pixel_origin == PixelOrigin::kCorner ? "corner" : "centre"},
          {"crs", g.output_crs},
          {"gcp_sigma_h_m", g.gcp_sigma_h_m},
          {"gcp_sigma_v_m", g.gcp_sigma_v_m},
          {"keep_control_sigmas", g.keep_stated_control_sigmas},
          {"zero_heights_are_heights", g.zero_heights_are_heights},
          {"variance_components", !g.bundle.estimate_variance_components ? "stated"
                                  : g.hold_stated_sigmas              ? "auto"
                                                                      : "estimate"},
          {"gps_offset", ToString(g.gps_offset)},
          {"refine", refine},
          {"loss", ToString(g.bundle.loss)},
          {"loss_scale_px", g.bundle.loss_scale_px},
          {"loss_use", g.bundle.least_squares_after_screening ? "screening" : "every solve"},
          {"outlier_threshold_px", g.bundle.outlier_threshold_px},
          {"tie_sigma_px", g.bundle.observation_sigma_px},
          {"mark_sigma_px", g.bundle.mark_sigma_px},
          {"checkpoints_in_bundle", g.bundle.check_points_in_bundle},
          {"leave_one_out", g.leave_one_out},
          {"rolling_shutter", !g.model_rolling_shutter ? "off" : g.estimate_readout ? "estimate" : "auto"},
          {"gnss_lever_arm_m", {g.bundle.gnss_lever_arm_m.x(), g.bundle.gnss_lever_arm_m.y(), g.bundle.gnss_lever_arm_m.z()}},
          {"function_tolerance", g.bundle.function_tolerance},
          {"parameter_tolerance", g.bundle.parameter_tolerance},
          {"gradient_tolerance", g.bundle.gradient_tolerance}};
}

nlohmann::json DenseFingerprint(const PipelineOptions& o) {
  return {{"dense_resolution_m", o.dense_resolution_m}, {"dense_image_scale", o.dense_image_scale},
          {"dense_min_views", o.dense_min_views},       {"dsm_resolution_m", o.dsm_resolution_m},
          {"dsm_fill_m", o.dsm_fill_m},                 {"cog", o.cog},
          {"heights", o.heights},                       {"ground_cell_m", o.ground_cell_m},
          {"ground_window_m", o.ground_window_m},       {"ground_slope", o.ground_slope},
          {"ground_threshold_m", o.ground_threshold_m}, {"contour_interval_m", o.contour_interval_m},
          {"cloud_format", o.cloud_format},
          // The pairing and fusion rules (dense_stereo.h): a workspace fused
          // under older rules is fused again.
          {"dense_method", "pairs: 2 along + 1 across the strip; agreement within 1 voxel; a lone depth map kept"}};
}

nlohmann::json OrthoFingerprint(const PipelineOptions& o) {
  return {{"ortho_resolution_m", o.ortho_resolution_m}, {"ortho_surface", o.ortho_surface},
          {"ortho_compress", o.ortho_compress},         {"ortho_cog", o.ortho_cog}};
}

nlohmann::json ProcessProvenance(const std::string& software, const std::vector<std::string>& command_line) {
  char date[32] = "";
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  if (gmtime_r(&now, &utc)) std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return {{"software", software.empty() ? std::string("aerotri (library)") : software},
          {"command_line", command_line},
          {"date_utc", date}};
}

nlohmann::json Provenance(const PipelineOptions& o, const nlohmann::json& ingest_options) {
  nlohmann::json p = ProcessProvenance(o.software_version, o.command_line);
  p["options"] = {{"ingest", ingest_options}, {"georeference", GeoreferenceFingerprint(o)}, {"threads", o.num_threads}};
  return p;
}

bool StageIsCurrent(const PipelineOptions& o, const std::string& stage, const fs::path& record,
                    const std::string& key, const nlohmann::json& now) {
  nlohmann::json recorded;
  if (fs::exists(record)) {
    const nlohmann::json doc = ReadJson(record, stage.c_str());
    recorded = key.empty() ? doc : doc.value(key, nlohmann::json());
  }
  const std::string changed = FingerprintChanges(recorded, now);
  if (changed.empty()) {
    Log(o, stage + ": done already (" + record.string() + ")");
    return true;
  }
  Log(o, stage + ": options or inputs changed since " + record.string() + " (" + changed +
             "): rerunning, and the stages after it");
  return false;
}

std::string FingerprintChanges(const nlohmann::json& recorded, const nlohmann::json& now) {
  std::string out;
  for (const auto& [key, value] : now.items()) {
    const nlohmann::json old = recorded.is_object() && recorded.contains(key) ? recorded.at(key) : nlohmann::json();
    if (old == value) continue;
    out += (out.empty() ? "" : "; ") + key + ": " + (old.is_null() ? "unrecorded" : old.dump()) + " -> " +
           value.dump();
  }
  return out;
}

}  // namespace aerotri
