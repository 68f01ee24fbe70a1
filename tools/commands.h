// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The subcommands of the aerotri executable. Each has an argument struct, a
// Register function that declares its options on a CLI11 app (the --help text
// comes from these declarations), and a Run function callable in-process.
// Run functions return the exit code: 0 success, 1 runtime or data error
// (they throw aerotri::Error for bad data; main maps it to 1).

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

#include "georef/gps_fix.h"
#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/sfm/incremental_mapper.h"
#include "tools/tool_context.h"

namespace aerotri {

// Sets *run to the chosen command's action once parsing succeeds.
using CommandAction = std::function<int(ToolContext&)>;

// The georeferenced adjustment's stochastic model and solve, shared by run
// and adjust: --gps-offset and --refine (auto by default), --tie-sigma-px,
// --mark-sigma-px, --checkpoints-in-bundle and the solver's tolerances.
struct AdjustmentPolicyArgs {
  std::string gps_offset = "auto";  // never, auto, always
  std::string refine = "auto";
  double tie_sigma_px = 1.0;   // image sigma of tie points
  double mark_sigma_px = 0.0;  // of GCP / check marks; 0: the tie sigma
  bool checkpoints_in_bundle = false;
  bool keep_control_sigmas = false;
  bool zero_heights_are_heights = false;
  std::string variance_components = "auto";  // auto, estimate, stated
  std::string leave_one_out = "off";  // on, off
  std::string rolling_shutter = "auto";  // auto, estimate, off
  std::string camera_file;            // a calibration certificate (camera_file.h)
  std::string gnss_lever_arm;         // "x,y,z" metres in the camera frame; empty: none
  double function_tolerance = SurveyBundleOptions().function_tolerance;
  double parameter_tolerance = SurveyBundleOptions().parameter_tolerance;
  double gradient_tolerance = SurveyBundleOptions().gradient_tolerance;
};
// run's: a survey's report carries leave-one-out figures unless asked not to.
inline AdjustmentPolicyArgs SurveyRunPolicy() {
  AdjustmentPolicyArgs p;
  p.leave_one_out = "on";
  return p;
}
void AddAdjustmentPolicyOptions(CLI::App* cmd, AdjustmentPolicyArgs* args);
// Into the georeferencing options (the loss is left as it is).
void ApplyAdjustmentPolicy(const AdjustmentPolicyArgs& args, GeoreferenceOptions* options);

// --loss NAME --loss-scale PX --refine WHAT, shared by the commands that
// adjust; throws InvalidArgument naming the option and the allowed values.

void ApplyAdjustmentOptions(const std::string& loss, double loss_scale_px, const std::string& refine,
                            BundleOptions* options);
// --refine alone (run: the loss is the survey default, SurveyBundleOptions()).
void ApplyRefineOption(const std::string& refine, BundleOptions* options);

struct BalArgs {
  std::string problem;
  std::string output;
  std::string loss = "none";
  double loss_scale_px = 1.0;
  std::string solver = "auto";
  int threads = 0;
  int max_iterations = 50;
  std::string refine = "all";
  double outlier_threshold_px = 0.0;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  double optimality_gap = 5e-4;
  std::string engine = "auto";
  bool diagnostics = false;
  bool solver_report = false;
};
void RegisterBalCommand(CLI::App& app, CommandAction* run);
int RunBal(const BalArgs& args, ToolContext& ctx);

struct AdjustArgs {
  std::string model_dir;
  std::string measurements;  // tie-point file: AT from measurements, no model
  std::string images_dir;
  std::string gcp;
  std::string checkpoints;
  std::string gps_csv;
  std::string crs;
  std::string output;
  double gps_sigma_h_m = kDefaultGpsSigmaH;
  double gps_sigma_v_m = kDefaultGpsSigmaV;
  std::string gps_altitude = "egm96";
  double gcp_sigma_h_m = 0.02;
  double gcp_sigma_v_m = 0.03;
  AdjustmentPolicyArgs policy;
  std::string gcp_pixel_origin = "centre";
  // The survey defaults of the library (SurveyBundleOptions), not the CLI's own.
  std::string loss = ToString(SurveyBundleOptions().loss);
  double loss_scale_px = SurveyBundleOptions().loss_scale_px;
  double outlier_threshold_px = SurveyBundleOptions().outlier_threshold_px;
  int threads = 0;
  int max_iterations = 100;
  std::string solver = "auto";  // auto, dense, sparse, ceres
};
void RegisterAdjustCommand(CLI::App& app, CommandAction* run);
int RunAdjust(const AdjustArgs& args, ToolContext& ctx);

struct SimulateArgs {
  std::string output;
  unsigned seed = 1;
  int width = 1000;
  int height = 750;
  double focal_px = 800.0;
  double area_width_m = 120.0;
  double area_height_m = 90.0;
  double flight_height_m = 60.0;
  double forward_overlap = 0.75;
  double side_overlap = 0.65;
  double relief_m = 12.0;
  int buildings = 0;
  std::string ground = "mixed";
  std::string targets = "checker";
  double gps_sigma_h_m = 2.0;
  double gps_sigma_v_m = 4.0;
  double gps_drift_v_m = 0.0;
  double gimbal_pitch_deg = -90.0;
  bool gimbal_xmp = false;
  double readout_ms = 0.0;
  double flight_speed_mps = 12.0;
  int control = 8;
  int checks = 6;
  double gcp_noise_m = 0.01;
  double click_noise_px = 0.3;
  int tie_points = 3000;
  double tie_noise_px = 0.3;
  std::string origin = "46.5,7.5,500";
  std::string crs = "EPSG:32632";
  bool no_images = false;
  int jpeg_quality = 88;
};
void RegisterSimulateCommand(CLI::App& app, CommandAction* run);
int RunSimulate(const SimulateArgs& args, ToolContext& ctx);

// aerotri run and its stages (ingest, features, match, reconstruct,
// georeference): one argument set, each stage reading and writing the
// workspace (see libphoto/pipeline/pipeline.h).
struct RunArgs {
  std::string images_dir;
  std::string output;
  AdjustmentPolicyArgs policy = SurveyRunPolicy();  // of the georeferenced adjustment
  bool keep_going = false;
  bool keep_depth_maps = false;
  bool force = false;
  // dense as a workflow's jobs: "K/N" (a share of the depth maps, of the
  // fusion), or N (the deliverables from N fused shares); one at most.
  std::string depth_share, fuse_share;
  int from_shares = 0;
  // ortho as a workflow's jobs: "K/N" (a band of tile rows); from_shares: N.
  std::string band_share;
  int parts = 4;               // split
  double seam_margin_m = 0.0;  // split; 0: automatic
  std::vector<std::string> georeference_args;  // split: the global adjustment's options as given
  int threads = 0;
  std::string gps_altitude = "egm96";
  double gps_sigma_h_m = kDefaultGpsSigmaH;
  double gps_sigma_v_m = kDefaultGpsSigmaV;
  std::string gps_csv;
  int max_dimension = 1600;
  int max_features = 12000;
  int gps_neighbours = 12;
  int local_ba_images = MapperOptions().local_adjust_images;
  double global_ba_growth = MapperOptions().global_adjust_growth;
  std::string global_ba_loss = MapperOptions().global_adjust_screening ? "screening" : "huber";
  int iterative_ba_above = MapperOptions().iterative_above_images;
  std::string mapper_gps = MapperOptions().gps_priors ? "priors" : "check";
  std::string gcp;
  std::string checkpoints;
  std::string gcp_pixel_origin = "centre";
  double gcp_sigma_h_m = 0.02;
  double gcp_sigma_v_m = 0.03;
  std::string crs;
  double dense_resolution_m = 0.0;
  int dense_min_views = 2;
  double dsm_resolution_m = 0.0;
  double dsm_fill_m = 2.0;
  bool cog = false;
  std::string cloud_format = "laz";
  std::string heights = "egm96";
  double ground_cell_m = 0.5;
  double ground_window_m = 18.0;
  double ground_slope = 0.15;
  double ground_threshold_m = 0.3;
  double contour_interval_m = 0.0;
  bool no_ortho = false;
  double ortho_resolution_m = 0.0;
  std::string ortho_surface = "dsm";
  std::string ortho_compress = "jpeg";
  bool ortho_no_cog = false;
  std::string dem_output;     // aerotri dem
  std::string stage = "all";  // which stage a stage subcommand runs
};
// GDAL's warnings and errors become the tool's "warning: GDAL: ..." lines
// (thread-safe); null restores GDAL's default handler.
void RouteGdalMessages(const ToolContext* ctx);

void RegisterRunCommands(CLI::App& app, CommandAction* run);
int RunPipelineCommand(const RunArgs& args, ToolContext& ctx);

}  // namespace aerotri
