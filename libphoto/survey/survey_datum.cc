// SPDX-License-Identifier: BSD-3-Clause
// The initial similarity: the model mapped onto the datum (survey_phases.h
// FitInitialSimilarity).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "libphoto/base/error.h"
#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

constexpr double kAttitudePriorSigmaDeg = 5.0;  // per photo (GpsDriftReport)

// The datum's correspondences: registered images with GPS, and control
// points triangulated in the model's own frame (those with heights).
void CollectDatumCorrespondences(SurveyState* s) {
  SparseModel* model = s->model;
  for (size_t i = 0; i < model->images.size(); ++i) {
    const Image& image = model->images[i];
    if (!image.registered || !image.gps_prior) continue;
    s->gps_images.push_back(static_cast<int>(i));
    s->gps_from.push_back(image.pose.centre_in_world);
    s->gps_to.push_back(image.gps_prior->position);
    s->gps_max_sigma = std::max({s->gps_max_sigma, image.gps_prior->sigma_h_m, image.gps_prior->sigma_v_m});
  }
  s->triangulated.assign(model->points.size(), 0);
  for (const SurveyedPoint& p : s->surveyed) {
    if (p.role != PointRole::kControl) continue;
    const auto t = TriangulatePoint(ViewsOf(*model, p.point_index));
    if (!t) continue;
    s->triangulated[p.point_index] = 1;
    model->points[p.point_index].position = t->position;
    if (p.source->horizontal_only) continue;  // no height: no part in a 3D similarity
    s->control_points.push_back(p.point_index);
    s->control_from.push_back(t->position);
    const PositionPrior& prior = *model->points[p.point_index].prior;
    s->control_to.push_back(prior.position);
    s->control_max_sigma = std::max({s->control_max_sigma, prior.sigma_h_m, prior.sigma_v_m});
  }
}

// The block's viewing geometry in its own frame, and the GPS images' capture
// times, flights and median sigmas (the GNSS drift model, gnss_drift.h).
void MeasureGpsTiming(SurveyState* s) {
  const SparseModel& model = *s->model;
  s->report.viewing = MeasureViewingGeometry(model);
  std::vector<double> gps_times;
  for (int i : s->gps_images) gps_times.push_back(s->gps.at(model.images[i].name).time_s);
  s->num_timed = static_cast<int>(
      std::count_if(gps_times.begin(), gps_times.end(), [](double t) { return std::isfinite(t); }));
  s->flights = SplitFlights(gps_times);
  std::vector<double> h, v;
  for (int i : s->gps_images) {
    h.push_back(model.images[i].gps_prior->sigma_h_m);
    v.push_back(model.images[i].gps_prior->sigma_v_m);
  }
  if (!h.empty()) {
    std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    s->median_sigma_h = h[h.size() / 2];
    s->median_sigma_v = v[v.size() / 2];
  }
}

// The control's scatter per axis over the fit's inliers (7 parameters
// fitted) after a similarity from `from`.
double ControlScatter(const SurveyState& s, const std::vector<int>& in, const std::vector<Eigen::Vector3d>& from) {
  std::vector<Eigen::Vector3d> a, b;
  for (int k : in) a.push_back(from[k]), b.push_back(s.control_to[k]);
  const auto fit = FitSimilarity(a, b);
  if (!fit) return std::numeric_limits<double>::infinity();
  double sum2 = 0.0;
  for (size_t k = 0; k < a.size(); ++k) sum2 += (fit->Apply(a[k]) - b[k]).squaredNorm();
  return std::sqrt(sum2 / std::max(1, 3 * static_cast<int>(in.size()) - 7));
}

// The scatter of the control about a free network: the block adjusted
// without the control's priors (its marks kept, as free points; the datum a
// held image and baseline, or the GPS), then fitted to it again. Loosening
// the priors a thousandfold instead left a nearly free datum on which
// Levenberg-Marquardt crawled (6 minutes on a 41-photo survey).
double FreeNetworkControlScatter(const SurveyState& s, const std::vector<int>& in) {
  const GeoreferenceOptions& options = s.Options();
  ReportProgress(options.progress, 0.12, "control precision: free-network check");
  SparseModel free = *s.model;
  ApplySimilarity(s.fit->transform, &free);
  for (Point& point : free.points) {
    if (point.role == PointRole::kControl) point.prior.reset();
  }
  BundleOptions loose = options.bundle;
  if (options.auto_refine) loose.refine_intrinsics = IntrinsicsRefinement::kAll;
  loose.function_tolerance = std::max(loose.function_tolerance, 1e-6);
  loose.compute_precision = false;
  loose.check_points_in_bundle = false;  // they are not placed yet; they judge nothing here
  AdjustBundle(&free, loose);
  std::vector<Eigen::Vector3d> adjusted(s.control_from.size());
  for (size_t k = 0; k < s.control_points.size(); ++k) {
    const auto t = TriangulatePoint(ViewsOf(free, s.control_points[k]));
    adjusted[k] = t ? t->position : free.points[s.control_points[k]].position;
  }
  return ControlScatter(s, in, adjusted);
}

// The control's precision against its stated sigmas: first about the model
// as it came; that model is not yet adjusted (its intrinsics may be rough),
// so a scatter beyond 3 times the stated sigmas is confirmed on a free
// network. Control that scatters so is weighed by the estimate unless the
// file's sigmas are to be kept (CONTROL_WEAKER_THAN_STATED).
void MeasureControlPrecision(SurveyState* s) {
  const int n_control = static_cast<int>(s->control_from.size());
  std::vector<int> in;
  double stated2 = 0.0;
  for (int k = 0; k < n_control; ++k) {
    if (!s->fit->inliers[k]) continue;
    in.push_back(k);
    const PositionPrior& p = *s->model->points[s->control_points[k]].prior;
    stated2 += (2.0 * p.sigma_h_m * p.sigma_h_m + p.sigma_v_m * p.sigma_v_m) / 3.0;
  }
  const int n = static_cast<int>(in.size());
  auto& cp = s->report.control_precision;
  cp.measured = true;
  cp.points = n;
  cp.stated_m = std::sqrt(stated2 / n);
  cp.estimated_m = ControlScatter(*s, in, s->control_from);
  if (cp.estimated_m > 3.0 * cp.stated_m) cp.estimated_m = FreeNetworkControlScatter(*s, in);
  if (!(cp.estimated_m > 3.0 * cp.stated_m)) return;
  if (s->Options().keep_stated_control_sigmas || (s->Options().hold_stated_sigmas && ControlSigmasStated(*s))) {
    // Kept as asked, or stated in the file. A free network of a weak block
    // deforms at the control by its own imprecision, which its scatter
    // cannot tell from the control's: the adjustment's variance component
    // for the control, whose redundancy share allows for the block's
    // precision there, judges them instead (ReportVarianceComponents).
    cp.deferred = true;
    return;
  }
  {
    // Weigh the control by what it shows: every control prior scaled alike.
    const double f = cp.estimated_m / cp.stated_m;
    for (int k : s->control_points) {
      PositionPrior& p = *s->model->points[k].prior;
      p.sigma_h_m *= f;
      p.sigma_v_m *= f;
      if (p.covariance) *p.covariance *= f * f;
    }
    cp.adopted = true;
  }
  s->report.findings.push_back(Finding::Warning(
      "CONTROL_WEAKER_THAN_STATED",
      "the control points scatter about the model by " + FormatMetres(cp.estimated_m) + " per axis (" +
          std::to_string(n) + " points), " +
          std::to_string(static_cast<int>(std::lround(cp.estimated_m / cp.stated_m))) + " times the " +
          FormatMetres(cp.stated_m) + " their sigmas state; the adjustment weighs them by the estimate (state "
          "sigmas in the control file, or keep these with --keep-control-sigmas)"));
}

// Priors much noisier than their sigmas leave few points within 5 sigma of
// any fit (a handheld-GPS kite survey stated at 2 cm kept 3 of 8; a consumer
// GPS scattering 12 m stated at 3 m, 12 of 35): the data's own scatter then
// sets the threshold, 4 robust standard deviations per axis (the 99.9 %
// point of a 3D error is 4.03 sigma) about the current fit, refitted until it
// settles; a blunder far off the others' scatter still falls out. Returns
// the threshold the fit ended with.
double WidenToTheScatter(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to,
                       double threshold, std::optional<SimilarityFit>* fit) {
  const int n = static_cast<int>(from.size());
  for (int round = 0; round < 4 && *fit && (*fit)->num_inliers < n; ++round) {
    std::vector<double> r;
    for (int k = 0; k < n; ++k) r.push_back(((*fit)->transform.Apply(from[k]) - to[k]).norm());
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    const double sigma_axis = r[r.size() / 2] / 1.538;  // median of a 3D Gaussian error's length
    const double adaptive = 4.03 * sigma_axis;
    if (!(adaptive > threshold * 1.01)) break;
    threshold = adaptive;
    auto wider = FitSimilarityRobust(from, to, threshold, 1);
    if (!wider || wider->num_inliers <= (*fit)->num_inliers) break;
    *fit = wider;
  }
  return threshold;
}

// With three or more non-collinear control points the datum is theirs;
// control much noisier than its sigmas widens the fit to its scatter
// (WidenToTheScatter).
void FitControlDatum(SurveyState* s) {
  if (s->control_from.size() < 3) return;
  const GeoreferenceOptions& options = s->Options();
  double threshold = HelmertThreshold(options, s->control_max_sigma);
  std::optional<SimilarityFit>& fit = s->fit;
  fit = FitSimilarityRobust(s->control_from, s->control_to, threshold, 1);
  if (options.helmert_inlier_m <= 0.0 && s->control_from.size() >= 4) {
    threshold = WidenToTheScatter(s->control_from, s->control_to, threshold, &fit);
  }
  if (fit && fit->num_inliers >= 4) MeasureControlPrecision(s);
  if (!fit || fit->num_inliers < 3) {
    fit.reset();
    return;
  }
  GeoreferenceReport& report = s->report;
  report.datum_source = "control points (" + std::to_string(fit->num_inliers) + " of " +
                        std::to_string(s->control_from.size()) + " in the initial similarity)";
  report.helmert_correspondences = static_cast<int>(s->control_from.size());
  if (fit->num_inliers >= static_cast<int>(s->control_from.size())) return;
  std::vector<std::string> names;
  for (size_t k = 0; k < s->control_points.size(); ++k) {
    if (!fit->inliers[k]) names.push_back(s->model->points[s->control_points[k]].name);
  }
  report.findings.push_back(Finding::Warning(
      "CONTROL_INCONSISTENT",
      std::to_string(names.size()) + " of " + std::to_string(s->control_from.size()) +
          " control points disagree with the others by more than " + FormatMetres(threshold) +
          " in the initial fit: " + JoinNames(names),
      names));
}

// The block's own vertical in the model frame: a nadir block's mean optical
// axis, else the gimbal pitches' (an empty vertical_source: none).
Eigen::Vector3d BlockVertical(SurveyState* s, std::string* vertical_note) {
  GeoreferenceReport& report = s->report;
  GpsDriftReport& drift = report.gps_drift;
  Eigen::Vector3d down_in_model = report.viewing.mean_axis;
  *vertical_note = report.viewing.reason;
  if (report.viewing.nadir) {
    drift.vertical_source = "nadir";
  } else if (!s->Options().gimbal.empty() && !s->local) {
    report.gimbal_vertical = MeasureGimbalVertical(*s->model, s->Options().gimbal);
    *vertical_note = report.viewing.reason + "; " + report.gimbal_vertical.reason;
    if (report.gimbal_vertical.usable) {
      drift.vertical_source = "gimbal";
      down_in_model = report.gimbal_vertical.down_in_model;
    }
  }
  return down_in_model;
}

// GPS heights that drift in time would tilt a block (strips are flown one
// after another): the block levelled by its own vertical shows the drift as
// a trend in time of the GPS height residuals. A trend, or a GPS fit that
// tilts the block by more than 10°, puts the attitude prior in charge of the
// tilt, with the drift estimated.
void LevelByVertical(SurveyState* s, const std::vector<Eigen::Vector3d>& from,
                     const std::vector<Eigen::Vector3d>& to, double threshold) {
  GpsDriftReport& drift = s->report.gps_drift;
  std::string vertical_note;
  const Eigen::Vector3d down_in_model = BlockVertical(s, &vertical_note);
  const char* block_kind = drift.vertical_source == "gimbal" ? "oblique" : "nadir";
  const char* levelled_by = drift.vertical_source == "gimbal" ? "its gimbal pitches" : "its mean optical axis";
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  const Eigen::Vector3d fit_axis = s->fit->transform.rotation * down_in_model;
  drift.gps_fit_tilt_deg = std::atan2(fit_axis.cross(down).norm(), fit_axis.dot(down)) * 180.0 / M_PI;
  if (drift.vertical_source.empty()) {
    drift.note = "not tested: " + vertical_note;
  } else if (s->gps_images.size() < 6) {
    drift.note = "not tested: fewer than 6 photos with GPS";
  } else if (const auto levelled = FitLevelledSimilarity(from, to, down_in_model, threshold)) {
    drift.tested = true;
    std::vector<Eigen::Vector3d> residuals(s->gps_images.size());
    FlightTimes inliers = s->flights;
    for (size_t k = 0; k < s->gps_images.size(); ++k) {
      residuals[k] = s->gps_to[k] - levelled->transform.Apply(s->gps_from[k]);
      if (!levelled->inliers[k]) inliers.flight[k] = -1;
    }
    const DriftTrend trend = FitDriftTrend(residuals, inliers, s->median_sigma_h, s->median_sigma_v);
    RecordDriftTrend(s, trend);
    const bool drifting = s->num_timed >= 6 && trend.Significant();
    const bool tilted = drift.gps_fit_tilt_deg > 10.0;
    char text[280];
    if (drifting || tilted) {
      s->fit = levelled;
      drift.attitude_prior = true;
      drift.attitude_prior_sigma_deg = kAttitudePriorSigmaDeg;
      drift.estimated = drifting;
      if (drifting) {
        drift.axes = trend.significant_axes;
        AttachFlights(s);
      }
      std::snprintf(text, sizeof text,
                    "the GPS alone would tilt this %s block by %.1f deg; levelled by %s "
                    "(attitude prior %.0f deg per photo)%s",
                    block_kind, drift.gps_fit_tilt_deg, levelled_by, kAttitudePriorSigmaDeg,
                    drifting ? ", the GPS drift estimated per flight" : "");
    } else if (s->num_timed < 6) {
      std::snprintf(text, sizeof text,
                    "no capture times: drift in time not tested; the GPS fit tilts the block %.1f deg from %s",
                    drift.gps_fit_tilt_deg, levelled_by);
    } else {
      std::snprintf(text, sizeof text,
                    "no significant trend in time of the GPS residuals; the GPS fit tilts the block %.1f deg "
                    "from %s",
                    drift.gps_fit_tilt_deg, levelled_by);
    }
    drift.note = text;
  } else {
    drift.note = "not tested: the levelled fit failed";
  }
  if (drift.vertical_source.empty()) {
    s->report.findings.push_back(Finding::Warning(
        "VERTICAL_FROM_GPS_ONLY",
        "the block's tilt rests on the GPS heights alone (" + vertical_note +
            "): a drift or error in them tilts the survey and nothing here can see it; add control points, or "
            "photos with gimbal angles"));
  }
}

// Too little control: GPS and control together, levelled where the GPS
// would tilt or drift the block.
void FitGpsDatum(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  std::vector<Eigen::Vector3d> from = s->gps_from, to = s->gps_to;
  from.insert(from.end(), s->control_from.begin(), s->control_from.end());
  to.insert(to.end(), s->control_to.begin(), s->control_to.end());
  report.helmert_correspondences = static_cast<int>(from.size());
  double threshold = HelmertThreshold(s->Options(), std::max(s->gps_max_sigma, s->control_max_sigma));
  s->fit = FitSimilarityRobust(from, to, threshold, 1);
  if (s->Options().helmert_inlier_m <= 0.0 && from.size() >= 6) {
    threshold = WidenToTheScatter(from, to, threshold, &s->fit);
  }
  if (!s->fit) {
    throw InvalidArgument(
        "cannot georeference: need GPS on 3 or more non-collinear images, or 3 or more control "
        "points measured in 2 or more images each (have " +
        std::to_string(s->num_gps) + " GPS positions and " + std::to_string(s->control_from.size()) +
        " triangulated control points)");
  }
  report.datum_source = s->control_from.empty() ? "GPS" : "GPS and control points";
  LevelByVertical(s, from, to, threshold);
  if (s->fit->num_inliers >= static_cast<int>(from.size())) return;
  std::vector<std::string> names;
  for (size_t k = 0; k < from.size(); ++k) {
    if (s->fit->inliers[k]) continue;
    names.push_back(k < s->gps_images.size() ? s->model->images[s->gps_images[k]].name
                                             : s->model->points[s->control_points[k - s->gps_images.size()]].name);
  }
  report.findings.push_back(Finding::Warning(
      "PRIORS_INCONSISTENT",
      std::to_string(names.size()) + " of " + std::to_string(from.size()) +
          " priors (GPS or control) disagree with the model by more than " + FormatMetres(threshold) +
          " in the initial fit: " + JoinNames(names),
      names));
}

// The similarity applied; control seen once starts at its survey, check
// points inside the bundle where the similarity puts their rays.
void ApplyInitialSimilarity(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  SparseModel* model = s->model;
  report.helmert_inliers = s->fit->num_inliers;
  report.helmert_rms_m = s->fit->rms_m;
  ApplySimilarity(s->fit->transform, model);
  report.check_points_in_bundle = s->Options().bundle.check_points_in_bundle;
  for (const SurveyedPoint& p : s->surveyed) {
    Point& point = model->points[p.point_index];
    if (p.role == PointRole::kControl && !s->triangulated[p.point_index]) {
      point.position = point.prior->position;  // seen once: start at its survey
    }
    if (p.role == PointRole::kCheck && report.check_points_in_bundle) {
      const auto t = TriangulatePoint(ViewsOf(*model, p.point_index));
      point.position = t ? t->position : point.prior->position;
    }
  }
}

}  // namespace

void RecordDriftTrend(SurveyState* s, const DriftTrend& trend) {
  GpsDriftReport& drift = s->report.gps_drift;
  drift.flights.clear();
  s->initial_drift_rates.clear();
  for (const DriftTrend::Flight& f : trend.flights) {
    GpsDriftReport::Flight out;
    out.images = f.images;
    out.duration_s = f.duration_s;
    out.trend_m_per_s = f.rate_m_per_s;
    out.trend_sigma = f.rate_sigma;
    drift.flights.push_back(out);
    Eigen::Vector3d start = Eigen::Vector3d::Zero();
    for (int a = 0; a < 3; ++a) start[a] = trend.significant_axes[a] ? f.rate_m_per_s[a] : 0.0;
    s->initial_drift_rates.push_back(start);
  }
}

void AttachFlights(SurveyState* s) {
  for (size_t k = 0; k < s->gps_images.size(); ++k) {
    PositionPrior& p = *s->model->images[s->gps_images[k]].gps_prior;
    p.flight = s->flights.flight[k];
    p.time_from_flight_s = s->flights.dt_s[k];
  }
}

void FitInitialSimilarity(SurveyState* s) {
  CollectDatumCorrespondences(s);
  MeasureGpsTiming(s);
  FitControlDatum(s);
  s->control_datum = s->fit.has_value();
  if (!s->control_datum) FitGpsDatum(s);
  ApplyInitialSimilarity(s);
}

}  // namespace aerotri
