// SPDX-License-Identifier: BSD-3-Clause
#include "tools/tool_context.h"

#include <CLI/CLI.hpp>

#include <bzlib.h>
#include <gdal.h>
#include <proj.h>

#include <CLI/Version.hpp>
#include <Eigen/Core>
#include <GeographicLib/Config.h>
#include <ceres/version.h>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core/version.hpp>
#include <sstream>

#include "libphoto/base/error.h"
#include "tools/commands.h"
#include "tools/version.h"

namespace aerotri {

void ToolContext::Info(const std::string& line) const {
  if (!quiet) *err << line << "\n" << std::flush;
}

void ToolContext::Warn(const std::string& line) const {
  *err << "warning: " << line << "\n" << std::flush;
}

void ToolContext::Error(const std::string& line) const {
  *err << "error: " << line << "\n" << std::flush;
}

ProgressCallback ToolContext::Progress(const std::string& stage) const {
  if (quiet) return nullptr;
  std::ostream* stream = err;
  return [stream, stage](double fraction, const std::string& message) {
    if (fraction >= 0.0) {
      char pct[16];
      std::snprintf(pct, sizeof(pct), "%3.0f%%", 100.0 * fraction);
      *stream << stage << ": " << pct << " " << message << "\n" << std::flush;
    } else {
      *stream << stage << ": " << message << "\n" << std::flush;
    }
    return true;
  };
}

std::string VersionString() {
  // libbz2 reports "1.0.8, 13-Jul-2019": keep the version, drop the date.
  std::string bzip2 = BZ2_bzlibVersion();
  bzip2 = bzip2.substr(0, bzip2.find(','));
  std::ostringstream out;
  out << "aerotri " << kAerotriVersion << " (ceres " << CERES_VERSION_STRING << ", eigen "
      << EIGEN_WORLD_VERSION << "." << EIGEN_MAJOR_VERSION << "." << EIGEN_MINOR_VERSION
      << ", opencv " << CV_VERSION << ", proj " << proj_info().version << ", gdal "
      << GDALVersionInfo("RELEASE_NAME") << ", geographiclib "
      << GEOGRAPHICLIB_VERSION_STRING << ", cli11 " << CLI11_VERSION << ", nlohmann-json "
      << NLOHMANN_JSON_VERSION_MAJOR << "." << NLOHMANN_JSON_VERSION_MINOR << "."
      << NLOHMANN_JSON_VERSION_PATCH << ", bzip2 " << bzip2 << ")";
  return out.str();
}

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
                  "control points: auto (when the control shows a significant one), always or never")
      ->check(CLI::IsMember({"never", "auto", "always"}))
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
  cmd->add_option("--leave-one-out", a->leave_one_out,
                  "on: adjust once more per control point with it withheld, and report its residual as a "
                  "check point's (report.json leave_one_out; needs 4 or more control points); off")
      ->check(CLI::IsMember({"on", "off"}))
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
  if (!policy) throw InvalidArgument("--gps-offset: expected never, auto or always; got '" + a.gps_offset + "'");
  o->gps_offset = *policy;
  o->auto_refine = a.refine == "auto";
  ApplyRefineOption(o->auto_refine ? "all" : a.refine, &o->bundle);
  o->bundle.observation_sigma_px = a.tie_sigma_px;
  o->bundle.mark_sigma_px = a.mark_sigma_px;
  o->bundle.check_points_in_bundle = a.checkpoints_in_bundle;
  o->leave_one_out = a.leave_one_out == "on";
  if (!a.gnss_lever_arm.empty()) {
    const auto l = ParseVector3(a.gnss_lever_arm);
    if (!l) throw InvalidArgument("--gnss-lever-arm: expected 'x,y,z' in metres, got '" + a.gnss_lever_arm + "'");
    o->bundle.gnss_lever_arm_m = *l;
  }
  o->bundle.function_tolerance = a.function_tolerance;
  o->bundle.parameter_tolerance = a.parameter_tolerance;
  o->bundle.gradient_tolerance = a.gradient_tolerance;
}

void ApplyAdjustmentOptions(const std::string& loss, double loss_scale_px, const std::string& refine,
                            BundleOptions* options) {
  const auto parsed_loss = ParseLossType(loss);
  if (!parsed_loss) throw InvalidArgument("--loss: unknown loss '" + loss + "'");
  options->loss = *parsed_loss;
  options->loss_scale_px = loss_scale_px;
  ApplyRefineOption(refine, options);
}

void ApplyRefineOption(const std::string& refine, BundleOptions* options) {
  const auto parsed_refine = ParseIntrinsicsRefinement(refine, &options->refine_params);
  if (!parsed_refine) {
    throw InvalidArgument("--refine: expected none, focal, focal,pp, all or a list of f, cx, cy, k1, k2, k3, "
                          "p1, p2; got '" + refine + "'");
  }
  options->refine_intrinsics = *parsed_refine;
}

}  // namespace aerotri
