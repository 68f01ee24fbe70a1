// SPDX-License-Identifier: BSD-3-Clause
// aerotri simulate: render a synthetic drone survey with known truth.
#include <memory>
#include <sstream>

#include "libphoto/base/error.h"
#include "libphoto/simulate/survey_writer.h"
#include "tools/commands.h"

namespace aerotri {

void RegisterSimulateCommand(CLI::App& app, CommandAction* run) {
  auto a = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Render a synthetic drone survey with known truth: textured relief at a real location, "
      "lawn-mower flight, Brown camera, JPEGs with EXIF GPS, GCP targets with gcp_list.txt and "
      "checkpoints.txt, and the truth (cameras, terrain DEM)");
  cmd->add_option("--output,-o", a->output, "Output folder")->required();
  cmd->add_option("--seed", a->seed, "Random seed (every figure reproduces)")->capture_default_str();
  cmd->add_option("--width", a->width, "Image width (pixels)")->check(CLI::Range(64, 20000))->capture_default_str();
  cmd->add_option("--height", a->height, "Image height (pixels)")->check(CLI::Range(48, 20000))->capture_default_str();
  cmd->add_option("--focal-px", a->focal_px, "Focal length (pixels)")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--area-width", a->area_width_m, "East-west extent (metres)")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--area-height", a->area_height_m, "North-south extent (metres)")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--flight-height", a->flight_height_m, "Flight height above ground (metres)")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--forward-overlap", a->forward_overlap, "Forward overlap (fraction)")->check(CLI::Range(0.05, 0.95))->capture_default_str();
  cmd->add_option("--side-overlap", a->side_overlap, "Side overlap (fraction)")->check(CLI::Range(0.05, 0.95))->capture_default_str();
  cmd->add_option("--relief", a->relief_m, "Terrain relief amplitude (metres)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--buildings", a->buildings,
                  "Flat-roofed box buildings 6-14 m wide and 4-8 m high, clear of the targets (truth/dsm.tif has them)")
      ->check(CLI::Range(0, 200))->capture_default_str();
  cmd->add_option("--ground", a->ground,
                  "Ground cover: 'mixed' (grass, soil and stones: texture at every scale) or 'crop-rows' "
                  "(farmland of crop rows and tilled fields: texture that repeats, the hard case of matching)")
      ->check(CLI::IsMember({"mixed", "crop-rows"}))
      ->capture_default_str();
  cmd->add_option("--targets", a->targets,
                  "Pattern of the control and check targets: 'checker' (2x2 in a white frame), 'cross' (a white "
                  "cross on a black square) or 'circle' (a bull's-eye: a white ring on a black square)")
      ->check(CLI::IsMember({"checker", "cross", "circle"}))
      ->capture_default_str();
  cmd->add_option("--gps-sigma-h", a->gps_sigma_h_m, "GPS horizontal noise (metres)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--gps-sigma-v", a->gps_sigma_v_m, "GPS vertical noise (metres)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--gps-drift-v", a->gps_drift_v_m,
                  "GPS altitude drift over the flight (metres, linear in time from the first photo: a consumer "
                  "drone's barometric drift)")
      ->capture_default_str();
  cmd->add_option("--gimbal-pitch", a->gimbal_pitch_deg,
                  "Camera pitch (degrees; -90 looks straight down, -60 leans 30 degrees towards the image's top, "
                  "north and south strip by strip)")
      ->check(CLI::Range(-135.0, -45.0))
      ->capture_default_str();
  cmd->add_flag("--gimbal-xmp", a->gimbal_xmp,
                "Write DJI XMP gimbal angles (drone-dji:GimbalPitchDegree, ...) into each photo: the true attitude "
                "with 0.5 degrees of noise");
  cmd->add_option("--readout-ms", a->readout_ms,
                  "A rolling shutter: rows read top to bottom over this many milliseconds while the drone flies "
                  "(0: a global shutter). The photos carry it and the velocity in Pix4D's camera tags "
                  "(Camera:LineReadoutTime, Camera:IMULinearVelocity), as a Parrot Sequoia writes them")
      ->check(CLI::Range(0.0, 200.0))
      ->capture_default_str();
  cmd->add_option("--flight-speed", a->flight_speed_mps,
                  "Flight speed along the strips (m/s), for the rolling shutter")
      ->check(CLI::Range(0.5, 40.0))
      ->capture_default_str();
  cmd->add_option("--control", a->control, "Number of ground control points")->check(CLI::Range(0, 100))->capture_default_str();
  cmd->add_option("--checks", a->checks, "Number of check points")->check(CLI::Range(0, 100))->capture_default_str();
  cmd->add_option("--gcp-noise", a->gcp_noise_m, "Survey noise of control and check points (metres)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--click-noise", a->click_noise_px, "Noise of GCP image measurements (pixels)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--tie-points", a->tie_points, "Tie points in the exported model")->check(CLI::Range(10, 10000000))->capture_default_str();
  cmd->add_option("--tie-noise", a->tie_noise_px, "Noise of the model's tie observations (pixels)")->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--origin", a->origin, "Survey centre 'lat,lon,h' (degrees, ellipsoidal metres)")->capture_default_str();
  cmd->add_option("--crs", a->crs, "CRS of the control files")->capture_default_str();
  cmd->add_flag("--no-images", a->no_images, "Skip rendering (files and models only)");
  cmd->add_option("--jpeg-quality", a->jpeg_quality, "JPEG quality")->check(CLI::Range(10, 100))->capture_default_str();
  cmd->callback([a, run]() { *run = [a](ToolContext& ctx) { return RunSimulate(*a, ctx); }; });
}

int RunSimulate(const SimulateArgs& a, ToolContext& ctx) {
  SimulationOptions o;
  o.survey.seed = a.seed;
  o.survey.width = a.width;
  o.survey.height = a.height;
  // Principal point a little off centre, moderate barrel distortion.
  o.survey.brown_params = {a.focal_px, 0.5 * (a.width - 1) + 0.004 * a.width,
                           0.5 * (a.height - 1) - 0.003 * a.height, -0.08, 0.05, -0.01, 0.0005, -0.0003};
  o.survey.area_width_m = a.area_width_m;
  o.survey.area_height_m = a.area_height_m;
  o.survey.flight_height_m = a.flight_height_m;
  o.survey.forward_overlap = a.forward_overlap;
  o.survey.side_overlap = a.side_overlap;
  o.survey.relief_m = a.relief_m;
  o.survey.gimbal_pitch_deg = a.gimbal_pitch_deg;
  o.write_gimbal_xmp = a.gimbal_xmp;
  o.survey.readout_time_s = a.readout_ms * 1e-3;
  o.survey.flight_speed_mps = a.flight_speed_mps;
  if (a.gimbal_xmp && a.readout_ms > 0.0) {
    throw UsageError("--gimbal-xmp and --readout-ms cannot be combined: one XMP packet per photo");
  }
  o.num_buildings = a.buildings;
  o.ground_cover = a.ground == "crop-rows" ? GroundCover::kCropRows : GroundCover::kMixed;
  o.target_pattern = a.targets == "cross"    ? TargetPattern::kCross
                     : a.targets == "circle" ? TargetPattern::kBullseye
                                             : TargetPattern::kChecker;
  o.survey.num_control_points = a.control;
  o.survey.num_check_points = a.checks;
  o.survey.num_tie_points = a.tie_points;
  o.survey.pixel_noise_px = a.tie_noise_px;
  o.georef.gps_sigma_h_m = a.gps_sigma_h_m;
  o.georef.gps_sigma_v_m = a.gps_sigma_v_m;
  o.georef.gcp_noise_m = a.gcp_noise_m;
  o.georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, a.gps_drift_v_m);
  o.georef.crs = a.crs;
  o.georef.seed = a.seed;
  {
    std::string text = a.origin;
    for (char& c : text) {
      if (c == ',') c = ' ';
    }
    std::istringstream in(text);
    if (!(in >> o.georef.origin.lat_deg >> o.georef.origin.lon_deg >> o.georef.origin.h_m)) {
      throw InvalidArgument("--origin: expected 'lat,lon,h', got '" + a.origin + "'");
    }
  }
  o.click_noise_px = a.click_noise_px;
  o.render_images = !a.no_images;
  o.jpeg_quality = a.jpeg_quality;
  o.progress = ctx.Progress("simulate");
  WriteSyntheticSurvey(o, a.output);
  *ctx.out << "simulated survey written to " << a.output << "\n";
  return 0;
}

}  // namespace aerotri
