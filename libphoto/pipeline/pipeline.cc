// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/pipeline/pipeline.h"

#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <nlohmann/json.hpp>
#include <sstream>
#include <mutex>
#include <thread>

#include "camera_models/exif_intrinsics.h"
#include "libphoto/adjust/camera_file.h"
#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"
#include "libphoto/dense/dense_stereo.h"
#include "libphoto/export/contours.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/survey_adjustment.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/report/report_json.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;

using Clock = std::chrono::steady_clock;

bool RunIngestStage(const PipelineOptions& o) {
  const fs::path out = o.workspace / "ingest.json";
  if (fs::exists(out) && !o.force && StageIsCurrent(o, "ingest", out, "options", IngestFingerprint(o))) return false;
  const auto start = BeginStage();
  IngestRecord record = IngestSurveyImages(IngestStageOptions(o), StageProgress(o, "ingest"));
  record.options = IngestFingerprint(o);
  fs::create_directories(o.workspace);
  WriteTextFileAtomically(out, ToJson(record).dump(2) + "\n");
  for (const auto& w : record.warnings) Log(o, "warning: " + w);
  RecordTiming(o, "ingest", std::chrono::duration<double>(Clock::now() - start).count());
  return true;
}

bool RunFeatureStage(const PipelineOptions& o) {
  IngestView ingest = LoadIngest(o);
  const fs::path images_dir = ingest.ImagesDir(o);
  // Features extracted under other options are all extracted again.
  const fs::path record = o.workspace / "features" / "options.json";
  const json options = FeatureFingerprint(o);
  if (fs::exists(o.workspace / "features") && !o.force) {
    // Per image, features present are kept (an interrupted extraction
    // resumes): "done already" is said below, once every image has them.
    const std::string changed =
        FingerprintChanges(fs::exists(record) ? ReadJson(record, "features") : json(), options);
    if (!changed.empty()) {
      Log(o, "features: options or inputs changed since " + record.string() + " (" + changed +
                 "): every image's features are extracted again, and the stages after it rerun");
      fs::remove_all(o.workspace / "features");
    }
  }
  std::vector<size_t> todo;
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    if (ingest.usable[i] && (o.force || !fs::exists(FeaturePath(o, ingest.names[i])))) todo.push_back(i);
  }
  if (todo.empty()) {
    Log(o, "features: done already");
    return false;
  }
  const auto start = BeginStage();
  fs::create_directories(o.workspace / "features");
  // Recorded first, so that an interrupted extraction resumes under the same options.
  WriteTextFileAtomically(record, options.dump(2) + "\n");
  // New features invalidate the matches (they index the old keypoints) and
  // what was built from them: those stages rerun.
  if (fs::exists(o.workspace / "matches.bin")) {
    Log(o, "features: re-extracted, so matches.bin and reconstruction.json are stale: removed (the match and "
           "reconstruct stages rerun)");
    fs::remove(o.workspace / "matches.bin");
    fs::remove(o.workspace / "matches.json");
    fs::remove(o.workspace / "reconstruction.json");
  }
  ProgressCallback progress = StageProgress(o, "features");
  std::atomic<size_t> done{0};
  std::mutex mutex;
  std::vector<std::string> failures;
  ParallelFor(todo.size(), Threads(o), [&](size_t k) {
    const std::string& name = ingest.names[todo[k]];
    try {
      const ImageFeatures f = ExtractFeatures(images_dir / name, o.features);
      WriteFeatures(f, FeaturePath(o, name));
      std::lock_guard<std::mutex> lock(mutex);
      ReportProgress(progress, static_cast<double>(++done) / todo.size(),
                     name + ": " + std::to_string(f.keypoints.size()) + " features");
    } catch (const Error& e) {
      std::lock_guard<std::mutex> lock(mutex);
      failures.push_back(e.what());
      ++done;
    }
  });
  for (const auto& f : failures) Log(o, "warning: " + f + "; image skipped");
  RecordTiming(o, "features", std::chrono::duration<double>(Clock::now() - start).count());
  return true;
}

bool RunMatchStage(const PipelineOptions& o) {
  const fs::path out = o.workspace / "matches.bin";
  const fs::path summary_path = o.workspace / "matches.json";
  if (fs::exists(out) && !o.force && StageIsCurrent(o, "match", summary_path, "options", MatchFingerprint(o))) {
    return false;
  }
  const auto start = BeginStage();
  IngestView ingest = LoadIngest(o);
  const std::vector<ImageFeatures> features = LoadFeatures(o, &ingest);
  // Horizontal GPS positions in a local frame for neighbourhoods.
  std::vector<std::optional<Eigen::Vector2d>> gps(ingest.names.size());
  if (const auto origin = ingest.EnuOrigin()) {
    const LocalFrame frame(*origin);
    for (size_t i = 0; i < gps.size(); ++i) {
      if (ingest.gps[i] && ingest.usable[i]) gps[i] = frame.EnuFromGeodetic(ingest.gps[i]->position).head<2>();
    }
  }
  // Unusable images take no part: give them a position so they do not force
  // exhaustive matching, and drop their pairs.
  std::vector<int> usable_index;
  std::vector<std::optional<Eigen::Vector2d>> usable_gps;
  for (size_t i = 0; i < gps.size(); ++i) {
    if (!ingest.usable[i]) continue;
    usable_index.push_back(static_cast<int>(i));
    usable_gps.push_back(gps[i]);
  }
  MatchOptions mo = o.matching;
  mo.num_threads = o.num_threads;
  std::string strategy;
  std::vector<std::pair<int, int>> pairs;
  for (const auto& [a, b] : SelectPairs(usable_gps, mo, &strategy)) {
    pairs.push_back({usable_index[a], usable_index[b]});
  }
  const std::vector<PairMatches> matches = MatchPairs(features, pairs, mo, StageProgress(o, "match"));
  WriteMatches(matches, out);
  MatchRecord summary;
  summary.strategy = strategy;
  summary.candidate_pairs = static_cast<int>(pairs.size());
  summary.verified_pairs = static_cast<int>(matches.size());
  summary.options = MatchFingerprint(o);
  std::vector<int> pair_count(ingest.names.size(), 0), match_count(ingest.names.size(), 0);
  for (const PairMatches& m : matches) {
    ++pair_count[m.i];
    ++pair_count[m.j];
    match_count[m.i] += static_cast<int>(m.inliers.size());
    match_count[m.j] += static_cast<int>(m.inliers.size());
  }
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    summary.images.push_back({ingest.names[i], static_cast<int>(features[i].keypoints.size()), pair_count[i],
                              match_count[i]});
    if (ingest.usable[i] && pair_count[i] == 0) {
      Log(o, "warning: " + ingest.names[i] + " overlaps no other image (no verified pair)");
    }
  }
  WriteTextFileAtomically(summary_path, ToJson(summary).dump(2) + "\n");
  RecordTiming(o, "match", std::chrono::duration<double>(Clock::now() - start).count());
  return true;
}

namespace {

// A camera the photo says looks straight down (Pix4D's camera tags: pitch
// and roll within 15 degrees of 0, which is nadir) turned to its stated yaw:
// the image's top toward that azimuth, as consecutive photos of a strip
// show it (the ground moves down the frame as the aircraft flies on).
// cam_from_world in ENU; nullopt where the photo states no such attitude.
std::optional<Eigen::Quaterniond> StatedNadirAttitude(const nlohmann::json& says) {
  if (!says.contains("camera_yaw_deg") || !says.contains("camera_pitch_deg") || !says.contains("camera_roll_deg")) {
    return std::nullopt;
  }
  if (std::abs(says["camera_pitch_deg"].get<double>()) > 15.0 || std::abs(says["camera_roll_deg"].get<double>()) > 15.0) {
    return std::nullopt;
  }
  const double yaw = says["camera_yaw_deg"].get<double>() * M_PI / 180.0;
  Eigen::Matrix3d cam_from_world;
  cam_from_world.row(0) << std::cos(yaw), -std::sin(yaw), 0.0;   // image right
  cam_from_world.row(1) << -std::sin(yaw), -std::cos(yaw), 0.0;  // image down: away from the yaw
  cam_from_world.row(2) << 0.0, 0.0, -1.0;                       // optical axis: down
  return Eigen::Quaterniond(cam_from_world).normalized();
}

}  // namespace

bool RunReconstructStage(const PipelineOptions& o) {
  const fs::path out_json = o.workspace / "reconstruction.json";
  if (fs::exists(out_json) && !o.force &&
      StageIsCurrent(o, "reconstruct", out_json, "options", ReconstructFingerprint(o))) {
    return false;
  }
  const auto start = BeginStage();
  IngestView ingest = LoadIngest(o);
  const std::vector<ImageFeatures> features = LoadFeatures(o, &ingest);
  const std::vector<PairMatches> matches = ReadMatches(o.workspace / "matches.bin");
  // A new model makes the georeferenced survey built on the old one stale.
  if (fs::exists(o.workspace / "report.json")) {
    Log(o, "reconstruct: a new model: the earlier georeference (report.json, sparse/) is removed and reruns");
    fs::remove(o.workspace / "report.json");
    fs::remove_all(o.workspace / "sparse");
  }
  ValidateMatches(matches, features, o.workspace / "matches.bin");
  std::vector<int> camera_of_image;
  for (size_t i = 0; i < ingest.names.size(); ++i) camera_of_image.push_back(std::max(0, ingest.group[i]));
  MapperOptions mo = o.mapper;
  mo.num_threads = o.num_threads;
  mo.progress = StageProgress(o, "reconstruct");
  mo.focal_prior_px = ingest.focal_prior_px;
  std::vector<std::optional<Eigen::Vector3d>> gps(ingest.names.size());
  if (const auto origin = ingest.EnuOrigin()) {
    const LocalFrame frame(*origin);
    for (size_t i = 0; i < gps.size(); ++i) {
      if (ingest.gps[i]) gps[i] = frame.EnuFromGeodetic(ingest.gps[i]->position);
    }
  }
  // With the GPS as priors: each fix's sigmas, and the photos' stated
  // rolling shutter (velocities in the same ENU frame).
  MapperPriors priors;
  if (mo.gps_priors) {
    std::string source;
    const std::map<std::string, RollingShutterMotion> shutters = ingest.RollingShutters(&source);
    for (size_t i = 0; i < gps.size(); ++i) {
      priors.gps_sigma_h_m.push_back(ingest.gps[i] ? ingest.gps[i]->sigma_h_m : 0.0);
      priors.gps_sigma_v_m.push_back(ingest.gps[i] ? ingest.gps[i]->sigma_v_m : 0.0);
      const auto it = shutters.find(ingest.names[i]);
      priors.rolling_shutter.push_back(o.georef.model_rolling_shutter && it != shutters.end()
                                           ? std::optional<RollingShutterMotion>(it->second)
                                           : std::nullopt);
      priors.attitude.push_back(StatedNadirAttitude(ingest.record.images[i].camera_says));
    }
  }
  // Gimbal pitches give an oblique block the vertical its GPS check levels by.
  MapperResult result = ReconstructIncremental(ingest.names, camera_of_image, ingest.cameras, features,
                                               matches, mo, gps, ingest.GimbalAngles(), priors);
  // Registered images only in the COLMAP model.
  SparseModel registered;
  registered.cameras = result.model.cameras;
  std::vector<int> remap(result.model.images.size(), -1);
  for (size_t i = 0; i < result.model.images.size(); ++i) {
    if (!result.model.images[i].registered) continue;
    remap[i] = static_cast<int>(registered.images.size());
    registered.images.push_back(result.model.images[i]);
  }
  registered.points = result.model.points;
  for (Observation obs : result.model.observations) {
    if (remap[obs.image] < 0) continue;
    obs.image = remap[obs.image];
    registered.observations.push_back(obs);
  }
  WriteColmapText(registered, o.workspace / "reconstruction");
  ReconstructionRecord doc;
  doc.initial_pair = result.initial_pair;
  doc.tracks = result.num_tracks;
  doc.dropped_inconsistent_tracks = result.dropped_inconsistent_tracks;
  doc.global_adjustments = result.global_adjustments;
  doc.adjustment_s = result.adjustment_s;
  doc.adjustment_iterations = result.adjustment_iterations;
  doc.local_adjustments = result.local_adjustments;
  doc.local_adjustment_s = result.local_adjustment_s;
  doc.focal_held = result.focal_held;
  doc.gps_anchored_at_images = result.gps_anchored_at_images;
  doc.rolling_shutter_images = result.rolling_shutter_images;
  doc.registered = static_cast<int>(registered.images.size());
  doc.component_images = result.component_images;
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    ReconstructionRecord::Image im{ingest.names[i], result.images[i].registered, "",
                                   i < result.component.size() ? result.component[i] : -1};
    if (!ingest.usable[i]) {
      im.why_not = "unusable image (unreadable or undecodable)";
    } else if (!im.registered) {
      im.why_not = result.images[i].why_not;
    }
    doc.images.push_back(im);
  }
  doc.options = ReconstructFingerprint(o);
  WriteTextFileAtomically(out_json, ToJson(doc).dump(2) + "\n");
  RecordTiming(o, "reconstruct", std::chrono::duration<double>(Clock::now() - start).count());
  return true;
}

// Scales a working-resolution model to each image's full resolution: one
// camera per (group, full size); f, cx, cy and observations scale about the
// pixel-centre convention, distortion coefficients are unit-free.
SparseModel ToFullResolution(const SparseModel& model, const IngestView& ingest) {
  std::map<std::string, int> index_of_name;
  for (size_t i = 0; i < ingest.names.size(); ++i) index_of_name[ingest.names[i]] = static_cast<int>(i);
  SparseModel out = model;
  out.cameras.clear();
  std::map<std::pair<int, double>, int> camera_of;
  std::vector<double> scale_of_image(model.images.size(), 1.0);
  for (size_t i = 0; i < model.images.size(); ++i) {
    const auto it = index_of_name.find(model.images[i].name);
    const double s = it != index_of_name.end() ? ingest.scale[it->second] : 1.0;
    scale_of_image[i] = s;
    const int group = model.images[i].camera;
    auto [c, inserted] = camera_of.emplace(std::make_pair(group, s), static_cast<int>(out.cameras.size()));
    if (inserted) {
      Camera cam = model.cameras[group];
      cam.id = static_cast<int>(out.cameras.size()) + 1;
      cam.width = static_cast<int>(std::lround(cam.width * s));
      cam.height = static_cast<int>(std::lround(cam.height * s));
      for (int k : cam.info().focal_params) cam.params[k] *= s;
      for (int k : cam.info().principal_point_params) cam.params[k] = (cam.params[k] + 0.5) * s - 0.5;
      out.cameras.push_back(cam);
    }
    out.images[i].camera = c->second;
  }
  for (Observation& obs : out.observations) {
    const double s = scale_of_image[obs.image];
    obs.xy = (obs.xy.array() + 0.5) * s - 0.5;
  }
  return out;
}

// The georeference stage's inputs and options, from the workspace's ingest
// record: one definition for the stage and for `check --leave-one-out`.
SurveyAdjustmentInputs GeoreferenceInputs(const PipelineOptions& o, const IngestView& ingest) {
  SurveyAdjustmentInputs inputs;
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    if (ingest.gps[i]) inputs.gps[ingest.names[i]] = *ingest.gps[i];
    inputs.full_from_model[ingest.names[i]] = ingest.scale[i];
  }
  inputs.gimbal = ingest.GimbalAngles();
  inputs.gcp = o.gcp;
  inputs.checkpoints = o.checkpoints;
  inputs.gcp_pixel_origin = o.gcp_pixel_origin;
  inputs.camera_file = o.camera_file;
  return inputs;
}

GeoreferenceOptions GeoreferenceStageOptions(const PipelineOptions& o, const IngestView& ingest) {
  GeoreferenceOptions go = o.georef;
  go.bundle.num_threads = o.num_threads;
  go.bundle.focal_prior_px = ingest.focal_prior_px;
  go.enu_origin = ingest.EnuOrigin();  // the workspace's one origin
  go.rolling_shutter = ingest.RollingShutters(&go.rolling_shutter_source);
  go.progress = StageProgress(o, "georeference");
  return go;
}

namespace {

// Every photo of the survey: registered or why not, its reprojection error
// and whether it has GPS; *registered counts the registered ones.
json ImagesJson(const SparseModel& model, const ReconstructionRecord& recon, const IngestView& ingest,
                int* registered_out) {
  std::map<std::string, int> index_of_name;
  for (size_t i = 0; i < ingest.names.size(); ++i) index_of_name[ingest.names[i]] = static_cast<int>(i);
  std::map<std::string, std::pair<double, int>> image_error;
  {
    const std::vector<double> errors = ReprojectionErrors(model);
    for (size_t k = 0; k < errors.size(); ++k) {
      const Observation& obs = model.observations[k];
      if (model.points[obs.point].role != PointRole::kTie || !std::isfinite(errors[k])) continue;
      auto& e = image_error[model.images[obs.image].name];
      e.first += errors[k] * errors[k];
      ++e.second;
    }
  }
  json images = json::array();
  int& registered = *registered_out;
  registered = 0;
  for (const ReconstructionRecord::Image& im : recon.images) {
    json entry = {{"name", im.name}, {"registered", im.registered}};
    if (!im.registered) entry["why_not"] = im.why_not;
    if (im.registered && im.component >= 0) entry["component"] = im.component;
    if (const auto e = image_error.find(im.name); e != image_error.end() && e->second.second > 0) {
      entry["reprojection_rms_px"] = std::sqrt(e->second.first / e->second.second);
      entry["observations"] = e->second.second;
    }
    const auto it = index_of_name.find(im.name);
    entry["gps"] = it != index_of_name.end() && ingest.gps[it->second].has_value();
    registered += im.registered ? 1 : 0;
    images.push_back(entry);
  }
  return images;
}

// The intrinsics in millimetres beside the pixels: the pixel pitch from EXIF,
// or a certificate's (full-resolution pixels: scaled to the group's working
// pixels), which wins.
void AddIntrinsicsInMmOf(const PipelineOptions& o, const IngestView& ingest, json* report) {
  std::vector<double> pixel_size_mm;  // camera id k is group k - 1
  for (const CameraGroup& g : ingest.record.groups) pixel_size_mm.push_back(g.pixel_size_mm);
  // A certificate's pixel pitch wins over EXIF's (full-resolution pixels:
  // scaled to the group's working pixels).
  std::string source = "EXIF";
  if (!o.camera_file.empty()) {
    const CameraFile certificate = ReadCameraFile(o.camera_file);
    if (certificate.pixel_size_mm > 0.0) {
      source = "the camera file";
      for (const IngestedImage& im : ingest.record.images) {
        if (im.group >= 0 && im.group < static_cast<int>(pixel_size_mm.size()) && im.working_width > 0) {
          pixel_size_mm[im.group] = certificate.pixel_size_mm * im.width / im.working_width;
        }
      }
    }
  }
  if (report->contains("adjustment")) AddIntrinsicsInMm(&(*report)["adjustment"], pixel_size_mm, source);
}

// Targets marked from coordinates (the mark stage, when the control or
// check files were its marks): the summary, and a warning per point left
// out.
void AddMarking(const PipelineOptions& o, json* report) {
  const fs::path path = o.workspace / "marks.json";
  const bool used = o.gcp == o.workspace / "gcp_marks.txt" || o.checkpoints == o.workspace / "check_marks.txt";
  if (!fs::exists(path) || !used) return;
  const json marks = ReadJson(path, "mark");
  (*report)["marking"] = {{"file", path.string()},
                          {"control", marks.at("control")},
                          {"checks", marks.at("checks")},
                          {"search_radius_m", marks.at("search_radius_m")},
                          {"placed_by", marks.value("placement_by_targets", json()).is_null() ? "gps" : "targets"},
                          {"review_page", (o.workspace / "marks.html").string()}};
  std::vector<std::string> left_out;
  std::string text;
  for (const json& p : marks.at("points")) {
    const std::string status = p.at("status");
    if (status == "MARKED" || status == "SINGLE_PHOTO") continue;
    left_out.push_back(p.at("name"));
    text += (text.empty() ? "" : "; ") + p.at("name").get<std::string>() + " (" + p.value("role", "") + "): " +
            status + ", " + p.value("reason", "");
  }
  if (left_out.empty()) return;
  if (!report->contains("warnings")) (*report)["warnings"] = json::array();
  (*report)["warnings"].push_back({{"code", "TARGETS_NOT_MARKED"},
                                   {"message", std::to_string(left_out.size()) +
                                                   " surveyed points were not marked in the photos and are not in "
                                                   "the adjustment (marks.json says why; marks.html shows them): " +
                                                   text},
                                   {"items", left_out}});
}

// The survey's status: the adjustment's findings, photos left out, input
// problems met at ingest.
void SetSurveyStatus(const ReconstructionRecord& recon, const IngestView& ingest, int registered, json* report_out) {
  json& report = *report_out;
  std::vector<Finding> findings;
  std::vector<std::string> unregistered;
  for (const ReconstructionRecord::Image& im : recon.images) {
    if (!im.registered) unregistered.push_back(im.name);
  }
  if (!unregistered.empty()) {
    findings.push_back(Finding::Warning(
        "IMAGES_NOT_REGISTERED",
        std::to_string(unregistered.size()) + " of " + std::to_string(ingest.names.size()) +
            " photos are not in the model (report images.per_image says why): " + JoinNames(unregistered),
        unregistered));
  }
  if (recon.component_images.size() > 1) {
    std::vector<std::string> placed;
    std::string sizes;
    for (const ReconstructionRecord::Image& im : recon.images) {
      if (im.registered && im.component > 0) placed.push_back(im.name);
    }
    for (size_t k = 1; k < recon.component_images.size(); ++k) {
      sizes += (k > 1 ? ", " : "") + std::to_string(recon.component_images[k]);
    }
    findings.push_back(Finding::Warning(
        "MODEL_SPLIT",
        "the photos form " + std::to_string(recon.component_images.size()) +
            " groups with no tie points between them: the main one of " +
            std::to_string(recon.component_images[0]) + " photos, and " + sizes +
            " placed by their own GPS; across the seams the relative accuracy is the GPS's, not the "
            "photos' (more overlap, or control in every group, closes them): " + JoinNames(placed),
        placed));
  }
  if (registered < 2) {
    findings.push_back(Finding::Error(
        "NOTHING_REGISTERED",
        std::to_string(registered) + " of " + std::to_string(ingest.names.size()) +
            " photos could be oriented: a survey needs at least two overlapping photos (report "
            "images.per_image and matching say why)",
        unregistered));
  } else if (!report["georeferenced"].get<bool>()) {
    findings.push_back(Finding::Warning(
        "NOT_GEOREFERENCED", "no GPS and no control points: the survey is in an arbitrary frame and scale, "
                             "with no CRS, cloud or DSM"));
  }
  for (const auto& w : report["ingest_warnings"]) findings.push_back(Finding::Warning("INPUT", w.get<std::string>()));
  const auto append = [&](const char* key, Severity severity) {
    for (const json& f : report.value(key, json::array())) {
      findings.push_back({severity, f.at("code"), f.at("message"), f.value("items", std::vector<std::string>{})});
    }
  };
  append("warnings", Severity::kWarning);
  append("errors", Severity::kError);
  report["status"] = SurveyStatus(findings);
  report["warnings"] = FindingsJson(findings, Severity::kWarning);
  report["errors"] = FindingsJson(findings, Severity::kError);
}

}  // namespace

bool RunGeoreferenceStage(const PipelineOptions& o) {
  const fs::path report_path = o.workspace / "report.json";
  // georeferenced/ too: what the dense stage reads (and a workflow's
  // georeference step declares as its output, which Snakemake removes
  // before it reruns the step).
  if (fs::exists(report_path) && fs::exists(o.workspace / "sparse") &&
      fs::exists(o.workspace / "georeferenced" / "images.txt") && !o.force &&
      StageIsCurrent(o, "georeference", report_path, "georeference_options", GeoreferenceFingerprint(o))) {
    return false;
  }
  const auto start = BeginStage();
  IngestView ingest = LoadIngest(o);
  const ReconstructionRecord recon = LoadReconstructionRecord(o);
  SparseModel model = ReadColmapText(o.workspace / "reconstruction");

  const SurveyAdjustmentInputs inputs = GeoreferenceInputs(o, ingest);
  json report;
  const bool can_georeference = !inputs.gps.empty() || (!o.gcp.empty() && !ReadGcpFile(o.gcp, o.gcp_pixel_origin).points.empty());
  if (can_georeference && !model.images.empty()) {
    const GeoreferenceOptions go = GeoreferenceStageOptions(o, ingest);
    const GeoreferenceReport georef = AdjustSurvey(&model, inputs, go);
    for (const Finding& f : georef.findings) {
      Log(o, std::string(f.severity == Severity::kError ? "error: " : "warning: ") + f.code + ": " +
                 f.message);
    }
    report = GeoreferenceReportJson(georef, model);
    WriteCameraProducts(georef, model, o.workspace);
  } else {
    Log(o, "warning: no GPS and no control points: the survey is not georeferenced "
           "(arbitrary frame and scale)");
    report["crs"] = nullptr;
    report["georeferenced"] = false;
    report["adjustment"]["final_rms_px"] = 0.0;
  }
  report["georeferenced"] = can_georeference && !model.images.empty();
  report["gsd_m"] = MedianGsd(model);
  report["pixels"] = "sparse/ holds full-resolution pixels; adjustment figures are at the working "
                     "resolution (longer side " + std::to_string(o.features.max_dimension) + " px)";
  int registered = 0;
  const json images = ImagesJson(model, recon, ingest, &registered);
  report["images"] = {{"total", ingest.names.size()}, {"registered", registered}, {"per_image", images}};
  report["reconstruction"] = {{"initial_pair", recon.initial_pair},
                              {"tracks", recon.tracks},
                              {"component_images", recon.component_images},
                              {"focal_held", recon.focal_held},
                              {"gps_anchored_at_images", recon.gps_anchored_at_images},
                              {"rolling_shutter_images", recon.rolling_shutter_images}};
  if (fs::exists(o.workspace / "matches.json")) {
    const json m = ToJson(LoadMatchRecord(o));
    report["matching"] = {{"strategy", m.at("strategy")},
                          {"candidate_pairs", m.at("candidate_pairs")},
                          {"verified_pairs", m.at("verified_pairs")},
                          {"per_image", m.at("images")}};
  }
  report["georeference_options"] = GeoreferenceFingerprint(o);
  report["provenance"] = Provenance(o, ingest.record.options);
  const json ingest_doc = ToJson(ingest.record);
  report["camera_groups"] = ingest_doc.at("groups");
  AddIntrinsicsInMmOf(o, ingest, &report);
  report["ingest_warnings"] = ingest_doc.at("warnings");
  // What the photos say about their cameras, by vendor (ingest.json has it per photo).
  report["camera_metadata"] = ingest_doc.value("camera_metadata", json::object());

  AddMarking(o, &report);
  SetSurveyStatus(recon, ingest, registered, &report);

  WriteColmapText(ToFullResolution(model, ingest), o.workspace / "sparse");
  fs::remove_all(o.workspace / "depth");  // depth maps of an earlier model are stale
  fs::remove_all(o.workspace / "dense_parts");  // and so are a workflow's dense shares
  for (const char* stale : {"cloud.las", "cloud.laz", "cloud.copc.laz", "cloud.ply", "dsm.tif", "dense.json", "report.html"}) {
    fs::remove(o.workspace / stale);  // so are the deliverables: the dense stage reruns
  }
  // The working-resolution model in ENU feeds dense matching.
  WriteColmapText(model, o.workspace / "georeferenced");
  RecordTiming(o, "georeference", std::chrono::duration<double>(Clock::now() - start).count());
  if (fs::exists(o.workspace / "timings.json")) {
    report["timings"] = json::parse(ReadTextFile(o.workspace / "timings.json"));
  }
  WriteTextFileAtomically(report_path, report.dump(2) + "\n");
  return true;
}

std::string SurveyStatusOf(const std::filesystem::path& workspace) {
  const fs::path path = workspace / "report.json";
  if (!fs::exists(path)) return "";
  return ReadJson(path, "georeference").value("status", "");
}

void PipelineOptions::Check() const {
  CheckOption(num_threads >= 0, "--threads", num_threads, "0 (all cores) or more");
  CheckOption(dense_shares >= 1 && dense_shares <= 10000, "the number of dense shares", dense_shares,
              "1 to 10000");
  CheckOption(ortho_shares >= 1 && ortho_shares <= 10000, "the number of ortho shares", ortho_shares,
              "1 to 10000");
  CheckOption(ortho_share >= 0 && ortho_share < ortho_shares, "the ortho share", ortho_share + 1,
              "1 to the number of shares (" + std::to_string(ortho_shares) + ")");
  CheckOption(dense_share >= 0 && dense_share < dense_shares, "the dense share", dense_share + 1,
              "1 to the number of shares (" + std::to_string(dense_shares) + ")");
  CheckOption(gps_sigma_h_m > 0.0 && std::isfinite(gps_sigma_h_m), "--gps-sigma-h", gps_sigma_h_m,
              "a positive number of metres");
  CheckOption(gps_sigma_v_m > 0.0 && std::isfinite(gps_sigma_v_m), "--gps-sigma-v", gps_sigma_v_m,
              "a positive number of metres");
  features.Check();
  matching.Check();
  mapper.Check();
  georef.Check();
  const auto non_negative = [](double v) { return v >= 0.0 && std::isfinite(v); };
  const auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  CheckOption(non_negative(dense_resolution_m), "--dense-resolution", dense_resolution_m,
              "0 (the GSD) or a positive number of metres");
  CheckOption(dense_image_scale > 0.0 && dense_image_scale <= 1.0, "dense image scale", dense_image_scale,
              "a fraction of the working images in (0, 1]");
  CheckOption(dense_min_views >= 1, "--dense-min-views", dense_min_views, "at least 1 depth map");
  CheckOption(non_negative(dsm_resolution_m), "--dsm-resolution", dsm_resolution_m,
              "0 (twice the dense spacing) or a positive number of metres");
  CheckOption(non_negative(dsm_fill_m), "--dsm-fill", dsm_fill_m, "0 (no filling) or a positive number of metres");
  CheckOption(heights == "egm96" || heights == "ellipsoidal", "--heights", heights, "egm96 or ellipsoidal");
  CheckOption(positive(ground_cell_m), "--ground-cell", ground_cell_m, "a positive number of metres");
  CheckOption(positive(ground_window_m), "--ground-window", ground_window_m, "a positive number of metres");
  CheckOption(non_negative(ground_slope), "--ground-slope", ground_slope, "a slope (rise / run) of 0 or more");
  CheckOption(non_negative(ground_threshold_m), "--ground-threshold", ground_threshold_m, "0 or more metres");
  CheckOption(non_negative(contour_interval_m), "--contour-interval", contour_interval_m,
              "0 (automatic) or a positive number of metres");
  CheckOption(non_negative(ortho_resolution_m), "--ortho-resolution", ortho_resolution_m,
              "0 (the GSD) or a positive number of metres");
  CheckOption(ortho_surface == "dsm" || ortho_surface == "dtm", "--ortho-surface", ortho_surface, "dsm or dtm");
  CheckOption(ortho_compress == "JPEG" || ortho_compress == "DEFLATE", "--ortho-compress", ortho_compress,
              "JPEG or DEFLATE");
}

void ValidateInputs(const PipelineOptions& o) {
  o.Check();
  if (!o.images_dir.empty() && !fs::is_directory(o.images_dir)) {
    throw IoError(o.images_dir.string(), "not a folder of images");
  }
  if (!o.images_dir.empty()) IngestStageOptions(o).Check();
  if (!o.gps_csv.empty()) ReadGpsFile(o.gps_csv, o.gps_altitude, o.gps_sigma_h_m, o.gps_sigma_v_m);
  // Control and check files: readable, their CRS known to PROJ, their images
  // in the folder (a name that is not is a warning: that line is skipped).
  std::set<std::string> photos;
  if (!o.images_dir.empty()) {
    for (const auto& entry : fs::directory_iterator(o.images_dir)) photos.insert(entry.path().filename().string());
  }
  if (!o.camera_file.empty()) ReadCameraFile(o.camera_file);  // its errors name file and line
  for (const fs::path& path : {o.gcp, o.checkpoints}) {
    if (path.empty()) continue;
    const GcpFile file = ReadGcpFile(path, o.gcp_pixel_origin);
    CheckGcpFileCrs(file);
    if (photos.empty()) continue;
    std::set<std::string> unknown;
    for (const GroundPoint& p : file.points) {
      for (const GcpMeasurement& m : p.measurements) {
        if (!photos.count(m.image)) unknown.insert(m.image);
      }
    }
    if (!unknown.empty()) {
      std::string names;
      for (const auto& n : unknown) names += (names.empty() ? "" : ", ") + n;
      Log(o, "warning: " + path.string() + ": images not in " + o.images_dir.string() +
                 " (their measurements are skipped): " + names);
    }
  }
  if (!o.gcp.empty() && !o.checkpoints.empty()) {
    CheckChecksIndependent(ReadGcpFile(o.gcp, o.gcp_pixel_origin), ReadGcpFile(o.checkpoints, o.gcp_pixel_origin),
                           o.georef.gcp_sigma_h_m, o.georef.gcp_sigma_v_m);
  }
  // The workspace: writable, and room for it (about 40 times the photos'
  // size with the dense stage's depth maps; the sample survey used 861 MB
  // for 3.9 MB of photos at full resolution).
  fs::create_directories(o.workspace);
  const fs::path probe = o.workspace / ".aerotri_write_test";
  {
    std::ofstream out(probe);
    if (!out || !(out << "ok")) throw IoError(o.workspace.string(), "cannot write in the output folder");
  }
  fs::remove(probe);
  std::uintmax_t photo_bytes = 0;
  if (!o.images_dir.empty()) {
    for (const auto& entry : fs::directory_iterator(o.images_dir)) {
      if (entry.is_regular_file()) photo_bytes += entry.file_size();
    }
  }
  const fs::space_info space = fs::space(o.workspace);
  if (photo_bytes > 0 && space.available < 40 * photo_bytes) {
    Log(o, "warning: " + o.workspace.string() + " has " + std::to_string(space.available >> 20) +
               " MB free; a survey of " + std::to_string(photo_bytes >> 20) + " MB of photos may need up to " +
               std::to_string((40 * photo_bytes) >> 20) + " MB");
  }
}

void RemoveDepthMaps(const PipelineOptions& o) {
  const fs::path depth = o.workspace / "depth";
  if (o.keep_depth_maps || !fs::exists(depth)) return;
  std::uintmax_t bytes = 0;
  for (const auto& entry : fs::recursive_directory_iterator(depth)) {
    std::error_code ec;
    if (entry.is_regular_file(ec)) bytes += entry.file_size(ec);
  }
  fs::remove_all(depth);
  Log(o, "dense: removed " + depth.string() + " (the depth maps, " + std::to_string(bytes >> 20) +
             " MB, fused into the cloud; --keep-depth-maps keeps them)");
}

std::string RunPipeline(const PipelineOptions& given) {
  ValidateInputs(given);
  RunIngestStage(given);
  CheckMarkingPossible(given);
  RunFeatureStage(given);
  RunMatchStage(given);
  RunReconstructStage(given);
  RunMarkStage(given);
  // From here on, control and check files of coordinates alone are their marks.
  const PipelineOptions o = WithMarks(given);
  RunGeoreferenceStage(o);
  const std::string status = SurveyStatusOf(o.workspace);
  if (status == "failed" && !o.keep_going) {
    Log(o, "warning: the adjustment failed (report.json errors): no cloud or DSM is written "
           "(--keep-going writes them, tagged as failed)");
  } else {
    RunDenseStage(o);
    RunOrthoStage(o);
  }
  RunReportStage(o);
  return status;
}

}  // namespace aerotri
