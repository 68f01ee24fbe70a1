// SPDX-License-Identifier: BSD-3-Clause
// aerotri adjust: georeference an existing reconstruction (COLMAP text model)
// with GPS and ground control, self-calibrating, and report accuracy on check
// points.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>

#include "georef/gcp_file.h"
#include "georef/tie_point_file.h"
#include "libphoto/adjust/camera_file.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/survey/initial_orientation.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/directory_lock.h"
#include "libphoto/base/error.h"
#include "libphoto/pipeline/survey_adjustment.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/ingest/image_metadata.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/report/report_json.h"
#include "tools/commands.h"

namespace aerotri {
namespace fs = std::filesystem;

void RegisterAdjustCommand(CLI::App& app, CommandAction* run) {
  auto a = std::make_shared<AdjustArgs>();
  CLI::App* cmd = app.add_subcommand(
      "adjust",
      "Georeference and adjust an existing reconstruction (COLMAP text model, any frame and "
      "scale), or image measurements alone (--measurements, a classic aerial triangulation), with "
      "GPS priors and ground control; writes OUTPUT/model (COLMAP text, local ENU metres) and "
      "OUTPUT/report.json with check-point accuracy");
  CLI::Option* model =
      cmd->add_option("--model", a->model_dir, "COLMAP text model folder (cameras.txt, images.txt, points3D.txt)")
          ->check(CLI::ExistingDirectory);
  CLI::Option* measurements =
      cmd->add_option("--measurements", a->measurements,
                      "Tie-point measurements instead of a model: lines 'image point im_x im_y [sigma_px=S]' "
                      "(pixels as --gcp-pixel-origin); with --camera-file (width, height, f) and --gcp: "
                      "initial values by space resection and forward intersection, then the bundle")
          ->check(CLI::ExistingFile);
  model->excludes(measurements);
  measurements->excludes(model);
  cmd->add_option("--images", a->images_dir, "Folder of the model's images, for their EXIF GPS")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--gcp", a->gcp, "Ground control points, OpenDroneMap gcp_list.txt format");
  cmd->add_option("--checkpoints", a->checkpoints,
                  "Check points (same format); never used in the adjustment");
  cmd->add_option("--gps-csv,--geo", a->gps_csv,
                  "Camera positions overriding EXIF: a CSV name,lat,lon,alt[,sigma_h,sigma_v] (degrees, metres), "
                  "or OpenDroneMap's geo.txt (a CRS line, then image x y z [yaw pitch roll] [horz_accuracy "
                  "vert_accuracy])");
  cmd->add_option("--gps-sigma-h", a->gps_sigma_h_m, "GPS horizontal sigma (metres)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--gps-sigma-v", a->gps_sigma_v_m, "GPS vertical sigma (metres)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--gps-altitude", a->gps_altitude,
                  "Reference of EXIF / CSV GPS altitudes: egm96 (EXIF's 'above sea level') or "
                  "ellipsoid (WGS84)")
      ->check(CLI::IsMember({"egm96", "ellipsoid"}))->capture_default_str();
  cmd->add_option("--gcp-sigma-h", a->gcp_sigma_h_m,
                  "Control point horizontal sigma (metres) when the file gives none")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--gcp-sigma-v", a->gcp_sigma_v_m,
                  "Control point vertical sigma (metres) when the file gives none")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--gcp-pixel-origin", a->gcp_pixel_origin,
                  "Pixel convention of GCP files: centre (OpenDroneMap / OpenSfM: integers at pixel "
                  "centres) or corner (COLMAP: top-left pixel centre at 0.5, 0.5)")
      ->check(CLI::IsMember({"corner", "centre", "center"}))->capture_default_str();
  cmd->add_option("--crs", a->crs,
                  "Output CRS (EPSG:32632, EPSG:32632+5773, WKT, PROJ string); default: the GCP "
                  "file's CRS, else the UTM zone of the survey centre");
  AddAdjustmentPolicyOptions(cmd, &a->policy);
  cmd->add_option("--solver", a->solver,
                  "auto: aerotri's Schur Levenberg-Marquardt, its reduced camera system dense up to 4,000 "
                  "columns and sparse (CHOLMOD) beyond; dense or sparse: that engine with the system so held; "
                  "ceres: Ceres' solver, the reference (the same results; for comparisons and benchmarks)")
      ->check(CLI::IsMember({"auto", "dense", "sparse", "ceres"}))->capture_default_str();
  cmd->add_option("--loss", a->loss,
                  "Robust loss on reprojection residuals of the screening solve that finds the blunders (the "
                  "estimate is least squares on the observations it keeps); none: least squares throughout")
      ->check(CLI::IsMember({"none", "huber", "cauchy", "tukey"}))->capture_default_str();
  cmd->add_option("--loss-scale", a->loss_scale_px, "Robust loss scale (pixels)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--outlier-threshold", a->outlier_threshold_px,
                  "Reject observations above this reprojection error (pixels) and re-solve; 0 = off")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--threads", a->threads, "Threads (0 = all cores)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--max-iterations", a->max_iterations, "Maximum solver iterations per round")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--output,-o", a->output, "Output folder")->required();
  measurements->needs(cmd->get_option("--camera-file"));
  cmd->callback([a, run]() {
    if (a->model_dir.empty() && a->measurements.empty()) {
      throw CLI::RequiredError("--model (a reconstruction) or --measurements (tie points, with --camera-file)");
    }
    *run = [a](ToolContext& ctx) { return RunAdjust(*a, ctx); };
  });
}

namespace {

// The initial orientation of a block from measurements, for report.json.
nlohmann::json InitialOrientationJson(const InitialOrientationReport& r) {
  nlohmann::json images = nlohmann::json::array();
  for (const ImageOrientationResult& i : r.images) {
    images.push_back({{"name", i.name}, {"oriented", i.oriented}, {"how", i.how}, {"round", i.round}});
  }
  return {{"seed", r.seed},
          {"control_frame", r.control_frame},
          {"images_measured", r.images.size()},
          {"images_oriented", r.oriented},
          {"tie_points", r.tie_points},
          {"tie_points_intersected", r.tie_points_intersected},
          {"rounds", r.rounds},
          {"suspect_marks", r.suspect_marks},
          {"images", images}};
}

}  // namespace

namespace {

// What the model's photos say about their capture: gimbal angles (DJI XMP),
// to check the adjusted attitudes against, and rolling shutters
// (RollingShutterStatedBy), to adjust with; unreadable photos are
// GpsFromImages' to name.
void ReadWhatThePhotosSay(const SparseModel& model, const std::string& images_dir,
                          std::map<std::string, GimbalAttitude>* gimbal,
                          std::map<std::string, RollingShutterMotion>* shutters, std::string* shutter_source) {
  for (const Image& image : model.images) {
    const fs::path path = fs::path(images_dir) / image.name;
    if (!fs::exists(path)) continue;  // GpsFromImages has said so
    try {
      const ImageMetadata m = ReadImageMetadata(path);
      if (m.gimbal_pitch_deg && m.gimbal_yaw_deg) (*gimbal)[image.name] = {*m.gimbal_pitch_deg, *m.gimbal_yaw_deg};
      if (const auto stated = RollingShutterStatedBy(m)) {
        (*shutters)[image.name] = {stated->readout_time_s, Eigen::Vector3d(stated->east_mps, stated->north_mps, 0.0)};
        if (shutter_source->find(stated->source) == std::string::npos) {
          *shutter_source += (shutter_source->empty() ? "" : " | ") + stated->source;
        }
      }
    } catch (const Error&) {
      // unreadable: GpsFromImages has said so
    }
  }
}

// What made an adjust report: the process, and the options and inputs as
// the georeference stage fingerprints them (content hashes of the files).
nlohmann::json AdjustProvenance(const AdjustArgs& args, const GeoreferenceOptions& options, PixelOrigin origin,
                                const ToolContext& ctx) {
  PipelineOptions o;
  o.workspace = args.output;
  o.gcp = args.gcp;
  o.checkpoints = args.checkpoints;
  o.camera_file = args.policy.camera_file;
  o.gcp_pixel_origin = origin;
  o.georef = options;
  nlohmann::json georeference = GeoreferenceFingerprint(o);
  georeference.erase("ingest");  // no ingest stage: the model and positions below instead
  nlohmann::json p = ProcessProvenance(VersionString(), ctx.command_line);
  p["options"] = {{"georeference", georeference},
                  {"model", args.model_dir.empty() ? "" : fs::absolute(args.model_dir).string()},
                  {"measurements", ContentHash(args.measurements)},
                  {"images", args.images_dir.empty() ? "" : fs::absolute(args.images_dir).string()},
                  {"gps_csv", ContentHash(args.gps_csv)},
                  {"gps_altitude", args.gps_altitude},
                  {"threads", args.threads}};
  return p;
}

// The stdout line of figures. An RMSE over no points is not a figure:
// "nan", never a reassuring 0.0000.
std::string FiguresLine(const GeoreferenceReport& report, const std::string& status) {
  const auto rmse = [](int count, double value) { return count > 0 ? value : std::nan(""); };
  char line[512];
  std::snprintf(line, sizeof(line),
                "status=%s crs=%s final_rms_px=%.4f control_count=%d control_rmse_3d_m=%.4f "
                "check_count=%d check_rmse_h_m=%.4f check_rmse_v_m=%.4f check_rmse_3d_m=%.4f\n",
                status.c_str(), report.crs.c_str(), report.bundle.final_rms_px, report.control_stats.count,
                rmse(report.control_stats.count, report.control_stats.rmse_3d_m), report.check_stats.count,
                rmse(report.check_stats.count, report.check_stats.rmse_h_m),
                rmse(report.check_stats.count, report.check_stats.rmse_z_m),
                rmse(report.check_stats.count, report.check_stats.rmse_3d_m));
  return line;
}

}  // namespace

int RunAdjust(const AdjustArgs& args, ToolContext& ctx) {
  const fs::path output(args.output);
  if (args.model_dir.empty() && args.measurements.empty()) {
    throw InvalidArgument("give --model (a reconstruction) or --measurements (tie points, with --camera-file)");
  }
  if (!args.measurements.empty() && args.policy.camera_file.empty()) {
    throw InvalidArgument("--measurements needs --camera-file (the camera's width, height and f at least)");
  }
  if (!args.model_dir.empty() && fs::exists(output) && fs::equivalent(output, args.model_dir)) {
    throw InvalidArgument("--output must differ from --model: inputs are never modified");
  }
  if (args.images_dir.empty() && args.gps_csv.empty() && args.gcp.empty()) {
    throw InvalidArgument("nothing to georeference with: give --images (EXIF GPS), --gps-csv "
                          "or --gcp");
  }
  const DirectoryLock lock(output);  // one process per output folder
  for (const fs::path& p : RemoveStaleTemporaryFiles(output)) {
    ctx.Info("removed " + p.string() + " (left by an interrupted run)");
  }
  GeoreferenceOptions options;
  options.output_crs = args.crs;
  options.gcp_sigma_h_m = args.gcp_sigma_h_m;
  options.gcp_sigma_v_m = args.gcp_sigma_v_m;
  options.progress = ctx.Progress("adjust");
  BundleOptions& bundle = options.bundle;
  ApplyAdjustmentOptions(args.loss, args.loss_scale_px, "all", &bundle);
  ApplyAdjustmentPolicy(args.policy, &options);
  bundle.outlier_threshold_px = args.outlier_threshold_px;
  bundle.num_threads = args.threads;
  bundle.max_iterations = args.max_iterations;
  if (args.solver == "ceres") bundle.engine = BundleEngine::kCeres;
  if (args.solver == "dense" || args.solver == "sparse") {
    bundle.engine = BundleEngine::kAerotri;
    bundle.reduced_storage = args.solver == "dense" ? ReducedStorage::kDense : ReducedStorage::kSparse;
  }

  const PixelOrigin origin = args.gcp_pixel_origin == "corner" ? PixelOrigin::kCorner : PixelOrigin::kCentre;
  // From measurements: every input read and checked before anything is
  // computed; the model comes from the initial orientation below.
  SparseModel model;
  TiePointFile ties;
  std::optional<GcpFile> control;
  std::optional<Camera> certificate;
  std::vector<std::string> names;  // the images, for their GPS
  if (!args.model_dir.empty()) {
    ctx.Info("reading model " + args.model_dir);
    model = ReadColmapText(args.model_dir);
    ctx.Info("model: " + std::to_string(model.cameras.size()) + " cameras, " +
             std::to_string(model.images.size()) + " images, " +
             std::to_string(model.points.size()) + " points, " +
             std::to_string(model.observations.size()) + " observations");
    for (const Image& image : model.images) names.push_back(image.name);
  } else {
    ties = ReadTiePointFile(args.measurements, origin);
    certificate = ReadCameraFile(args.policy.camera_file).ToCamera();
    if (!args.gcp.empty()) {
      control = ReadGcpFile(args.gcp, origin);
      CheckGcpFileCrs(*control);
    }
    std::set<std::string> unique;
    for (const TieMeasurement& m : ties.measurements) unique.insert(m.image);
    if (control) {
      for (const GroundPoint& g : control->points) {
        for (const GcpMeasurement& m : g.measurements) unique.insert(m.image);
      }
    }
    names.assign(unique.begin(), unique.end());
    ctx.Info("measurements: " + std::to_string(ties.measurements.size()) + " tie marks on " +
             std::to_string(names.size()) + " images");
  }

  const AltitudeReference reference =
      args.gps_altitude == "ellipsoid" ? AltitudeReference::kEllipsoid : AltitudeReference::kEgm96;
  std::map<std::string, GpsFix> gps;
  std::vector<std::string> warnings;
  if (!args.images_dir.empty()) {
    gps = GpsFromImages(names, args.images_dir, reference, args.gps_sigma_h_m, args.gps_sigma_v_m,
                        &warnings);
    ctx.Info("EXIF GPS: " + std::to_string(gps.size()) + " of " + std::to_string(names.size()) + " images");
  }
  // Gimbal angles (DJI XMP), to check the adjusted attitudes against, and
  // rolling shutters, to adjust with.
  std::map<std::string, GimbalAttitude> gimbal;
  if (!args.images_dir.empty()) {
    ReadWhatThePhotosSay(model, args.images_dir, &gimbal, &options.rolling_shutter, &options.rolling_shutter_source);
  }
  if (!args.gps_csv.empty()) {
    const auto csv = ReadGpsFile(args.gps_csv, reference, args.gps_sigma_h_m, args.gps_sigma_v_m);
    for (const auto& [name, fix] : csv) gps[name] = fix;
    ctx.Info("GPS CSV: " + std::to_string(csv.size()) + " positions (override EXIF)");
  }
  std::optional<InitialOrientationReport> initial;
  if (certificate) {
    initial.emplace();
    model = OrientFromMeasurements(*certificate, ties, control ? &*control : nullptr, gps, {}, &*initial);
    ctx.Info("initial orientation: " + initial->seed + "; " + std::to_string(initial->oriented) + " of " +
             std::to_string(initial->images.size()) + " images oriented, " +
             std::to_string(initial->tie_points_intersected) + " of " + std::to_string(initial->tie_points) +
             " tie points intersected");
    for (const std::string& w : initial->warnings) warnings.push_back(args.measurements + ": " + w);
  }
  SurveyAdjustmentInputs inputs;
  inputs.gps = std::move(gps);
  inputs.gcp = args.gcp;
  inputs.checkpoints = args.checkpoints;
  inputs.gcp_pixel_origin = origin;
  inputs.camera_file = args.policy.camera_file;
  inputs.input_warnings = warnings;
  inputs.gimbal = std::move(gimbal);
  const GeoreferenceReport report = AdjustSurvey(&model, inputs, options);
  for (const Finding& f : report.findings) {
    ctx.Warn((f.severity == Severity::kError ? "error " : "") + f.code + ": " + f.message);
  }

  WriteColmapText(model, output / "model");
  nlohmann::json json = GeoreferenceReportJson(report, model);
  if (initial) json["initial_orientation"] = InitialOrientationJson(*initial);
  json["provenance"] = AdjustProvenance(args, options, origin, ctx);
  // The certificate's pixel pitch states the calibration in mm as well.
  if (!args.policy.camera_file.empty() && json.contains("adjustment")) {
    const double pitch = ReadCameraFile(args.policy.camera_file).pixel_size_mm;
    if (pitch > 0.0) AddIntrinsicsInMm(&json["adjustment"], std::vector<double>(model.cameras.size(), pitch), "the camera file");
  }
  WriteTextFileAtomically(output / "report.json", json.dump(2) + "\n");
  WriteCameraProducts(report, model, output);
  ctx.Info(report.bundle.BriefReport());
  ctx.Info("wrote " + (output / "model").string() + ", " + (output / "report.json").string() +
           ", cameras.csv, exterior_orientation.csv, cameras.gpkg and tie_points.csv");

  const std::string status = SurveyStatus(report.findings);
  *ctx.out << FiguresLine(report, status) << std::flush;
  if (status == "failed") {
    for (const Finding& f : report.findings) {
      if (f.severity == Severity::kError) ctx.Error("survey failed: " + f.code + ": " + f.message);
    }
    return 1;
  }
  return 0;
}

}  // namespace aerotri
