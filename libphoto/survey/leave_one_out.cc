// SPDX-License-Identifier: BSD-3-Clause
// Leave-one-out over the control points (survey_phases.h LeaveControlOut).
#include <chrono>
#include <map>

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
  o.withhold_points.clear();
  return o;
}

// One control point withheld from its own adjustment: its residual as a
// check point's, from `model` as that adjustment left it.
GroundPointResult Withheld(const SurveyState& s, const SurveyedPoint& p, const SparseModel& model, bool in_bundle) {
  Eigen::Vector3d position = model.points[p.point_index].position;
  GroundPointResult r = EvaluateGroundPoint(p.source->name, PointRole::kCheck, ViewsOf(model, p.point_index),
                                            p.geodetic, s.Frame(), *s.out_crs, /*triangulate=*/!in_bundle,
                                            &position);
  r.role = PointRole::kControl;
  if (p.source->horizontal_only) {
    r.solved = false;
    r.why_not = "surveyed in plan only: no height to check";
  }
  return r;
}

// `model` with a withheld point's update applied (WithheldPoint), the values
// it replaced kept in `undo`.
void Apply(const WithheldPoint& w, SparseModel* model, WithheldPoint* undo) {
  undo->point = w.point;
  undo->position = model->points[w.point].position;
  for (const auto& [i, pose] : w.images) {
    undo->images.emplace_back(i, model->images[i].pose);
    model->images[i].pose = pose;
  }
  for (const auto& [c, params] : w.cameras) {
    undo->cameras.emplace_back(c, model->cameras[c].params);
    model->cameras[c].params = params;
  }
  model->points[w.point].position = w.position;
}

}  // namespace

// The control points leave-one-out withholds (those in use), when it runs:
// 4 or more, so that 3 hold the datum without the one.
std::vector<const SurveyedPoint*> ControlToWithhold(const SurveyState& s) {
  std::vector<const SurveyedPoint*> control;
  if (!s.Options().leave_one_out) return control;
  for (const SurveyedPoint& p : s.surveyed) {
    if (p.role == PointRole::kControl && p.excluded.empty()) control.push_back(&p);
  }
  return control;
}

void WithholdControl(SurveyState* s) {
  BundleOptions& b = s->bundle;
  b.withhold_points.clear();
  const std::vector<const SurveyedPoint*> control = ControlToWithhold(*s);
  // The final pass must be the least-squares estimate's, as a re-solve's
  // from the optimum would be (WarmOptions).
  const bool least_squares = b.loss == LossType::kNone || (b.least_squares_after_screening &&
                                                           b.outlier_threshold_px > 0.0 && b.max_outlier_rounds > 0);
  if (control.size() < 4 || !b.compute_precision || !least_squares) return;
  for (const SurveyedPoint* p : control) b.withhold_points.push_back(p->point_index);
}

// Each control point withheld in turn, from the survey's own optimum: its
// prior and its marks taken out (with check points in the bundle, its prior
// only), and the point triangulated from the cameras as an independent
// check (or adjusted as a free point, as check points then are). The
// survey's own decisions stay: its weights, outliers, GNSS offset and drift
// model, what it refines. A separate adjustment without the point (a cold
// start through every phase) remakes those decisions; where none hinges on
// the one point, both end at the same optimum (tests: 1 mm).
//
// The block without the point is the block-deletion update of the normal
// equations at the optimum (BundleOptions::withhold_points): one precision
// pass gives every point's, where a re-solve per point cost a whole
// adjustment's iterations each. A point the update cannot take (its cameras
// not determined without it) is re-solved from the optimum instead.
void LeaveControlOut(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  if (!options.leave_one_out) return;
  LeaveOneOut& loo = s->report.leave_one_out;
  const auto loo_start = std::chrono::steady_clock::now();
  const std::vector<const SurveyedPoint*> control = ControlToWithhold(*s);
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

  // Each point's update from the normal equations at the survey's optimum:
  // its own final precision pass computed them (WithholdControl), else the
  // optimum once more with the survey's final weights (a step or two) and
  // a precision pass.
  ReportProgress(options.progress, 0.9, "leave-one-out: the block without each control point");
  const std::vector<WithheldPoint>* withheld = &s->report.bundle.precision.withheld;
  BundleSummary solved;
  if (withheld->size() != control.size()) {
    BundleOptions updates = warm;
    updates.compute_precision = true;
    updates.withhold_points.clear();
    for (const SurveyedPoint* p : control) updates.withhold_points.push_back(p->point_index);
    solved = AdjustBundle(&base, updates);
    ++loo.adjustments;
    loo.iterations += solved.iterations;
    withheld = &solved.precision.withheld;
  }
  std::map<int, const WithheldPoint*> update_of;
  for (const WithheldPoint& w : *withheld) {
    if (w.computed) update_of.emplace(w.point, &w);
  }
  std::vector<Eigen::Vector3d> d;
  for (int k = 0; k < n; ++k) {
    const SurveyedPoint& p = *control[k];
    const auto it = update_of.find(p.point_index);
    GroundPointResult r;
    if (it != update_of.end()) {
      WithheldPoint undo;
      Apply(*it->second, &base, &undo);
      r = Withheld(*s, p, base, in_bundle);
      WithheldPoint ignored;
      Apply(undo, &base, &ignored);
      ++loo.updated;
    } else {
      ReportProgress(options.progress, 0.9 + 0.1 * k / n, "leave-one-out: without " + p.source->name);
      SparseModel copy = base;
      Point& point = copy.points[p.point_index];
      point.prior.reset();
      point.role = PointRole::kCheck;
      const BundleSummary alone = AdjustBundle(&copy, warm);
      ++loo.adjustments;
      loo.iterations += alone.iterations;
      r = Withheld(*s, p, copy, in_bundle);
    }
    if (r.solved) d.push_back(r.d_m);
    loo.points.push_back(r);
  }
  loo.stats = AccuracyStats::FromResiduals(d);
  loo.computed = true;
  loo.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loo_start).count();
}

}  // namespace aerotri
