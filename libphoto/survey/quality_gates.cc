// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/quality_gates.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace aerotri {
namespace {

std::string Fixed(double v, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return std::string(text);
}

// Images whose own RMS is above the limit, worst first.
std::vector<std::string> ImagesAboveRms(const SparseModel& model, double max_rms_px) {
  const std::vector<double> errors = ReprojectionErrors(model);
  std::vector<double> sum(model.images.size(), 0.0);
  std::vector<int> count(model.images.size(), 0);
  for (size_t k = 0; k < errors.size(); ++k) {
    const Observation& obs = model.observations[k];
    if (model.points[obs.point].role == PointRole::kCheck || !model.images[obs.image].registered) continue;
    const double e = std::isfinite(errors[k]) ? errors[k] : 1e6;
    sum[obs.image] += e * e;
    ++count[obs.image];
  }
  std::vector<std::pair<double, std::string>> rms;
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (count[i] == 0) continue;
    const double r = std::sqrt(sum[i] / count[i]);
    if (r > max_rms_px) rms.push_back({r, model.images[i].name});
  }
  std::sort(rms.rbegin(), rms.rend());
  std::vector<std::string> names;
  for (const auto& [r, name] : rms) names.push_back(name);
  return names;
}

const Point* FindPoint(const SparseModel& model, PointRole role, const std::string& name) {
  const Point* point = nullptr;
  for (const Point& p : model.points) {
    if (p.role == role && p.name == name) point = &p;
  }
  return point;
}

// The sigmas of what holds the datum: the largest control sigmas, else the
// cameras' median GPS sigmas.
std::pair<double, double> DatumSigmas(const SparseModel& model, const GeoreferenceReport& report,
                                      bool control_datum) {
  double datum_h = 0.0, datum_v = 0.0;
  if (control_datum) {
    for (const Point& p : model.points) {
      if (p.role == PointRole::kControl && p.prior) {
        datum_h = std::max(datum_h, p.prior->sigma_h_m);
        datum_v = std::max(datum_v, p.prior->sigma_v_m);
      }
    }
    return {datum_h, datum_v};
  }
  std::vector<double> gps_h, gps_v;
  for (const CameraResult& c : report.cameras) {
    if (!c.has_prior) continue;
    gps_h.push_back(c.sigma_h_m);
    gps_v.push_back(c.sigma_v_m);
  }
  if (!gps_h.empty()) {
    std::nth_element(gps_h.begin(), gps_h.begin() + gps_h.size() / 2, gps_h.end());
    std::nth_element(gps_v.begin(), gps_v.begin() + gps_v.size() / 2, gps_v.end());
    datum_h = gps_h[gps_h.size() / 2];
    datum_v = gps_v[gps_v.size() / 2];
  }
  return {datum_h, datum_v};
}

}  // namespace

void ApplyQualityGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  ReprojectionGates(model, gates, report);
  GpsGates(gates, report);
  const std::vector<std::string> control_bad = ControlPointsBeyondSigmas(model, gates, *report);
  CheckPointGates(model, gates, report);
  DomeGate(gates, report);
  if (!control_bad.empty()) {
    report->findings.push_back(Finding::Warning(
        "CONTROL_RESIDUAL_HIGH",
        std::to_string(control_bad.size()) + " control points end farther from their survey than " +
            Fixed(gates.control_sigma_multiple, 0) + " sigma (a blunder, a wrong mark, or sigmas "
            "too small): " + JoinNames(control_bad),
        control_bad));
  }
}

void ReprojectionGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  const BundleSummary& b = report->bundle;
  const std::vector<std::string> bad_images = ImagesAboveRms(model, gates.max_rms_px);
  if (!b.converged) {
    report->findings.push_back(Finding::Warning(
        "ADJUSTMENT_NOT_CONVERGED", "the adjustment stopped before converging (" + b.termination + ")"));
  }
  if (b.final_rms_px > gates.max_rms_px) {
    report->findings.push_back(Finding::Error(
        "REPROJECTION_RMS_HIGH",
        "final reprojection RMS " + Fixed(b.final_rms_px, 2) + " px is above " + Fixed(gates.max_rms_px, 1) +
            " px: the model and its priors do not agree" +
            (bad_images.empty() ? std::string() : "; worst images: " + JoinNames(bad_images)),
        bad_images));
  } else if (b.final_rms_px > 1.0 && b.final_rms_px > gates.max_rms_growth * b.initial_rms_px) {
    report->findings.push_back(Finding::Error(
        "REPROJECTION_RMS_GREW",
        "the adjustment raised the reprojection RMS from " + Fixed(b.initial_rms_px, 2) + " to " +
            Fixed(b.final_rms_px, 2) + " px: the priors pull the model apart",
        bad_images));
  }
}

void GpsGates(const QualityGates& gates, GeoreferenceReport* report) {
  std::vector<std::string> gps_bad;
  int with_gps = 0;
  for (const CameraResult& c : report->cameras) {
    if (!c.has_prior || c.prior_rejected) continue;
    ++with_gps;
    const double h = c.d_enu_m.head<2>().norm() / c.sigma_h_m;
    const double v = std::abs(c.d_enu_m.z()) / c.sigma_v_m;
    if (h > gates.gps_sigma_multiple || v > gates.gps_sigma_multiple) gps_bad.push_back(c.name);
  }
  if (gps_bad.empty()) return;
  const std::string text = std::to_string(gps_bad.size()) + " of " + std::to_string(with_gps) +
                           " cameras end farther from their GPS than " + Fixed(gates.gps_sigma_multiple, 0) +
                           " sigma: " + JoinNames(gps_bad);
  if (gps_bad.size() > gates.max_gps_inconsistent_fraction * with_gps) {
    report->findings.push_back(Finding::Error(
        "GPS_MOSTLY_INCONSISTENT",
        text + "; the GPS and the model disagree (wrong registration, GPS in another datum or "
               "height reference, or wrong sigmas)",
        gps_bad));
  } else {
    report->findings.push_back(Finding::Warning("GPS_INCONSISTENT", text, gps_bad));
  }
}

std::vector<std::string> ControlPointsBeyondSigmas(const SparseModel& model, const QualityGates& gates,
                                                   const GeoreferenceReport& report) {
  std::vector<std::string> control_bad;
  for (const GroundPointResult& r : report.control) {
    if (!r.solved) continue;
    const Point* point = FindPoint(model, PointRole::kControl, r.name);
    if (!point || !point->prior) continue;
    const double h = r.d_m.head<2>().norm() / point->prior->sigma_h_m;
    const double v = std::abs(r.d_m.z()) / point->prior->sigma_v_m;
    if (h > gates.control_sigma_multiple || v > gates.control_sigma_multiple) control_bad.push_back(r.name);
  }
  return control_bad;
}

// Check points against what the datum allows: their own survey sigma and
// the sigma of what holds the datum (control, else GPS), five times, at
// least QualityGates::min_check_threshold_m. GPS and model can agree on a
// wrong survey (a layout turned by 180 degrees fits a similarity exactly):
// only independent points can tell.
void CheckPointGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  const bool control_datum = report->datum_source.rfind("control", 0) == 0;
  const auto [datum_h, datum_v] = DatumSigmas(model, *report, control_datum);
  std::vector<std::string> far;
  int solved = 0;
  for (const GroundPointResult& r : report->check) {
    if (!r.solved) continue;
    ++solved;
    const Point* point = FindPoint(model, PointRole::kCheck, r.name);
    const double sh = point && point->prior ? point->prior->sigma_h_m : 0.0;
    const double sv = point && point->prior ? point->prior->sigma_v_m : 0.0;
    const double limit_h = std::max(gates.min_check_threshold_m, gates.check_sigma_multiple * std::hypot(sh, datum_h));
    const double limit_v = std::max(gates.min_check_threshold_m, gates.check_sigma_multiple * std::hypot(sv, datum_v));
    if (r.d_m.head<2>().norm() > limit_h || std::abs(r.d_m.z()) > limit_v) far.push_back(r.name);
  }
  if (far.empty()) return;
  const std::string text =
      std::to_string(far.size()) + " of " + std::to_string(solved) +
      " check points are farther from their survey than the datum allows (" +
      Fixed(gates.check_sigma_multiple, 0) + " sigma of the check point and of the " +
      (control_datum ? "control" : "GPS") + "): " + JoinNames(far);
  if (2 * far.size() > static_cast<size_t>(solved)) {
    report->findings.push_back(Finding::Error(
        "CHECK_POINTS_FAR", text + "; the survey is misplaced (GPS in the wrong order or datum, "
                                   "wrong registration) or the check file is wrong",
        far));
  } else {
    report->findings.push_back(Finding::Warning("CHECK_POINTS_FAR", text + " (blunders?)", far));
  }
}

void DomeGate(const QualityGates& gates, GeoreferenceReport* report) {
  const DomeTest& dome = report->dome;
  if (!(dome.significant && report->geometry.gsd_m > 0.0 &&
        std::abs(dome.amplitude_m) > gates.max_dome_gsd * report->geometry.gsd_m)) {
    return;
  }
  report->findings.push_back(Finding::Warning(
      "DOME", "the vertical residuals of the " + dome.source + " form a " +
                  (dome.amplitude_m > 0 ? "bowl" : "dome") + " across the block: edge minus centre " +
                  Fixed(dome.amplitude_m, 3) + " ± " + Fixed(dome.amplitude_sigma_m, 3) + " m (" +
                  Fixed(std::abs(dome.amplitude_m) / report->geometry.gsd_m, 1) +
                  " GSD); radial distortion is likely mis-estimated (a nadir block at one altitude: add "
                  "oblique photos or control across the block)" +
                  (dome.source == "GPS" ? std::string("; measured on GPS altitudes, which a drift over the flight "
                                                      "can shape too: check points would tell")
                                        : std::string())));
}

}  // namespace aerotri
