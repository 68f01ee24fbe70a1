// SPDX-License-Identifier: BSD-3-Clause
// aerotri run IMAGES --output DIR, and the stages as subcommands.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/directory_lock.h"
#include "libphoto/base/error.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/survey_split.h"
#include "tools/commands.h"

namespace aerotri {
namespace {

// The aerotri front end beside this executable (what a workflow should call).
std::filesystem::path AerotriExecutable() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "aerotri";
  const std::filesystem::path front = self.parent_path() / "aerotri";
  return std::filesystem::exists(front) ? front : self;
}

void AddDsmOptions(CLI::App* cmd, RunArgs* a) {
  cmd->add_option("--dsm-resolution", a->dsm_resolution_m,
                  "DSM pixel size (metres, in the output CRS); 0 = twice the dense spacing")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--dsm-fill", a->dsm_fill_m, "Fill DSM holes up to this distance (metres); 0 = no filling")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_flag("--cog", a->cog, "Write the DSM and DTM as Cloud-Optimised GeoTIFFs");
}

void AddTerrainOptions(CLI::App* cmd, RunArgs* a) {
  cmd->add_option("--heights", a->heights,
                  "Heights of the deliverables under a 2D output CRS: egm96 (EPSG code + 5773, EGM96 geoid heights, "
                  "when PROJ's grid is installed) or ellipsoidal (WGS84 ellipsoidal heights, said in the metadata)")
      ->check(CLI::IsMember({"egm96", "ellipsoidal"}))->capture_default_str();
  cmd->add_option("--ground-cell", a->ground_cell_m, "Ground filter (SMRF) grid cell (metres)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--ground-window", a->ground_window_m,
                  "Ground filter: widest object to remove, e.g. the largest building (metres)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--ground-slope", a->ground_slope, "Ground filter: steepest terrain kept as ground (rise / run)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--ground-threshold", a->ground_threshold_m,
                  "Ground filter: points within this height of the ground surface are ground (metres)")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--cloud-format", a->cloud_format,
                  "The dense cloud's file: laz (cloud.laz: LAS 1.4 compressed as LASzip does, about an eighth of "
                  "the size), copc (cloud.copc.laz: the same in an octree, a Cloud-Optimised Point Cloud that "
                  "QGIS, PDAL and web viewers read in place) or las (cloud.las, uncompressed)")
      ->check(CLI::IsMember({"laz", "copc", "las"}))->capture_default_str();
  cmd->add_option("--contour-interval", a->contour_interval_m,
                  "Contour interval (metres); 0 = a round number near a twentieth of the relief")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
}

void AddOrthoOptions(CLI::App* cmd, RunArgs* a, bool offer_skip) {
  if (offer_skip) cmd->add_flag("--no-ortho", a->no_ortho, "Do not draw the orthomosaic");
  cmd->add_option("--ortho-resolution", a->ortho_resolution_m,
                  "Orthomosaic cell (metres); 0 = the survey's GSD at the working resolution")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--ortho-surface", a->ortho_surface,
                  "Surface the photos are projected through: dsm (buildings upright, true ortho) or dtm")
      ->check(CLI::IsMember({"dsm", "dtm"}))->capture_default_str();
  cmd->add_option("--ortho-compress", a->ortho_compress, "Orthomosaic compression: jpeg (alpha as a mask) or deflate")
      ->check(CLI::IsMember({"jpeg", "deflate"}))->capture_default_str();
  cmd->add_flag("--ortho-no-cog", a->ortho_no_cog, "Write a plain tiled GeoTIFF with overviews instead of a COG");
}

void AddGcpPixelOriginOption(CLI::App* cmd, RunArgs* a) {
  cmd->add_option("--gcp-pixel-origin", a->gcp_pixel_origin, "Pixel convention of GCP files: centre (OpenDroneMap / OpenSfM: integers at pixel centres) or corner (COLMAP: top-left pixel centre at 0.5, 0.5)")
      ->check(CLI::IsMember({"corner", "centre", "center"}))->capture_default_str();
}

// The options a stage reads, as flags: a stage subcommand offers (and its
// --help lists) only its own; `run` offers them all.
enum OptionGroup : unsigned {
  kIngestOptions = 1u << 0,
  kFeatureOptions = 1u << 1,
  kMatchOptions = 1u << 2,
  kGeoreferenceOptions = 1u << 3,
  kDenseOptions = 1u << 4,
  kThreadsOption = 1u << 5,
  kRunOnlyOptions = 1u << 6,  // what only the whole run does (--no-ortho)
  kOrthoOptions = 1u << 7,
  kReconstructOptions = 1u << 8,
  kAllOptions = ~0u,
};

void AddWorkspaceOption(CLI::App* cmd, std::string* workspace, bool must_exist) {
  CLI::Option* opt = cmd->add_option("--output,-o,--survey", *workspace,
                                     must_exist ? "Survey workspace (the --output folder of aerotri run)"
                                                : "Survey workspace (output folder)")
                         ->required();
  if (must_exist) opt->check(CLI::ExistingDirectory);
}

// The georeference stage's options (control, check points, CRS and the
// adjustment policy).
void AddGeoreferenceOptions(CLI::App* cmd, RunArgs* a) {
  cmd->add_option("--gcp", a->gcp, "Ground control points (OpenDroneMap gcp_list.txt, full-resolution pixels)");
  cmd->add_option("--checkpoints", a->checkpoints, "Check points (same format); never used in the adjustment");
  AddGcpPixelOriginOption(cmd, a);
  cmd->add_option("--gcp-sigma-h", a->gcp_sigma_h_m, "Control horizontal sigma (metres) when the file gives none")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--gcp-sigma-v", a->gcp_sigma_v_m, "Control vertical sigma (metres) when the file gives none")
      ->check(CLI::PositiveNumber)->capture_default_str();
  AddAdjustmentPolicyOptions(cmd, &a->policy);
  cmd->add_option("--crs", a->crs, "Output CRS; default: the GCP file's, else the UTM zone of the survey");
}

// The options from index `first` on of cmd that the command line gave, as
// arguments again ("--name" for a flag, "--name" and each value for the
// others); the values of `paths` made absolute, for a command run
// elsewhere.
std::vector<std::string> GivenOptions(const CLI::App& cmd, size_t first, const std::set<std::string>& paths) {
  std::vector<std::string> args;
  const std::vector<const CLI::Option*> options = cmd.get_options();
  for (size_t k = first; k < options.size(); ++k) {
    const CLI::Option& opt = *options[k];
    if (opt.count() == 0 || opt.get_lnames().empty()) continue;
    const std::string& name = opt.get_lnames().front();
    args.push_back("--" + name);
    if (opt.get_expected_min() == 0) continue;  // a flag
    for (const std::string& value : opt.results()) {
      args.push_back(paths.count(name) ? std::filesystem::absolute(value).string() : value);
    }
  }
  return args;
}

void AddStageOptions(CLI::App* cmd, RunArgs* a, bool images_positional, unsigned groups) {
  if (images_positional) {
    cmd->add_option("images", a->images_dir, "Folder of photos (.jpg, .jpeg, .tif)")
        ->required()->check(CLI::ExistingDirectory);
  }
  AddWorkspaceOption(cmd, &a->output, /*must_exist=*/false);
  cmd->add_flag("--force", a->force, "Redo stages whose product exists (default: resume)");
  if (groups & kDenseOptions) {
    cmd->add_flag("--keep-depth-maps", a->keep_depth_maps,
                  "Keep the dense stage's depth maps (depth/) after fusion; by default they are removed once "
                  "the cloud is written (they are most of a workspace, and nothing after fusion reads them)");
    cmd->add_flag("--keep-going", a->keep_going,
                  "Write the cloud and DSM even when the adjustment failed its quality gates (the report "
                  "says failed and the exit code stays 1)");
  }
  if (groups & kThreadsOption) {
    cmd->add_option("--threads", a->threads, "Threads (0 = all cores)")->check(CLI::NonNegativeNumber)->capture_default_str();
  }
  if (groups & kIngestOptions) {
    cmd->add_option("--gps-altitude", a->gps_altitude,
                    "Reference of EXIF / CSV GPS altitudes: egm96 (EXIF's 'above sea level') or ellipsoid")
        ->check(CLI::IsMember({"egm96", "ellipsoid"}))->capture_default_str();
    cmd->add_option("--gps-sigma-h", a->gps_sigma_h_m, "GPS horizontal sigma (metres)")->check(CLI::PositiveNumber)->capture_default_str();
    cmd->add_option("--gps-sigma-v", a->gps_sigma_v_m, "GPS vertical sigma (metres)")->check(CLI::PositiveNumber)->capture_default_str();
    cmd->add_option("--gps-csv,--geo", a->gps_csv,
                    "Camera positions overriding EXIF: a CSV name,lat,lon,alt[,sigma_h,sigma_v] (degrees, metres), "
                    "or OpenDroneMap's geo.txt (a CRS line, then image x y z [yaw pitch roll] [horz_accuracy "
                    "vert_accuracy])");
  }
  if (groups & (kIngestOptions | kFeatureOptions | kGeoreferenceOptions)) {
    cmd->add_option("--max-dimension", a->max_dimension,
                    "Working resolution: longer image side (pixels) for features and adjustment")
        ->check(CLI::Range(200, 20000))->capture_default_str();
  }
  if (groups & kFeatureOptions) {
    cmd->add_option("--max-features", a->max_features, "Features per image (spread over the image)")
        ->check(CLI::Range(100, 200000))->capture_default_str();
  }
  if (groups & kMatchOptions) {
    cmd->add_option("--gps-neighbours", a->gps_neighbours, "Images matched with each image's nearest GPS neighbours")
        ->check(CLI::Range(1, 1000))->capture_default_str();
  }
  if (groups & kReconstructOptions) {
    cmd->add_option("--local-ba-images", a->local_ba_images,
                    "Local bundle adjustment after each registration: the new image and its most connected "
                    "neighbours, this many in all, vary (the images around them held); 0 = none")
        ->check(CLI::Range(0, 1000))->capture_default_str();
    cmd->add_option("--global-ba-growth", a->global_ba_growth,
                    "Global bundle adjustment whenever the registered images have grown by this fraction")
        ->check(CLI::Range(0.01, 10.0))->capture_default_str();
    cmd->add_option("--global-ba-loss", a->global_ba_loss,
                    "Global bundle adjustments: 'screening' (Huber finds the blunders, least squares "
                    "estimates) or 'huber' (Huber in every solve)")
        ->check(CLI::IsMember({"screening", "huber"}))->capture_default_str();
    cmd->add_option("--iterative-ba-above", a->iterative_ba_above,
                    "Intermediate global adjustments of models above this many images solve by conjugate "
                    "gradients (the final one is always exact); 0 = never")
        ->check(CLI::NonNegativeNumber)->capture_default_str();
    cmd->add_option("--mapper-gps", a->mapper_gps,
                    "The photos' GPS in the reconstruction: 'check' (registrations that disagree with it are "
                    "undone) or 'priors' (also: once the registered fixes span the block, the model is moved "
                    "into the GPS frame and every later adjustment holds each fix with its sigmas, and the "
                    "photos' stated rolling shutter; for blocks that fold or bend)")
        ->check(CLI::IsMember({"check", "priors"}))->capture_default_str();
  }
  if (groups & kGeoreferenceOptions) AddGeoreferenceOptions(cmd, a);
  if (groups & kDenseOptions) {
    cmd->add_option("--dense-resolution", a->dense_resolution_m,
                    "Dense cloud spacing (metres); 0 = the survey's GSD at the working resolution")
        ->check(CLI::NonNegativeNumber)->capture_default_str();
    cmd->add_option("--dense-min-views", a->dense_min_views,
                    "Depth maps (two per photo) that must agree on a dense point: more is cleaner, fewer covers "
                    "more of hard surfaces such as tree canopy")
        ->check(CLI::Range(1, 50))->capture_default_str();
    AddDsmOptions(cmd, a);
    AddTerrainOptions(cmd, a);
  }
  if (groups & kOrthoOptions) AddOrthoOptions(cmd, a, groups & kRunOnlyOptions);
}

}  // namespace

namespace {

// "K/N" with 1 <= K <= N: a share of a split workflow's dense work.
std::string ShareValidator(const std::string& value) {
  const auto slash = value.find('/');
  try {
    size_t used_k = 0, used_n = 0;
    const int k = slash == std::string::npos ? 0 : std::stoi(value.substr(0, slash), &used_k);
    const int n = slash == std::string::npos ? 0 : std::stoi(value.substr(slash + 1), &used_n);
    if (used_k == slash && used_n == value.size() - slash - 1 && n >= 1 && n <= 10000 && k >= 1 && k <= n) return "";
  } catch (const std::exception&) {
  }
  return "Value " + value + " is not a share K/N (1 <= K <= N <= 10000), e.g. 2/4";
}

void AddDenseShareOptions(CLI::App* cmd, RunArgs* a) {
  auto* depth = cmd->add_option("--depth-share", a->depth_share,
                                "Only the depth maps of share K of N of the image pairs (a workflow's job; "
                                "several may run at once on one workspace)")
                    ->check(CLI::Validator(ShareValidator, "K/N"));
  auto* fuse = cmd->add_option("--fuse-share", a->fuse_share,
                               "Only the fusion of share K of N of the ground tiles, once every depth share is "
                               "done (a workflow's job)")
                   ->check(CLI::Validator(ShareValidator, "K/N"));
  auto* from = cmd->add_option("--from-shares", a->from_shares,
                               "The cloud, DSM, DTM and contours from the N fused shares (a workflow's last "
                               "dense job)")
                   ->check(CLI::Range(1, 10000));
  depth->excludes(fuse)->excludes(from);
  fuse->excludes(from);
}

void AddOrthoShareOptions(CLI::App* cmd, RunArgs* a) {
  auto* band = cmd->add_option("--band-share", a->band_share,
                               "Only the band of tile rows of share K of N (a workflow's job; several may run at "
                               "once on one workspace)")
                   ->check(CLI::Validator(ShareValidator, "K/N"));
  auto* from = cmd->add_option("--from-shares", a->from_shares,
                               "OUTPUT/ortho.tif from the N bands (a workflow's last ortho job)")
                   ->check(CLI::Range(1, 10000));
  band->excludes(from);
}

}  // namespace

void RegisterRunCommands(CLI::App& app, CommandAction* run) {
  struct Stage {
    const char* name;
    const char* help;
    bool needs_images;
    unsigned options;
  };
  const Stage stages[] = {
      {"run", "Photos to an adjusted, georeferenced survey and its deliverables: ingest, features, match, "
              "reconstruct, georeference, dense (cloud, DSM, DTM, contours), ortho, report (each stage resumes)",
       true, kAllOptions},
      {"ingest", "Read EXIF / XMP of a folder of photos into OUTPUT/ingest.json", true, kIngestOptions},
      {"features", "Extract SIFT features of the ingested photos (OUTPUT/features/)", false,
       kFeatureOptions | kThreadsOption},
      {"match", "Select, match and verify image pairs (OUTPUT/matches.bin)", false, kMatchOptions | kThreadsOption},
      {"reconstruct", "Incremental reconstruction from the matches (OUTPUT/reconstruction/)", false,
       kReconstructOptions | kThreadsOption},
      {"mark", "Find the targets of control and check points given as coordinates only ('name x y z', or "
               "PIX4D's CSV) in the photos of a reconstructed workspace: OUTPUT/gcp_marks.txt, check_marks.txt, "
               "marks.json and marks.html, the review page to check, move, reject and export marks (run marks "
               "them itself)", false, kGeoreferenceOptions | kThreadsOption},
      {"georeference", "Georeference and adjust with GPS and control; write OUTPUT/sparse/ and "
                       "OUTPUT/report.json", false, kGeoreferenceOptions | kThreadsOption},
      {"dense", "Dense matching and the deliverables: OUTPUT/cloud.laz (ground-classified), cloud.ply, dsm.tif, "
                "dtm.tif, contours.gpkg", false, kDenseOptions | kThreadsOption},
      {"ortho", "Orthomosaic through the DSM (or DTM): OUTPUT/ortho.tif, a Cloud-Optimised GeoTIFF", false,
       kOrthoOptions | kThreadsOption},
      {"report", "Complete report.json (DSM at check points, coverage) and write report.html (and marks.html with "
                 "the adjustment's residuals, where targets were marked)", false, 0u},
  };
  for (const Stage& s : stages) {
    auto a = std::make_shared<RunArgs>();
    a->stage = s.name;
    CLI::App* cmd = app.add_subcommand(s.name, s.help);
    AddStageOptions(cmd, a.get(), s.needs_images, s.options);
    if (a->stage == "dense") AddDenseShareOptions(cmd, a.get());
    if (a->stage == "ortho") AddOrthoShareOptions(cmd, a.get());
    cmd->callback([a, run]() { *run = [a](ToolContext& ctx) { return RunPipelineCommand(*a, ctx); }; });
  }
  {
    auto a = std::make_shared<RunArgs>();
    a->stage = "dem";
    CLI::App* cmd = app.add_subcommand("dem", "Rebuild a DSM from an existing survey's cloud (LAZ or LAS) at another resolution");
    AddWorkspaceOption(cmd, &a->output, /*must_exist=*/true);
    cmd->add_option("--dsm-output", a->dem_output, "DSM file to write (default: OUTPUT/dsm_<resolution>m.tif)");
    AddDsmOptions(cmd, a.get());
    cmd->callback([a, run]() { *run = [a](ToolContext& ctx) { return RunPipelineCommand(*a, ctx); }; });
  }
  {
    auto a = std::make_shared<RunArgs>();
    a->stage = "split";
    a->policy.leave_one_out = "on";
    CLI::App* cmd = app.add_subcommand(
        "split", "Split a survey by GPS into overlapping parts reconstructed on their own, merged and adjusted "
                 "once: ingests the photos, writes OUTPUT/parts/ and OUTPUT/Snakefile (run it with snakemake)");
    AddStageOptions(cmd, a.get(), /*images_positional=*/true, kIngestOptions | kThreadsOption);
    cmd->add_option("--parts", a->parts, "Number of parts (by recursive bisection of the GPS positions)")
        ->check(CLI::Range(2, 10000))->capture_default_str();
    cmd->add_option("--seam-margin", a->seam_margin_m,
                    "Photos within this distance (metres) of a part's cell join it, shared with its neighbour; "
                    "0 = 2.5 x the median distance between neighbouring photos")
        ->check(CLI::NonNegativeNumber)->capture_default_str();
    // The global adjustment's options, as georeference takes them: the
    // workflow's georeference step is given those the user gave.
    const size_t first_georeference_option = cmd->get_options().size();
    AddGeoreferenceOptions(cmd, a.get());
    cmd->callback([a, run, cmd, first_georeference_option]() {
      a->georeference_args = GivenOptions(*cmd, first_georeference_option, {"gcp", "checkpoints", "camera-file"});
      *run = [a](ToolContext& ctx) { return RunPipelineCommand(*a, ctx); };
    });
  }
  {
    auto a = std::make_shared<RunArgs>();
    a->stage = "merge";
    CLI::App* cmd = app.add_subcommand(
        "merge", "Merge the parts of a split survey (OUTPUT/parts/*/ws/reconstruction) into OUTPUT/reconstruction/ "
                 "for the global adjustment (georeference)");
    AddWorkspaceOption(cmd, &a->output, /*must_exist=*/true);
    cmd->callback([a, run]() { *run = [a](ToolContext& ctx) { return RunPipelineCommand(*a, ctx); }; });
  }
  {
    auto a = std::make_shared<RunArgs>();
    a->stage = "check";
    CLI::App* cmd = app.add_subcommand(
        "check", "Accuracy of an existing survey: against check points (--checkpoints), and leave-one-out over "
                 "its control points (--leave-one-out on, with --gcp and the options the survey ran with); "
                 "rewrites OUTPUT/report.json and report.html");
    a->policy.leave_one_out = "off";  // asked for: it adjusts the survey's reconstruction again
    AddStageOptions(cmd, a.get(), /*images_positional=*/false, kGeoreferenceOptions | kThreadsOption);
    cmd->callback([a, run]() {
      if (a->checkpoints.empty() && a->policy.leave_one_out != "on") {
        throw CLI::ValidationError("check", "give --checkpoints, --leave-one-out on (with --gcp), or both");
      }
      *run = [a](ToolContext& ctx) { return RunPipelineCommand(*a, ctx); };
    });
  }
}

namespace {

// The pipeline's options from the command line's (shares K/N into the
// share from 0 and the count), with the context's progress and log.
PipelineOptions PipelineOptionsOf(const RunArgs& a, ToolContext& ctx) {
  PipelineOptions o;
  // K/N (checked by ShareValidator) into the share (from 0) and the count.
  const auto share_of = [](const std::string& kn, int* share, int* shares) {
    *share = std::stoi(kn.substr(0, kn.find('/'))) - 1;
    *shares = std::stoi(kn.substr(kn.find('/') + 1));
  };
  if (!a.depth_share.empty() || !a.fuse_share.empty()) {
    o.dense_step = a.depth_share.empty() ? PipelineOptions::DenseStep::kFuseShare
                                         : PipelineOptions::DenseStep::kDepthShare;
    share_of(a.depth_share.empty() ? a.fuse_share : a.depth_share, &o.dense_share, &o.dense_shares);
  }
  if (a.from_shares > 0 && a.stage == "dense") {
    o.dense_step = PipelineOptions::DenseStep::kFromShares;
    o.dense_shares = a.from_shares;
  }
  if (!a.band_share.empty()) {
    o.ortho_step = PipelineOptions::OrthoStep::kBandShare;
    share_of(a.band_share, &o.ortho_share, &o.ortho_shares);
  }
  if (a.from_shares > 0 && a.stage == "ortho") {
    o.ortho_step = PipelineOptions::OrthoStep::kFromShares;
    o.ortho_shares = a.from_shares;
  }
  o.images_dir = a.images_dir;
  o.workspace = a.output;
  o.force = a.force;
  o.keep_going = a.keep_going;
  o.keep_depth_maps = a.keep_depth_maps;
  o.num_threads = a.threads;
  o.gps_altitude = a.gps_altitude == "ellipsoid" ? AltitudeReference::kEllipsoid : AltitudeReference::kEgm96;
  o.gps_sigma_h_m = a.gps_sigma_h_m;
  o.gps_sigma_v_m = a.gps_sigma_v_m;
  o.gps_csv = a.gps_csv;
  o.features.max_dimension = a.max_dimension;
  o.features.max_features = a.max_features;
  o.matching.gps_neighbours = a.gps_neighbours;
  o.mapper.local_adjust_images = a.local_ba_images;
  o.mapper.global_adjust_growth = a.global_ba_growth;
  o.mapper.global_adjust_screening = a.global_ba_loss == "screening";
  o.mapper.iterative_above_images = a.iterative_ba_above;
  o.mapper.gps_priors = a.mapper_gps == "priors";
  o.gcp = a.gcp;
  o.camera_file = a.policy.camera_file;
  o.checkpoints = a.checkpoints;
  o.gcp_pixel_origin = a.gcp_pixel_origin == "corner" ? PixelOrigin::kCorner : PixelOrigin::kCentre;
  o.georef.output_crs = a.crs;
  o.dense_resolution_m = a.dense_resolution_m;
  o.dense_min_views = a.dense_min_views;
  o.dsm_resolution_m = a.dsm_resolution_m;
  o.dsm_fill_m = a.dsm_fill_m;
  o.cog = a.cog;
  o.cloud_format = a.cloud_format;
  o.heights = a.heights;
  o.ground_cell_m = a.ground_cell_m;
  o.ground_window_m = a.ground_window_m;
  o.ground_slope = a.ground_slope;
  o.ground_threshold_m = a.ground_threshold_m;
  o.contour_interval_m = a.contour_interval_m;
  o.ortho = !a.no_ortho;
  o.ortho_resolution_m = a.ortho_resolution_m;
  o.ortho_surface = a.ortho_surface;
  o.ortho_compress = a.ortho_compress == "deflate" ? "DEFLATE" : "JPEG";
  o.ortho_cog = !a.ortho_no_cog;
  o.georef.gcp_sigma_h_m = a.gcp_sigma_h_m;
  o.georef.gcp_sigma_v_m = a.gcp_sigma_v_m;
  ApplyAdjustmentPolicy(a.policy, &o.georef);
  o.software_version = VersionString();
  o.command_line = ctx.command_line;
  o.progress = [&ctx](const std::string& stage) { return ctx.Progress(stage); };
  o.log = [&ctx](const std::string& message) {
    if (message.rfind("warning: ", 0) == 0) {
      ctx.Warn(message.substr(9));
    } else {
      ctx.Info(message);
    }
  };
  return o;
}

}  // namespace

int RunPipelineCommand(const RunArgs& a, ToolContext& ctx) {
  // One process per workspace: a second one exits 1 at once, naming the
  // holder. Holding the lock, anything a killed run left half-written is
  // stale. A workflow's dense shares share the workspace (each writes its
  // own files): they leave the others' files in progress alone.
  const bool share_job = !a.depth_share.empty() || !a.fuse_share.empty() || !a.band_share.empty();
  const DirectoryLock lock(a.output, share_job ? DirectoryLock::Mode::kShared : DirectoryLock::Mode::kExclusive);
  if (!share_job) {
    for (const std::filesystem::path& p : RemoveStaleTemporaryFiles(a.output)) {
      ctx.Info("removed " + p.string() + " (left by an interrupted run)");
    }
  }
  const std::string& s = a.stage;
  // The stages after marking read the marks in place of coordinates-only files.
  const bool after_marking = s == "georeference" || s == "dense" || s == "ortho" || s == "report" || s == "check";
  const PipelineOptions o = after_marking ? WithMarks(PipelineOptionsOf(a, ctx)) : PipelineOptionsOf(a, ctx);
  if (s == "mark") {
    if (!NeedsMarking(o)) {
      throw UsageError("mark: give --gcp and/or --checkpoints files of coordinates only ('name x y z'); a file "
                       "with pixel columns is marked already");
    }
    ValidateInputs(o);
    RunMarkStage(o);
    const nlohmann::json m = nlohmann::json::parse(ReadTextFile(std::filesystem::path(a.output) / "marks.json"));
    *ctx.out << "control_marked=" << m["control"]["marked"] << "/" << m["control"]["points"]
             << " checks_marked=" << m["checks"]["marked"] << "/" << m["checks"]["points"]
             << " marks=" << (std::filesystem::path(a.output) / "marks.json").string()
             << " review=" << (std::filesystem::path(a.output) / "marks.html").string() << "\n";
    return 0;
  }
  if (s == "run") {
    RunPipeline(o);  // its status is read back from report.json below
  } else if (s == "ingest") {
    RunIngestStage(o);
  } else if (s == "features") {
    RunFeatureStage(o);
  } else if (s == "match") {
    RunMatchStage(o);
  } else if (s == "reconstruct") {
    RunReconstructStage(o);
  } else if (s == "georeference") {
    RunGeoreferenceStage(o);
  } else if (s == "dense") {
    RunDenseStage(o);
  } else if (s == "ortho") {
    RunOrthoStage(o);
  } else if (s == "report") {
    RunReportStage(o);
  } else if (s == "dem") {
    const std::filesystem::path out = RebuildDsm(o, a.dem_output);
    *ctx.out << "dsm: " << out.string() << "\n";
    return 0;
  } else if (s == "check") {
    CheckSurvey(o);
  } else if (s == "split") {
    RunIngestStage(o);
    const std::vector<SurveyPart> parts = SplitSurvey(o, SplitOptions{a.parts, a.seam_margin_m});
    WriteSplitWorkflow(o, parts, AerotriExecutable(), a.georeference_args);
    for (const SurveyPart& p : parts) {
      *ctx.out << "part=" << p.name << " photos=" << p.images.size() << " own=" << p.core << "\n";
    }
    *ctx.out << "snakefile=" << (std::filesystem::path(a.output) / "Snakefile").string() << "\n";
    return 0;
  } else if (s == "merge") {
    const MergeSummary m = RunMergeStage(o);
    *ctx.out << "parts=" << m.parts << " photos=" << m.images << " shared_photos=" << m.shared_images
             << " tie_points=" << m.points << " joined_points=" << m.merged_points << "\n";
    return 0;
  }
  if (s == "run" || s == "georeference" || s == "report" || s == "check") {
    // An RMSE over no check points is not a figure: "nan", never a reassuring 0.0000.
    const auto CheckRmse = [](const nlohmann::json& checks, const char* key) {
      return checks.value("count", 0) > 0 ? checks.value(key, std::nan("")) : std::nan("");
    };
    // One data line on stdout, for scripts: the figures a surveyor looks at first.
    const auto path = std::filesystem::path(a.output) / "report.json";
    const nlohmann::json r = nlohmann::json::parse(ReadTextFile(path));
    const auto& images = r.value("images", nlohmann::json::object());
    const auto& checks = r.value("check_points", nlohmann::json::object());
    char line[512];
    std::snprintf(line, sizeof(line),
                  "report=%s status=%s registered=%d/%d rms_px=%.3f crs=%s check_count=%d check_rmse_h_m=%.4f "
                  "check_rmse_v_m=%.4f check_rmse_3d_m=%.4f\n",
                  path.string().c_str(), r.value("status", std::string("unknown")).c_str(),
                  images.value("registered", 0), images.value("total", 0),
                  r.value("adjustment", nlohmann::json::object()).value("final_rms_px", 0.0),
                  r.contains("crs") && r["crs"].is_string() ? r["crs"].get<std::string>().c_str() : "none",
                  checks.value("count", 0), CheckRmse(checks, "rmse_h_m"), CheckRmse(checks, "rmse_z_m"),
                  CheckRmse(checks, "rmse_3d_m"));
    *ctx.out << line << std::flush;
    // A failed survey exits non-zero, naming why.
    if (r.value("status", std::string()) == "failed") {
      for (const auto& e : r.value("errors", nlohmann::json::array())) {
        ctx.Error("survey failed: " + e.value("code", std::string()) + ": " + e.value("message", std::string()));
      }
      return 1;
    }
  }
  return 0;
}

}  // namespace aerotri
