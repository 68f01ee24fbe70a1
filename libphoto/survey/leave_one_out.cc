// SPDX-License-Identifier: BSD-3-Clause
// Leave-one-out over the control points (survey_phases.h LeaveControlOut).
#include <chrono>

#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

// The options of the survey's final solve, for a re-solve from its optimum:
// the weights its variance components arrived at, its GNSS offsets and
// drift as starts, least squares on the observations it kept (no
// screening, no outlier round), and nothing but the solve.
BundleOptions WarmOptions(const SurveyState& s) {
  BundleOptions o = s.bundle;
  const BundleSummary& b = s.report.bundle;
  for (const VarianceComponent& vc : b.variance_components) o.sigma_scale[static_cast<int>(vc.group)] = vc.scale;
  o.estimate_variance_components = false;
  o.compute_precision = false;
  o.compute_intrinsics_covariance = false;
  o.loss = LossType::kNone;
  o.least_squares_after_screening = false;
  o.max_outlier_rounds = 0;
  o.outlier_threshold_px = 0.0;
  o.initial_gps_offset_m = b.gps_offset_m;
  o.initial_gps_flight_offsets_m = b.gps_flight_offsets_m;
  if (b.gps_drift_estimated) o.initial_gps_drift_m_per_s = b.gps_drift_m_per_s;
  o.iteration_callback = nullptr;
  return o;
}

}  // namespace

// Each control point withheld in turn, from the survey's own optimum: its
// prior and its marks taken out, the block solved again from the adjusted
// state (a few iterations: only that point's pull is gone), and the point
// triangulated from the cameras as an independent check (or, with check
// points in the bundle, adjusted as a free point, as they are). The
// survey's own decisions stay: its weights, outliers, GNSS offset and drift
// model, what it refines. A separate adjustment without the point (a cold
// start through every phase) remakes those decisions; where none hinges on
// the one point, both end at the same optimum (tests: 1 mm).
void LeaveControlOut(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  if (!options.leave_one_out) return;
  LeaveOneOut& loo = s->report.leave_one_out;
  const auto loo_start = std::chrono::steady_clock::now();
  std::vector<const SurveyedPoint*> control;
  for (const SurveyedPoint& p : s->surveyed) {
    if (p.role == PointRole::kControl && p.excluded.empty()) control.push_back(&p);
  }
  const int n = static_cast<int>(control.size());
  if (n < 4) {
    loo.note = "needs 4 or more control points (have " + std::to_string(n) + "): 3 must hold the datum";
    loo.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loo_start).count();
    return;
  }
  const BundleOptions warm = WarmOptions(*s);
  SparseModel base = *s->model;
  // The GPS the survey left out stays out (ReportGnssAndAttitude restored it
  // for the report).
  for (const auto& [index, prior] : s->rejected_gps) base.images[index].gps_prior.reset();
  const bool in_bundle = warm.check_points_in_bundle;
  std::vector<Eigen::Vector3d> d;
  for (int k = 0; k < n; ++k) {
    const SurveyedPoint& p = *control[k];
    ReportProgress(options.progress, 0.9 + 0.1 * k / n, "leave-one-out: without " + p.source->name);
    SparseModel copy = base;
    Point& point = copy.points[p.point_index];
    point.prior.reset();
    point.role = PointRole::kCheck;
    const BundleSummary solved = AdjustBundle(&copy, warm);
    ++loo.adjustments;
    loo.iterations += solved.iterations;
    Eigen::Vector3d position = copy.points[p.point_index].position;
    GroundPointResult r = EvaluateGroundPoint(p.source->name, PointRole::kCheck, ViewsOf(copy, p.point_index),
                                              p.geodetic, s->Frame(), *s->out_crs, /*triangulate=*/!in_bundle,
                                              &position);
    r.role = PointRole::kControl;
    if (p.source->horizontal_only) {
      r.solved = false;
      r.why_not = "surveyed in plan only: no height to check";
    }
    if (r.solved) d.push_back(r.d_m);
    loo.points.push_back(r);
  }
  loo.stats = AccuracyStats::FromResiduals(d);
  loo.computed = true;
  loo.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loo_start).count();
}

}  // namespace aerotri
