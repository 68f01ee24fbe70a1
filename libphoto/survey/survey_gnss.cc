// SPDX-License-Identifier: BSD-3-Clause
// The GNSS model: GPS judged against the control datum, offset, drift and
// attitude prior configured for the adjustment (survey_phases.h ModelGnss).
#include <algorithm>
#include <cmath>
#include <functional>

#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

// GPS minus the camera centres of an adjustment held by the control alone;
// a constant part is an offset (antenna, height reference), the rest GPS
// noise or blunders. The similarity alone would not do: its model still
// carries the reconstruction's intrinsics, and a focal length 1 % off moves
// every camera height by 1 % of the flying height. Observations this
// adjustment rejects leave the model before the final solve (counted in its
// figure, never hidden).
std::vector<Eigen::Vector3d> GpsMinusControlAdjustment(SurveyState* s) {
  ReportProgress(s->Options().progress, 0.15, "adjustment on control alone: GPS against control");
  BundleOptions control_only = s->bundle;
  control_only.use_gps_priors = false;
  // A judge of the GPS, not a deliverable: Ceres' default tolerance
  // suffices (weakly held intrinsics converge slowly without the GPS).
  control_only.function_tolerance = std::max(s->bundle.function_tolerance, 1e-6);
  const BundleSummary control_summary = AdjustBundle(s->model, control_only);
  s->outliers_before_final = control_summary.outliers_removed;
  if (!control_summary.converged) {
    s->report.findings.push_back(Finding::Warning(
        "ADJUSTMENT_NOT_CONVERGED",
        "adjustment on control alone (to judge the GPS) did not converge: " + control_summary.termination));
  }
  std::vector<Eigen::Vector3d> d(s->gps_images.size());
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    d[k] = s->gps_to[k] - AntennaOf(s->model->images[s->gps_images[k]], s->bundle.gnss_lever_arm_m);
  }
  return d;
}

// A GNSS drift in time shows in d directly (the control holds the datum):
// estimated per flight, and d taken about it.
void TestDriftAgainstControl(SurveyState* s, std::vector<Eigen::Vector3d>* d) {
  GpsDriftReport& drift = s->report.gps_drift;
  if (s->num_timed < 6) {
    drift.note = "not tested: capture times on fewer than 6 photos with GPS";
    return;
  }
  drift.tested = true;
  const DriftTrend trend = FitDriftTrend(*d, s->flights, s->median_sigma_h, s->median_sigma_v);
  RecordDriftTrend(s, trend);
  if (!trend.Significant()) {
    drift.note = "no significant trend in time of GPS minus the control-only adjustment";
    return;
  }
  drift.estimated = true;
  drift.axes = trend.significant_axes;
  AttachFlights(s);
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    if (s->flights.flight[k] >= 0) (*d)[k] -= s->initial_drift_rates[s->flights.flight[k]] * s->flights.dt_s[k];
  }
  drift.note = "GPS minus the control-only adjustment trends in time: drift estimated per flight";
}

// The component-wise median of d over the images that `in` selects.
Eigen::Vector3d MedianOf(const std::vector<Eigen::Vector3d>& d, const std::function<bool(size_t)>& in) {
  Eigen::Vector3d median = Eigen::Vector3d::Zero();
  for (int c = 0; c < 3; ++c) {
    std::vector<double> v;
    for (size_t k = 0; k < d.size(); ++k) {
      if (in(k)) v.push_back(d[k][c]);
    }
    if (v.empty()) continue;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    median[c] = v[v.size() / 2];
  }
  return median;
}

// The GPS offset from the control datum: the positions within the Helmert
// threshold of the median (per flight with --gps-offset per-flight, each
// flight about its own), their mean, its standard error and significance.
// Returns which positions are consistent.
std::vector<char> MeasureGpsOffset(SurveyState* s, const std::vector<Eigen::Vector3d>& d) {
  GpsVersusControl& versus = s->report.gps_vs_control;
  const FlightTimes& flights = s->flights;
  const Eigen::Vector3d median = MedianOf(d, [](size_t) { return true; });
  const bool per_flight = s->Options().gps_offset == GpsOffsetPolicy::kPerFlight && flights.NumFlights() > 1;
  std::vector<Eigen::Vector3d> flight_median(flights.NumFlights(), median);
  if (per_flight) {
    for (int f = 0; f < flights.NumFlights(); ++f) {
      flight_median[f] = MedianOf(d, [&](size_t k) { return flights.flight[k] == f; });
    }
  }
  auto centre_of = [&](size_t k) {
    return per_flight && flights.flight[k] >= 0 ? flight_median[flights.flight[k]] : median;
  };
  std::vector<char> consistent(s->gps_images.size(), 0);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sigma_sum = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> flight_sum(flights.NumFlights(), Eigen::Vector3d::Zero());
  std::vector<int> flight_count(flights.NumFlights(), 0);
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    const PositionPrior& prior = *s->model->images[s->gps_images[k]].gps_prior;
    const double threshold = HelmertThreshold(s->Options(), std::max(prior.sigma_h_m, prior.sigma_v_m));
    if ((d[k] - centre_of(k)).norm() > threshold) continue;
    consistent[k] = 1;
    ++versus.consistent;
    sum += d[k];
    sigma_sum += Eigen::Vector3d(prior.sigma_h_m, prior.sigma_h_m, prior.sigma_v_m);
    if (flights.flight[k] >= 0) {
      flight_sum[flights.flight[k]] += d[k];
      ++flight_count[flights.flight[k]];
    }
  }
  if (per_flight) {
    for (int f = 0; f < flights.NumFlights(); ++f) {
      versus.flight_offsets_enu_m.push_back(flight_count[f] > 0 ? Eigen::Vector3d(flight_sum[f] / flight_count[f])
                                                                : flight_median[f]);
    }
  }
  if (versus.consistent == 0) return consistent;
  const double n = versus.consistent;
  versus.offset_enu_m = sum / n;
  Eigen::Vector3d var = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    if (consistent[k]) var += (d[k] - versus.offset_enu_m).cwiseAbs2();
  }
  versus.rms_after_offset_m = (var / n).cwiseSqrt();
  versus.offset_sigma_m =
      n > 1 ? Eigen::Vector3d((var / (n - 1) / n).cwiseSqrt()) : Eigen::Vector3d(sigma_sum / n);
  const Eigen::Vector3d prior_sigma = sigma_sum / n;
  for (int c = 0; c < 3; ++c) {
    versus.significant |= std::abs(versus.offset_enu_m[c]) > 3.0 * versus.offset_sigma_m[c] &&
                          std::abs(versus.offset_enu_m[c]) > prior_sigma[c];
  }
  return consistent;
}

// GPS positions that disagree with the control datum leave the adjustment
// (GPS_REJECTED); a significant offset is said (GPS_CONTROL_OFFSET).
void RejectGpsAgainstControl(SurveyState* s, const std::vector<char>& consistent) {
  GpsVersusControl& versus = s->report.gps_vs_control;
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    if (consistent[k]) continue;
    Image& image = s->model->images[s->gps_images[k]];
    versus.rejected.push_back(image.name);
    s->rejected_gps[s->gps_images[k]] = *image.gps_prior;
    image.gps_prior.reset();
  }
  const Eigen::Vector3d& o = versus.offset_enu_m;
  const Eigen::Vector3d& so = versus.offset_sigma_m;
  const std::string offset_text = "E " + FormatMetres(o.x()) + " ± " + FormatMetres(so.x()) + ", N " +
                                  FormatMetres(o.y()) + " ± " + FormatMetres(so.y()) + ", U " +
                                  FormatMetres(o.z()) + " ± " + FormatMetres(so.z());
  if (versus.significant) {
    const bool estimate = s->Options().gps_offset != GpsOffsetPolicy::kNever;
    s->report.findings.push_back(Finding::Warning(
        "GPS_CONTROL_OFFSET",
        "GPS and control disagree by a constant offset (GPS minus control datum, " +
            std::to_string(versus.consistent) + " cameras): " + offset_text +
            (estimate ? "; estimated in the adjustment as a GPS offset (antenna or height "
                        "reference: check --gps-altitude)"
                      : "; not estimated (--gps-offset never): the GPS pulls against the control")));
  }
  if (!versus.rejected.empty()) {
    s->report.findings.push_back(Finding::Warning(
        "GPS_REJECTED",
        std::to_string(versus.rejected.size()) + " of " + std::to_string(versus.cameras) +
            " GPS positions disagree with the control datum after the offset; left out of the "
            "adjustment: " + JoinNames(versus.rejected),
        versus.rejected));
  }
}

// The GPS against the control datum (step one of the GNSS model).
void JudgeGpsAgainstControl(SurveyState* s) {
  std::vector<Eigen::Vector3d> d = GpsMinusControlAdjustment(s);
  GpsVersusControl& versus = s->report.gps_vs_control;
  versus.measured = true;
  versus.cameras = static_cast<int>(s->gps_images.size());
  TestDriftAgainstControl(s, &d);
  const std::vector<char> consistent = MeasureGpsOffset(s, d);
  RejectGpsAgainstControl(s, consistent);
}

// The offset (one, or per flight), the drift and the attitude prior as the
// adjustment's options.
void ConfigureGnssModel(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  const GpsVersusControl& versus = s->report.gps_vs_control;
  const GpsDriftReport& drift = s->report.gps_drift;
  BundleOptions& bundle = s->bundle;
  const bool always =
      options.gps_offset == GpsOffsetPolicy::kAlways || options.gps_offset == GpsOffsetPolicy::kPerFlight;
  if (versus.measured && options.gps_offset != GpsOffsetPolicy::kNever && (versus.significant || always)) {
    bundle.estimate_gps_offset = true;
    bundle.initial_gps_offset_m = versus.offset_enu_m;
    if (!versus.flight_offsets_enu_m.empty()) {
      AttachFlights(s);
      bundle.gps_offset_per_flight = true;
      bundle.initial_gps_flight_offsets_m = versus.flight_offsets_enu_m;
    }
  } else if (always && !s->gps_images.empty()) {
    s->report.findings.push_back(Finding::Warning(
        "GPS_OFFSET_NOT_ESTIMATED",
        "GPS offset not estimated: it needs 3 or more non-collinear control points measured in 2 "
        "or more images each to hold the datum"));
  }
  if (drift.estimated) {
    bundle.estimate_gps_drift = true;
    bundle.gps_drift_axes = drift.axes;
    bundle.initial_gps_drift_m_per_s = s->initial_drift_rates;
  }
  if (drift.attitude_prior) {
    bundle.attitude_prior_sigma_deg = drift.attitude_prior_sigma_deg;
    bundle.attitude_prior_down_in_camera.clear();
    if (drift.vertical_source == "gimbal") {
      // Each photo's own vertical; photos without gimbal angles go without.
      const SparseModel& model = *s->model;
      bundle.attitude_prior_down_in_camera.assign(model.images.size(), Eigen::Vector3d::Zero());
      for (size_t i = 0; i < model.images.size(); ++i) {
        const auto it = options.gimbal.find(model.images[i].name);
        if (it != options.gimbal.end()) bundle.attitude_prior_down_in_camera[i] = DownInCamera(it->second);
      }
    }
  }
}

}  // namespace

void ModelGnss(SurveyState* s) {
  if (s->control_datum && !s->gps_images.empty()) JudgeGpsAgainstControl(s);
  ConfigureGnssModel(s);
}

}  // namespace aerotri
