// SPDX-License-Identifier: BSD-3-Clause
// What the adjustment shows: the GNSS model and the attitude as adjusted,
// control and check points, the dome test, the cameras, the variance
// components and the marks' data snooping (survey_phases.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/SVD>

#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

constexpr double kGpsOnlyGroundSlopeDeg = 20.0;  // GROUND_TILTED_BY_GPS

bool GpsRejected(const SurveyState& s, const Image& image) {
  return s.rejected_gps.count(static_cast<int>(&image - s.model->images.data())) > 0;
}

// The rates rest on the GPS alone: their sigma is scaled by the GPS priors'
// own variance factor (their standardised residuals after the drift), not
// by the adjustment's, which the tie points dominate.
double GpsVarianceFactor(const SurveyState& s) {
  const GpsDriftReport& drift = s.report.gps_drift;
  double gps_sum2 = 0.0;
  int gps_rows = 0;
  for (const Image& image : s.model->images) {
    if (!image.registered || !image.gps_prior || GpsRejected(s, image)) continue;
    const Eigen::Vector3d r = GpsAsAdjusted(s, image) - image.gps_prior->position;
    const Eigen::Vector3d sigma(image.gps_prior->sigma_h_m, image.gps_prior->sigma_h_m, image.gps_prior->sigma_v_m);
    gps_sum2 += r.cwiseQuotient(sigma).squaredNorm();
    gps_rows += 3;
  }
  int drift_params = 0;
  for (int a = 0; a < 3; ++a) drift_params += drift.axes[a] ? static_cast<int>(drift.flights.size()) : 0;
  return gps_rows > drift_params + 3 ? gps_sum2 / (gps_rows - drift_params - 3) : 1.0;
}

// The drift as estimated, per flight with its sigma (GPS_DRIFT).
void ReportDrift(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  GpsDriftReport& drift = report.gps_drift;
  const BundlePrecision& precision = report.bundle.precision;
  const double gps_variance_factor = GpsVarianceFactor(*s);
  std::string text;
  for (size_t f = 0; f < drift.flights.size() && f < report.bundle.gps_drift_m_per_s.size(); ++f) {
    GpsDriftReport::Flight& flight = drift.flights[f];
    flight.rate_m_per_s = report.bundle.gps_drift_m_per_s[f];
    if (precision.computed && f < precision.gps_drift_cov.size() && precision.variance_factor > 0.0) {
      flight.rate_sigma = (precision.gps_drift_cov[f].diagonal() / precision.variance_factor * gps_variance_factor)
                              .cwiseMax(0.0)
                              .cwiseSqrt();
    }
    const char* axis_names[3] = {"E", "N", "U"};
    for (int a = 0; a < 3; ++a) {
      if (!drift.axes[a]) continue;
      char part[200];
      std::snprintf(part, sizeof part, "%sflight %zu %s %+.3f m/s ± %.3f (%+.1f m over %.0f s)",
                    text.empty() ? "" : "; ", f + 1, axis_names[a], flight.rate_m_per_s[a], flight.rate_sigma[a],
                    flight.rate_m_per_s[a] * flight.duration_s, flight.duration_s);
      text += part;
    }
  }
  report.findings.push_back(Finding::Warning(
      "GPS_DRIFT",
      "the GPS positions drift in time (" + text + "): estimated in the adjustment as a GNSS drift per flight" +
          (drift.attitude_prior ? std::string("; the block's tilt held by the photos' ") +
                                      (drift.vertical_source == "gimbal" ? "gimbal pitches" : "nadir attitude") +
                                      " (the GPS alone would tilt it " + FormatDegrees(drift.gps_fit_tilt_deg) +
                                      "); without control the heights carry the GPS's mean error"
                                : std::string("; the control holds the datum"))));
}

// The cameras' adjusted attitude against the flight type.
void ReportAttitude(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  report.tilt = MeasureTilt(*s->model);
  if (report.viewing.nadir && report.tilt.mean_axis_tilt_deg > 10.0) {
    report.findings.push_back(Finding::Error(
        "CAMERA_ATTITUDE_IMPLAUSIBLE",
        "the adjusted block of nadir photos looks " + FormatDegrees(report.tilt.mean_axis_tilt_deg) +
            " off vertical (mean optical axis; median photo " + FormatDegrees(report.tilt.median_deg) +
            "): the datum is tilted. GPS heights drifting or wrong, or control in a wrong CRS?"));
  }
  // Nothing but the GPS heights set the block's tilt (no nadir axis, no
  // gimbal, no control): a ground that slopes more than 20° over the whole
  // block is what a drifting GPS altitude makes of a level one.
  if (!s->control_datum && report.gps_drift.vertical_source.empty() && !s->local &&
      report.tilt.ground_slope_deg > kGpsOnlyGroundSlopeDeg) {
    report.findings.push_back(Finding::Error(
        "GROUND_TILTED_BY_GPS",
        "the adjusted ground slopes " + FormatDegrees(report.tilt.ground_slope_deg) + " across the whole block (plane "
            "through " + std::to_string(report.tilt.ground_points) + " tie points) and only the GPS heights set the "
            "block's tilt (" + report.viewing.reason + ", no gimbal angles, no control): a drifting or wrong GPS "
            "altitude tilts a survey this way. Add control points or photos with gimbal angles, or run with "
            "--keep-going if the ground truly slopes so"));
  }
}

// The rotation part of a conformal Jacobian (polar decomposition).
Eigen::Matrix3d RotationOf(const Eigen::Matrix3d& j) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(j, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) r = -r;
  return r;
}

// ω, φ, κ (radians) of R = Rx(ω) Ry(φ) Rz(κ).
Eigen::Vector3d OmegaPhiKappa(const Eigen::Matrix3d& r) {
  return {std::atan2(-r(1, 2), r(2, 2)), std::asin(std::clamp(r(0, 2), -1.0, 1.0)), std::atan2(-r(0, 1), r(0, 0))};
}

// Grid-from-photo rotation of a pose: photo axes are OpenCV's camera axes
// with y and z turned (x right, y up, z out of the lens).
Eigen::Matrix3d GridFromPhoto(const Eigen::Matrix3d& grid_from_enu, const Eigen::Quaterniond& cam_from_world) {
  return grid_from_enu * cam_from_world.conjugate().toRotationMatrix() * Eigen::Vector3d(1, -1, -1).asDiagonal();
}

// Angles wrapped into (-pi, pi] around a reference (for differences).
double WrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

// d(ω, φ, κ)/dθ of Exp(θ) R_cw, by central differences.
Eigen::Matrix3d OpkJacobian(const Eigen::Matrix3d& grid, const Eigen::Quaterniond& cam_from_world) {
  Eigen::Matrix3d d;
  const double eps = 1e-6;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(eps, Eigen::Vector3d::Unit(k)));
    const Eigen::Vector3d plus = OmegaPhiKappa(GridFromPhoto(grid, turn * cam_from_world));
    const Eigen::Vector3d minus = OmegaPhiKappa(GridFromPhoto(grid, turn.conjugate() * cam_from_world));
    for (int a = 0; a < 3; ++a) d(a, k) = WrapAngle(plus[a] - minus[a]) / (2.0 * eps);
  }
  return d;
}

// One registered camera in the output CRS, with its sigmas and GPS residual.
CameraResult CameraInCrs(const SurveyState& s, size_t index) {
  const Image& image = s.model->images[index];
  const Crs& out_crs = *s.out_crs;
  CameraResult c;
  c.name = image.name;
  const Eigen::Vector3d& centre = image.pose.centre_in_world;
  c.position_crs = out_crs.FromGeodetic(s.Frame().GeodeticFromEnu(centre));
  const Eigen::Matrix3d j = CrsFromEnuJacobian(s.Frame(), out_crs, centre);
  const Eigen::Matrix3d grid = RotationOf(j);
  c.opk_deg = OmegaPhiKappa(GridFromPhoto(grid, image.pose.cam_from_world)) * 180.0 / M_PI;
  if (const ImagePrecision* ip = s.report.bundle.precision.ForImage(static_cast<int>(index))) {
    c.has_precision = true;
    c.sigma_position_m = (j * ip->centre_cov * j.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
    const Eigen::Matrix3d d = OpkJacobian(grid, image.pose.cam_from_world);
    c.sigma_opk_deg = (d * ip->rotation_cov * d.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt() * 180.0 / M_PI;
  }
  if (image.gps_prior) {
    c.has_prior = true;
    c.prior_rejected = GpsRejected(s, image);
    c.d_enu_m = GpsAsAdjusted(s, image) - image.gps_prior->position;
    c.sigma_h_m = image.gps_prior->sigma_h_m;
    c.sigma_v_m = image.gps_prior->sigma_v_m;
    c.flight = image.gps_prior->flight;
  }
  return c;
}

// Control that scattered about the free network beyond 3 times its stated
// sigmas, with sigmas stated in its file or kept as asked
// (ControlPrecision::deferred): judged by its variance component in the
// adjustment, whose redundancy share allows for the block's own precision
// at the control. Too little redundancy (a weak block that the control
// holds) cannot contradict the stated sigmas.
void JudgeControlByItsComponent(SurveyState* s, const VarianceComponent& vc) {
  if (!s->report.control_precision.deferred || !(vc.stated_sigma > 0.0) || !std::isfinite(vc.sigma0)) return;
  const double factor = vc.EstimatedSigma() / vc.stated_sigma;
  if (!(factor > 3.0) || vc.redundancy < 3.0) return;
  char text[400];
  std::snprintf(text, sizeof text,
                "the control scatters %.0f times its stated sigmas in the adjustment: %.3g m against %.3g m "
                "(variance component, redundancy %.1f of %d coordinates)%s",
                factor, vc.EstimatedSigma(), vc.stated_sigma, vc.redundancy, vc.rows,
                vc.estimated ? "; the adjustment weighs it by the estimate"
                             : "; the stated sigmas were kept: the block is bent to fit the control");
  s->report.findings.push_back(Finding::Warning("CONTROL_WEAKER_THAN_STATED", text));
}

}  // namespace

void ReportGnssAndAttitude(SurveyState* s) {
  for (auto& [index, prior] : s->rejected_gps) s->model->images[index].gps_prior = prior;
  const GpsDriftReport& drift = s->report.gps_drift;
  if (drift.estimated) {
    ReportDrift(s);
  } else if (drift.attitude_prior) {
    const bool gimbal = drift.vertical_source == "gimbal";
    s->report.findings.push_back(Finding::Warning(
        "GPS_TILT_REJECTED",
        std::string("the GPS heights would tilt this ") + (gimbal ? "oblique" : "nadir") + " block by " +
            FormatDegrees(drift.gps_fit_tilt_deg) + " without any trend in time; the block is levelled by the photos' " +
            (gimbal ? "gimbal pitches" : "nadir attitude") + " instead: check the GPS altitudes"));
  }
  ReportAttitude(s);
}

void EvaluateGroundPoints(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  SparseModel* model = s->model;
  std::vector<Eigen::Vector3d> control_d, check_d;
  for (const SurveyedPoint& p : s->surveyed) {
    Point& point = model->points[p.point_index];
    GroundPointResult r =
        EvaluateGroundPoint(p.source->name, p.role, ViewsOf(*model, p.point_index), p.geodetic, s->Frame(),
                            *s->out_crs, /*triangulate=*/p.role == PointRole::kCheck && !report.check_points_in_bundle,
                            &point.position);
    if (!p.excluded.empty()) {
      r.solved = false;
      r.why_not = p.excluded;
    }
    if (p.source->horizontal_only && p.role == PointRole::kControl) {
      // Its height is the adjustment's own: no vertical residual, and no
      // part in the 3D statistics (which count the points they rest on).
      r.horizontal_only = true;
      r.d_m.z() = std::numeric_limits<double>::quiet_NaN();
      r.surveyed_crs.z() = std::numeric_limits<double>::quiet_NaN();
    } else if (r.solved) {
      (p.role == PointRole::kControl ? control_d : check_d).push_back(r.d_m);
    }
    const PointPrecision* precision = report.bundle.precision.ForPoint(p.point_index);
    if (r.solved && precision) {
      const Eigen::Matrix3d j = CrsFromEnuJacobian(s->Frame(), *s->out_crs, point.position);
      r.has_precision = true;
      r.sigma_m = (j * precision->cov * j.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
    }
    (p.role == PointRole::kControl ? report.control : report.check).push_back(r);
  }
  report.control_stats = AccuracyStats::FromResiduals(control_d);
  report.check_stats = AccuracyStats::FromResiduals(check_d);
}

void TestDome(SurveyState* s) {
  const SparseModel& model = *s->model;
  GeoreferenceReport& report = s->report;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  int n = 0;
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    centre += image.pose.centre_in_world.head<2>();
    ++n;
  }
  if (n > 0) centre /= n;
  double radius = 0.0;
  for (const Image& image : model.images) {
    if (image.registered) radius = std::max(radius, (image.pose.centre_in_world.head<2>() - centre).norm());
  }
  std::vector<Eigen::Vector2d> xy;
  std::vector<double> dz;
  for (size_t k = 0; k < report.check.size(); ++k) {
    if (!report.check[k].solved) continue;
    for (const SurveyedPoint& p : s->surveyed) {
      if (p.role == PointRole::kCheck && p.source->name == report.check[k].name) {
        xy.push_back(model.points[p.point_index].position.head<2>());
        dz.push_back(report.check[k].d_m.z());
      }
    }
  }
  std::string source = "check points";
  if (xy.size() < 4) {
    xy.clear();
    dz.clear();
    source = "GPS";
    for (const Image& image : model.images) {
      if (!image.registered || !image.gps_prior || GpsRejected(*s, image)) continue;
      xy.push_back(image.pose.centre_in_world.head<2>());
      dz.push_back((GpsAsAdjusted(*s, image) - image.gps_prior->position).z());
    }
  }
  report.dome = FitDome(xy, dz, centre, radius, source);
}

void ReportCameras(SurveyState* s) {
  const BundlePrecision& precision = s->report.bundle.precision;
  s->report.precision_note = precision.computed ? "" : precision.note;
  for (size_t index = 0; index < s->model->images.size(); ++index) {
    if (s->model->images[index].registered) s->report.cameras.push_back(CameraInCrs(*s, index));
  }
}

void ReportVarianceComponents(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  const BundlePrecision& precision = report.bundle.precision;
  std::vector<double> h, v;
  for (const CameraResult& c : report.cameras) {
    if (!c.has_precision) continue;
    h.push_back(c.sigma_position_m.head<2>().norm());
    v.push_back(c.sigma_position_m.z());
  }
  if (!h.empty()) {
    std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    report.placement = {true, h[h.size() / 2], v[v.size() / 2]};
  }
  const bool gps_datum = report.datum_source.rfind("GPS", 0) == 0;
  if (s->Options().posterior_precision && !precision.computed) {
    report.findings.push_back(Finding::Warning(
        "PRECISION_NOT_COMPUTED", "posterior standard deviations and the marks' w-test are missing: " + precision.note));
  }
  // Observation groups whose data scatter several times their stated sigmas
  // (control has its own finding, CONTROL_WEAKER_THAN_STATED).
  for (const VarianceComponent& vc : report.bundle.variance_components) {
    if (vc.group == ObservationGroup::kControl) {
      JudgeControlByItsComponent(s, vc);
      continue;
    }
    if (!(vc.stated_sigma > 0.0)) continue;
    const double factor = vc.EstimatedSigma() / vc.stated_sigma;
    if (!(factor > 3.0)) continue;
    const bool px = vc.group == ObservationGroup::kTies || vc.group == ObservationGroup::kMarks;
    char text[400];
    std::snprintf(text, sizeof text,
                  "%s scatter %.1f times their stated sigma: %.3g %s against %.3g %s (variance component, "
                  "redundancy %.0f)%s",
                  vc.group == ObservationGroup::kTies            ? "tie-point measurements"
                  : vc.group == ObservationGroup::kMarks         ? "target marks"
                  : vc.group == ObservationGroup::kGpsHorizontal ? "GPS positions horizontally"
                                                                 : "GPS heights",
                  factor, vc.EstimatedSigma(), px ? "px" : "m", vc.stated_sigma, px ? "px" : "m", vc.redundancy,
                  vc.estimated ? "; the adjustment weighs them by the estimate"
                               : "; state the estimate, or let it be used (--variance-components estimate)");
    std::string message = text;
    const bool gps = vc.group == ObservationGroup::kGpsHorizontal || vc.group == ObservationGroup::kGpsVertical;
    if (gps && gps_datum && vc.estimated && report.placement.computed) {
      // A poor GPS is not an inconsistent one: the survey is delivered, and
      // how well it is placed is said.
      char placed[240];
      std::snprintf(placed, sizeof placed,
                    "; the survey's placement rests on it: the cameras are placed to %.2g m horizontally and "
                    "%.2g m vertically (1 sigma), the shape to the photos' precision",
                    report.placement.sigma_h_m, report.placement.sigma_v_m);
      message += placed;
    }
    report.findings.push_back(Finding::Warning("SIGMAS_OPTIMISTIC", message, {ToString(vc.group)}));
  }
}

void SnoopTargetMarks(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  const SparseModel& model = *s->model;
  for (const MarkTest& t : report.bundle.precision.marks) {
    MarkResult m;
    m.point = model.points[t.point].name;
    m.image = model.images[t.image].name;
    m.role = model.points[t.point].role;
    m.residual_px = t.residual_px;
    m.redundancy = t.redundancy;
    m.w = t.w;
    report.marks.push_back(m);
  }
  report.mark_tests = CountMarkTests(report.marks);
  report.mark_family_alpha = s->Options().gates.mark_family_alpha;
  report.w_critical_family = FamilyWiseCriticalValue(std::max(report.mark_tests, 1), report.mark_family_alpha);
  for (Finding& f : SnoopMarks(&report.marks, report.w_critical, report.w_critical_family, report.mark_family_alpha)) {
    report.findings.push_back(std::move(f));
  }
}

}  // namespace aerotri
