// SPDX-License-Identifier: BSD-3-Clause
// The adjustment-policy options shared by run, georeference and adjust.
#include <CLI/CLI.hpp>

#include <Eigen/Core>
#include <optional>
#include <sstream>

#include "libphoto/base/error.h"
#include "tools/commands.h"

namespace aerotri {

namespace {
// "x,y,z": three finite numbers.
std::optional<Eigen::Vector3d> ParseVector3(const std::string& text) {
  std::istringstream in(text);
  Eigen::Vector3d v;
  char c1 = 0, c2 = 0;
  if (!(in >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !(in >> std::ws).eof() ||
      !v.allFinite()) {
    return std::nullopt;
  }
  return v;
}
}  // namespace

void AddAdjustmentPolicyOptions(CLI::App* cmd, AdjustmentPolicyArgs* a) {
  cmd->add_option("--tie-sigma-px", a->tie_sigma_px, "Image sigma of tie-point measurements (pixels)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--mark-sigma-px", a->mark_sigma_px,
                  "Image sigma of GCP / check-point marks (pixels); 0 = the tie sigma")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--gps-offset", a->gps_offset,
                  "Constant GPS offset from the camera (antenna, height reference), estimated with 3+ "
                  "control points: auto (when the control shows a significant one), always, per-flight (one "
                  "per flight, flights told apart by capture-time gaps) or never")
      ->check(CLI::IsMember({"never", "auto", "always", "per-flight"}))
      ->capture_default_str();
  cmd->add_option("--refine", a->refine,
                  "Intrinsics refined: auto (all that the block determines; a focal length known to worse "
                  "than 1 % is held at its EXIF value), none, focal, focal,pp, all, or a list "
                  "(f,cx,cy,k1,k2,k3,p1,p2)")
      ->capture_default_str();
  cmd->add_option("--camera-file", a->camera_file,
                  "Interior orientation from a calibration certificate: f, principal point (px, or mm with "
                  "the pixel size), k1-k3, p1, p2, each a start value, a prior (sigma S) or fixed")
      ->check(CLI::ExistingFile);
  cmd->add_option("--gnss-lever-arm", a->gnss_lever_arm,
                  "GNSS antenna position in the camera frame, metres 'x,y,z' (x right, y down the image, z "
                  "along the optical axis): the receiver reads the centre plus the rotated arm")
      ->check(CLI::Validator(
          [](std::string& text) {
            return ParseVector3(text) ? std::string() : "expected 'x,y,z' in metres, got '" + text + "'";
          },
          "X,Y,Z"));
  cmd->add_flag("--checkpoints-in-bundle", a->checkpoints_in_bundle,
                "Carry check points as free points inside the bundle (no prior), as classic aerial "
                "triangulation does; default: independent, triangulated afterwards with the cameras held");
  cmd->add_flag("--keep-control-sigmas", a->keep_control_sigmas,
                "Weigh control by the file's sigmas even when it scatters 3 or more times more about the model "
                "(by default the estimate is used where the sigmas are defaults, and said: CONTROL_WEAKER_THAN_STATED)");
  cmd->add_flag("--zero-heights-are-heights", a->zero_heights_are_heights,
                "Control heights that are all exactly 0 are surveyed heights (by default they are taken as "
                "unknown, the points used in plan only: CONTROL_HEIGHTS_ZERO)");
  cmd->add_option("--variance-components", a->variance_components,
                  "auto: each observation group (tie points, target marks, GPS horizontal / vertical, control) "
                  "weighed by the scatter it shows, re-solved until its sigma0 is 1 (Foerstner), except groups "
                  "whose every sigma the input files state (sigma_px= on every mark, sigmas on every control "
                  "point), held as stated; estimate: every group estimated; stated: the stated sigmas kept "
                  "(the groups' sigma0 still reported)")
      ->check(CLI::IsMember({"auto", "estimate", "stated"}))
      ->capture_default_str();
  cmd->add_option("--leave-one-out", a->leave_one_out,
                  "on: each control point withheld from the adjustment (the block-deletion update of its normal "
                  "equations at the optimum), its residual reported as a check point's (report.json "
                  "leave_one_out; needs 4 or more control points); off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--rolling-shutter", a->rolling_shutter,
                  "auto: photos that state their velocity (Parrot's Camera:IMULinearVelocity, DJI's "
                  "FlightXSpeed / FlightYSpeed) and whose readout time is stated (Camera:LineReadoutTime) or in "
                  "the known-camera table (DJI Phantom 3 / 4, Mavic, Air, Mini, Inspire 1, GoPro: "
                  "OpenDroneMap's measured figures) are adjusted with each row exposed where the camera was; "
                  "estimate: the same, and each camera group's readout time estimated in the "
                  "adjustment with its sigma (photos that state a velocity but no readout included); off: every "
                  "photo taken as a global shutter's (report.json adjustment.shutter)")
      ->check(CLI::IsMember({"auto", "estimate", "off"}))
      ->capture_default_str();
  cmd->add_option("--function-tolerance", a->function_tolerance,
                  "Solver stops when the cost changes by less than this fraction")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--parameter-tolerance", a->parameter_tolerance,
                  "Solver stops when a step changes the parameters by less than this fraction")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--gradient-tolerance", a->gradient_tolerance,
                  "Solver stops when the gradient's max norm falls below this")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

void ApplyAdjustmentPolicy(const AdjustmentPolicyArgs& a, GeoreferenceOptions* o) {
  const auto policy = ParseGpsOffsetPolicy(a.gps_offset);
  if (!policy) throw InvalidArgument("--gps-offset: expected never, auto, always or per-flight; got '" + a.gps_offset + "'");
  o->gps_offset = *policy;
  o->auto_refine = a.refine == "auto";
  ApplyRefineOption(o->auto_refine ? "all" : a.refine, &o->bundle);
  o->bundle.observation_sigma_px = a.tie_sigma_px;
  o->bundle.mark_sigma_px = a.mark_sigma_px;
  o->bundle.check_points_in_bundle = a.checkpoints_in_bundle;
  o->keep_stated_control_sigmas = a.keep_control_sigmas;
  o->zero_heights_are_heights = a.zero_heights_are_heights;
  o->bundle.estimate_variance_components = a.variance_components != "stated";
  o->hold_stated_sigmas = a.variance_components == "auto";
  o->leave_one_out = a.leave_one_out == "on";
  o->model_rolling_shutter = a.rolling_shutter != "off";
  o->estimate_readout = a.rolling_shutter == "estimate";
  if (!a.gnss_lever_arm.empty()) {
    const auto l = ParseVector3(a.gnss_lever_arm);
    if (!l) throw InvalidArgument("--gnss-lever-arm: expected 'x,y,z' in metres, got '" + a.gnss_lever_arm + "'");
    o->bundle.gnss_lever_arm_m = *l;
  }
  o->bundle.function_tolerance = a.function_tolerance;
  o->bundle.parameter_tolerance = a.parameter_tolerance;
  o->bundle.gradient_tolerance = a.gradient_tolerance;
}

}  // namespace aerotri
