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
  GpsGates(model, gates, report);
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

// The factor from a group's stated sigmas to what the adjustment estimated
// for it (1 where it was not estimated).
double EstimatedFactor(const GeoreferenceReport& report, ObservationGroup group) {
  for (const VarianceComponent& vc : report.bundle.variance_components) {
    if (vc.group == group && vc.estimated && std::isfinite(vc.sigma0) && vc.sigma0 > 0.0) {
      return vc.scale * vc.sigma0;
    }
  }
  return 1.0;
}

// The horizontal RMS of the GPS residuals over the RMS spread of the
// registered cameras with GPS about their mean (the model's layout, ENU);
// 0 where the layout is too small for its GPS to draw it (a spread under
// three times the stated horizontal sigma: photos from one spot).
double GpsResidualOverLayout(const SparseModel& model, const GeoreferenceReport& report) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int n = 0;
  double residual2 = 0.0, stated2 = 0.0;
  std::vector<Eigen::Vector2d> centres;
  for (const CameraResult& c : report.cameras) {
    if (!c.has_prior || c.prior_rejected) continue;
    for (const Image& image : model.images) {
      if (image.name != c.name) continue;
      centres.push_back(image.pose.centre_in_world.head<2>());
      mean += centres.back();
      residual2 += c.d_enu_m.head<2>().squaredNorm();
      stated2 += c.sigma_h_m * c.sigma_h_m;
      ++n;
    }
  }
  if (n < 4) return 0.0;
  mean /= n;
  double spread2 = 0.0;
  for (const Eigen::Vector2d& c : centres) spread2 += (c - mean).squaredNorm();
  if (!(spread2 > 9.0 * stated2)) return 0.0;
  return std::sqrt(residual2 / spread2);
}

void GpsGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  std::vector<std::string> gps_bad;
  int with_gps = 0;
  const double over_layout = GpsResidualOverLayout(model, *report);
  if (over_layout > gates.max_gps_residual_over_layout) {
    std::vector<std::string> names;
    for (const CameraResult& c : report->cameras) {
      if (c.has_prior && !c.prior_rejected) names.push_back(c.name);
    }
    report->findings.push_back(Finding::Error(
        "GPS_MOSTLY_INCONSISTENT",
        "the GPS does not follow the photos' layout: its horizontal residuals are " +
            Fixed(100.0 * over_layout, 0) + " % of the spread of the camera positions (a GPS that only scatters "
            "stays far below): positions matched to the wrong photos (a CSV in another order, another flight's "
            "log), or another survey's",
        names));
    return;
  }
  // Judged against the sigmas the adjustment estimated for the GPS, where
  // it did: a poor GPS is not an inconsistent one.
  const double fh = EstimatedFactor(*report, ObservationGroup::kGpsHorizontal);
  const double fv = EstimatedFactor(*report, ObservationGroup::kGpsVertical);
  for (const CameraResult& c : report->cameras) {
    if (!c.has_prior || c.prior_rejected) continue;
    ++with_gps;
    const double h = c.d_enu_m.head<2>().norm() / (fh * c.sigma_h_m);
    const double v = std::abs(c.d_enu_m.z()) / (fv * c.sigma_v_m);
    if (h > gates.gps_sigma_multiple || v > gates.gps_sigma_multiple) gps_bad.push_back(c.name);
  }
  if (gps_bad.empty()) return;
  const std::string text = std::to_string(gps_bad.size()) + " of " + std::to_string(with_gps) +
                           " cameras end farther from their GPS than " + Fixed(gates.gps_sigma_multiple, 0) +
                           (fh != 1.0 || fv != 1.0 ? " sigma as the adjustment estimated it (" + Fixed(fh, 1) +
                                                         " and " + Fixed(fv, 1) +
                                                         " times the stated, horizontally and vertically)"
                                                   : std::string(" sigma")) +
                           ": " + JoinNames(gps_bad);
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

namespace {

// A check point's predicted sigma per axis: its survey's own (its file's
// sigmas) and the posterior sigma of its adjusted or triangulated position;
// without a posterior, the sigma of what holds the datum and
// min_check_threshold_m / check_sigma_multiple (a triangulation adds a few
// GSD that no stated sigma holds).
Eigen::Vector3d PredictedSigma(const Point* point, const GroundPointResult& r, const QualityGates& gates,
                               std::pair<double, double> datum) {
  Eigen::Vector3d survey = Eigen::Vector3d::Zero();
  if (point && point->prior) {
    const PositionPrior& p = *point->prior;
    survey = p.covariance ? Eigen::Vector3d(p.covariance->diagonal().cwiseMax(0.0).cwiseSqrt())
                          : Eigen::Vector3d(p.sigma_h_m, p.sigma_h_m, p.sigma_v_m);
  }
  if (r.has_precision) return (survey.cwiseAbs2() + r.sigma_m.cwiseAbs2()).cwiseSqrt();
  const double floor = gates.min_check_threshold_m / gates.check_sigma_multiple;
  const Eigen::Vector3d d(datum.first, datum.first, datum.second);
  return (survey.cwiseAbs2() + d.cwiseAbs2()).cwiseSqrt().cwiseMax(floor);
}

std::string AxisName(int a) { return a == 0 ? "x" : a == 1 ? "y" : "z"; }

// "410 (w -7.3 in y)": a rejected point and its largest normalised residual.
std::string DescribeRejected(const GroundPointResult& r) {
  int a = 0;
  r.w.cwiseAbs().maxCoeff(&a);
  return r.name + " (w " + Fixed(r.w[a], 1) + " in " + AxisName(a) + ")";
}

// What can put a whole survey off its check points, for this block.
std::string MisplacedReasons(bool gps, bool control) {
  std::string reasons;
  if (control) reasons += "the control and the check points in different datums, CRSs or height references";
  if (gps) {
    if (!reasons.empty()) reasons += "; ";
    reasons += "GPS positions in another datum or height reference, or matched to the wrong photos";
  }
  if (reasons.empty()) reasons = "a wrong registration";
  return reasons + "; or the check file in another CRS";
}

}  // namespace

// Check points against their full predicted sigma. Each residual, per axis,
// over the root-sum-square of its posterior sigma and its survey's (Baarda's
// w); rejected beyond the family-wise critical value. The survey is failed
// only where the evidence is of a survey misplaced against its check points:
// most of them rejected, by a common offset far beyond their sigmas, or by
// residuals far beyond any sigma. GPS and model can agree on a wrong survey
// (a layout turned by 180 degrees fits a similarity exactly): only
// independent points can tell.
void CheckPointGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  const bool control_datum = report->datum_source.rfind("control", 0) == 0;
  const auto datum = DatumSigmas(model, *report, control_datum);
  std::vector<GroundPointResult*> solved;
  bool posterior = true;
  for (GroundPointResult& r : report->check) {
    if (r.solved && r.d_m.allFinite()) solved.push_back(&r);
  }
  if (solved.empty()) return;
  auto& test = report->check_test;
  test.tests = 3 * static_cast<int>(solved.size());
  test.family_alpha = gates.check_family_alpha;
  test.critical_value = FamilyWiseCriticalValue(test.tests, gates.check_family_alpha);
  std::vector<std::string> rejected, described;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), sigma2 = Eigen::Vector3d::Zero();
  std::vector<double> largest;
  for (GroundPointResult* r : solved) {
    r->predicted_sigma_m = PredictedSigma(FindPoint(model, PointRole::kCheck, r->name), *r, gates, datum);
    r->w = r->d_m.cwiseQuotient(r->predicted_sigma_m);
    r->tested = true;
    r->rejected = r->w.cwiseAbs().maxCoeff() > test.critical_value;
    posterior &= r->has_precision;
    mean += r->d_m;
    sigma2 += r->predicted_sigma_m.cwiseAbs2();
    largest.push_back(r->w.cwiseAbs().maxCoeff());
    if (r->rejected) rejected.push_back(r->name), described.push_back(DescribeRejected(*r));
  }
  test.posterior = posterior;
  if (rejected.empty()) return;
  const double n = static_cast<double>(solved.size());
  mean /= n;
  // The offset over the points' typical predicted sigma (not over sqrt(n):
  // the datum's error is common to them all).
  const Eigen::Vector3d offset_w = mean.cwiseQuotient((sigma2 / n).cwiseSqrt());
  double scatter2 = 0.0;
  for (const GroundPointResult* r : solved) scatter2 += (r->d_m - mean).squaredNorm();
  const double scatter = std::sqrt(scatter2 / n);
  std::nth_element(largest.begin(), largest.begin() + largest.size() / 2, largest.end());
  const double median_w = largest[largest.size() / 2];
  const bool most = solved.size() >= 2 && 2 * rejected.size() > solved.size();
  bool gps = false;
  for (const CameraResult& c : report->cameras) gps |= c.has_prior;
  const std::string test_text = " (|w| above " + Fixed(test.critical_value, 2) + ", family-wise " +
                                Fixed(100.0 * test.family_alpha, 0) + " % over " + std::to_string(test.tests) +
                                " axis tests)";
  if (most && offset_w.cwiseAbs().maxCoeff() > gates.check_offset_multiple && scatter < 0.5 * mean.norm()) {
    report->findings.push_back(Finding::Error(
        "CHECK_POINTS_OFFSET",
        "the check points sit a common (" + Fixed(mean.x(), 3) + ", " + Fixed(mean.y(), 3) + ", " +
            Fixed(mean.z(), 3) + ") m from their survey, " + Fixed(offset_w.cwiseAbs().maxCoeff(), 0) +
            " times their predicted sigma, and scatter " + Fixed(scatter, 3) +
            " m about it: the survey is misplaced against them (" + MisplacedReasons(gps, control_datum) + ")",
        rejected));
    return;
  }
  if (most && median_w > gates.check_gross_multiple) {
    report->findings.push_back(Finding::Error(
        "CHECK_POINTS_FAR",
        std::to_string(rejected.size()) + " of " + std::to_string(solved.size()) +
            " check points lie far beyond their predicted sigmas (median |w| " + Fixed(median_w, 0) +
            "): " + JoinNames(described) + "; the survey does not fit them (" +
            MisplacedReasons(gps, control_datum) + ")",
        rejected));
    return;
  }
  const bool one_of_many = rejected.size() == 1 && solved.size() >= 3;
  report->findings.push_back(Finding::Warning(
      "CHECK_POINTS_FAR",
      std::to_string(rejected.size()) + " of " + std::to_string(solved.size()) +
          " check points beyond their predicted sigmas" + test_text + ": " + JoinNames(described) +
          (one_of_many ? std::string("; the others agree: its survey or its marks are likely wrong")
                       : std::string(rejected.size() == 1 ? "; the model does not explain it"
                                                           : "; the model does not explain them") +
                             ": unmodelled systematic error (the block's deformation, a lens model that is too "
                             "simple), or a check point surveyed or marked wrong"),
      rejected));
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
