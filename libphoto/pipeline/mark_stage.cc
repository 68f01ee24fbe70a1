// SPDX-License-Identifier: BSD-3-Clause
// The mark stage: control and check points given as coordinates only are
// found in the photos (libphoto/targets/marking.h) after the reconstruction
// and before the georeferencing, and written as gcp_list.txt files in the
// workspace, which the later stages read in the coordinates' place.
#include <chrono>
#include <filesystem>
#include <tuple>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/report/review_page.h"
#include "libphoto/targets/marking.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A file that cannot be read is not (its reader's error comes from the
// stage that needs it, in that stage's order of checks).
bool CoordinatesOnly(const fs::path& path, PixelOrigin origin) {
  if (path.empty()) return false;
  try {
    return ReadGcpFile(path, origin).coordinates_only;
  } catch (const Error&) {
    return false;
  }
}

// control, checks: the coordinate lists marked (their CRS lines and each
// point's coordinates go into marks.json, so the review page exports lines
// from marks.json alone).
json MarkingJson(const MarkingResult& r, const GcpFile& control, const GcpFile& checks) {
  json points = json::array();
  int marked[2] = {0, 0}, total[2] = {0, 0};
  for (const PointMarking& p : r.points) {
    json photos = json::array();
    for (const TargetMark& m : p.photos) {
      json e = {{"image", m.image}, {"predicted_px", {m.predicted_px.x(), m.predicted_px.y()}}, {"marked", m.detected}};
      if (m.detected) {
        e["xy_px"] = {m.xy_px.x(), m.xy_px.y()};
        e["confidence"] = m.confidence;
        e["kind"] = TargetKindName(m.kind);
        e["reprojection_px"] = m.reprojection_px;
      }
      photos.push_back(e);
    }
    json e = {{"name", p.name}, {"role", p.check ? "check" : "control"}, {"status", p.status}, {"photos", photos}};
    for (const GroundPoint& g : (p.check ? checks : control).points) {
      if (g.name != p.name) continue;
      e["coordinates"] = GcpCoordinatesText(g);
      e["sigmas"] = GcpSigmasText(g);
    }
    if (!p.reason.empty()) e["reason"] = p.reason;
    if (p.Marked()) e["offset_from_gps_georeferencing_m"] = {p.offset_m.x(), p.offset_m.y(), p.offset_m.z()};
    ++total[p.check];
    marked[p.check] += p.Marked();
    points.push_back(e);
  }
  json files = json::object();
  if (control.coordinates_only && !control.points.empty()) files["control"] = {{"path", control.path}, {"crs", control.crs}};
  if (checks.coordinates_only && !checks.points.empty()) files["check"] = {{"path", checks.path}, {"crs", checks.crs}};
  const std::string method =
      r.method == "gps"
          ? "each point predicted through the model georeferenced by the photos' GPS; targets detected within the "
            "search radius, joined across photos by triangulation"
          : "photos without GPS: every target in every photo, joined across photos by triangulation (3 photos or "
            "more), the coordinate list placed on them by a similarity (the most points on a target); each point "
            "then predicted through it, and marked as with GPS";
  json placement = nullptr;
  if (r.method == "targets") {
    placement = {{"targets_found", r.targets_found}, {"points_placed", r.placed_points},
                 {"rms_m", r.placement_rms_m}};
  }
  return {{"method", method},
          {"placement_by_targets", placement},
          {"search_radius_m", r.search_radius_m},
          {"gps_photos", r.gps_photos},
          {"control", {{"points", total[0]}, {"marked", marked[0]}}},
          {"checks", {{"points", total[1]}, {"marked", marked[1]}}},
          {"files", files},
          {"points", points}};
}

json MarkFingerprint(const PipelineOptions& o) {
  return {{"gcp", ContentHash(o.gcp)},
          {"checkpoints", ContentHash(o.checkpoints)},
          {"gcp_pixel_origin", o.gcp_pixel_origin == PixelOrigin::kCorner ? "corner" : "centre"},
          {"reconstruction", ContentHash(o.workspace / "reconstruction.json")}};
}

}  // namespace

bool NeedsMarking(const PipelineOptions& o) {
  return CoordinatesOnly(o.gcp, o.gcp_pixel_origin) || CoordinatesOnly(o.checkpoints, o.gcp_pixel_origin);
}

PipelineOptions WithMarks(const PipelineOptions& o) {
  PipelineOptions out = o;
  const std::pair<fs::path PipelineOptions::*, const char*> files[] = {{&PipelineOptions::gcp, "gcp_marks.txt"},
                                                                        {&PipelineOptions::checkpoints, "check_marks.txt"}};
  for (const auto& [member, name] : files) {
    if (!CoordinatesOnly(o.*member, o.gcp_pixel_origin)) continue;
    const fs::path marks = o.workspace / name;
    if (!fs::exists(o.workspace / "marks.json")) {
      throw IoError(marks.string(), (o.*member).string() + " gives coordinates only and its targets have not been "
                                    "marked: run `aerotri mark` (or `aerotri run`) on this workspace first");
    }
    // No target found: the survey goes on without those points (marks.json
    // and the report say why).
    out.*member = fs::exists(marks) ? marks : fs::path();
    out.gcp_pixel_origin = PixelOrigin::kCentre;  // aerotri writes its marks so
  }
  return out;
}

namespace {

// The frame the list and the GPS are compared in: the photos' GPS origin,
// else the list's first point (photos without GPS). UsageError when neither
// places the list on the Earth (a LOCAL list and photos without GPS).
Geodetic MarkingOrigin(const PipelineOptions& o, const IngestView& ingest) {
  if (const std::optional<Geodetic> origin = ingest.EnuOrigin()) return *origin;
  for (const fs::path& path : {o.gcp, o.checkpoints}) {
    if (!CoordinatesOnly(path, o.gcp_pixel_origin)) continue;
    const GcpFile file = ReadGcpFile(path, o.gcp_pixel_origin);
    try {
      Eigen::Vector3d xyz = file.points.at(0).xyz;
      if (file.points[0].horizontal_only) xyz.z() = 0.0;
      return Crs::FromString(file.crs).ToGeodetic(xyz);
    } catch (const Error& e) {
      throw UsageError(path.string() + ": the photos have no GPS, and its CRS line '" + file.crs +
                       "' does not place its points on the Earth (" + e.what() +
                       "); give the list in a CRS PROJ knows, or mark the targets by hand");
    }
  }
  throw UsageError("no coordinates-only list to mark");
}

}  // namespace

void CheckMarkingPossible(const PipelineOptions& o) {
  if (NeedsMarking(o)) MarkingOrigin(o, LoadIngest(o));
}

bool RunMarkStage(const PipelineOptions& o) {
  if (!NeedsMarking(o)) {
    // An earlier run's marks are not this run's control.
    for (const char* stale : {"marks.json", "marks.html", "gcp_marks.txt", "check_marks.txt"}) {
      fs::remove(o.workspace / stale);
    }
    return false;
  }
  const fs::path record = o.workspace / "marks.json";
  if (fs::exists(record) && !o.force && StageIsCurrent(o, "mark", record, "options", MarkFingerprint(o))) {
    return false;
  }
  const auto start = BeginStage();
  IngestView ingest = LoadIngest(o);
  const SparseModel model = ToFullResolution(ReadColmapText(o.workspace / "reconstruction"), ingest);
  std::map<std::string, GpsFix> gps;
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    if (ingest.gps[i]) gps[ingest.names[i]] = *ingest.gps[i];
  }
  const Geodetic origin = MarkingOrigin(o, ingest);
  const GcpFile control = o.gcp.empty() ? GcpFile{} : ReadGcpFile(o.gcp, o.gcp_pixel_origin);
  const GcpFile checks = o.checkpoints.empty() ? GcpFile{} : ReadGcpFile(o.checkpoints, o.gcp_pixel_origin);
  MarkingOptions mo;
  mo.num_threads = o.num_threads;
  mo.progress = StageProgress(o, "mark");
  // Only the files that need it are marked; a file of marks is used as it is.
  const GcpFile empty_control = GcpFile{control.path, control.crs, control.crs_line, true, {}};
  const MarkingResult r =
      MarkControl(model, ingest.ImagesDir(o), gps, origin, control.coordinates_only ? control : empty_control,
                  checks.coordinates_only ? &checks : nullptr, mo);
  for (const PointMarking& p : r.points) {
    if (!p.Marked()) Log(o, "warning: " + std::string(p.check ? "check" : "control") + " point " + p.name + ": " + p.status + ": " + p.reason);
  }
  for (const auto& [file, marks, name] : {std::tuple{&control, &r.control_marks, "gcp_marks.txt"},
                                          std::tuple{&checks, &r.check_marks, "check_marks.txt"}}) {
    fs::remove(o.workspace / name);
    if (file->coordinates_only && !marks->points.empty()) WriteGcpFile(*marks, o.workspace / name);
  }
  json doc = MarkingJson(r, control, checks);
  doc["options"] = MarkFingerprint(o);
  WriteTextFileAtomically(record, doc.dump(2) + "\n");
  WriteReviewPage(o, nullptr);
  RecordTiming(o, "mark", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return true;
}

void WriteReviewPage(const PipelineOptions& o, const json& report) {
  const fs::path record = o.workspace / "marks.json";
  if (!fs::exists(record)) return;
  ReviewPageInput in;
  in.marking = ReadJson(record, "mark");
  if (report.is_object() && report.contains("adjustment") && report["adjustment"].contains("data_snooping")) {
    in.adjustment_marks = report["adjustment"]["data_snooping"].value("marks", json());
  }
  in.title = fs::absolute(o.workspace).lexically_normal().filename().string();
  const fs::path images = LoadIngest(o).ImagesDir(o);
  const auto load = [&](const std::string& name) {
    return cv::imread((images / name).string(), cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
  };
  WriteTextFileAtomically(o.workspace / "marks.html", RenderReviewPage(in, load));
}

}  // namespace aerotri
