// SPDX-License-Identifier: BSD-3-Clause
// What the adjustment refines, and the adjustment itself (survey_phases.h
// ChooseRefinement, AdjustBlock, HoldWeakFocal).
#include <algorithm>
#include <cstdio>

#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

// Every camera group in use has an EXIF / certificate focal length.
bool FocalPriorsForAll(const SparseModel& model, const BundleOptions& bundle) {
  const std::vector<char> used = CamerasInUse(model);
  bool priors = true;
  for (size_t c = 0; c < used.size(); ++c) {
    if (used[c]) priors &= c < bundle.focal_prior_px.size() && bundle.focal_prior_px[c] > 0.0;
  }
  return priors;
}

// Whether the last solve refined camera group c's focal length.
bool FocalRefined(const BundleSummary& summary, const SparseModel& model, size_t c) {
  if (c >= summary.refined_params.size()) return true;  // not recorded: as asked
  const int f = model.cameras[c].info().focal_params.at(0);
  const std::vector<int>& refined = summary.refined_params[c];
  return std::find(refined.begin(), refined.end(), f) != refined.end();
}

// The focal lengths the block does not determine (sigma f beyond
// weak_focal_rel of f), by camera group, and whether each has a prior to
// hold it at. Without a covariance the geometry decides: nadir photos of
// flat ground at one altitude cannot determine f.
struct WeakFocal {
  std::vector<std::string> cameras;
  std::string detail;
  bool all_have_priors = true;
};

WeakFocal FindWeakFocal(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  const SparseModel& model = *s->model;
  const BundleOptions& bundle = s->bundle;
  WeakFocal weak;
  for (const IntrinsicsPrecision& p : report.bundle.intrinsics_precision) {
    const Camera& camera = model.cameras[p.camera];
    const std::string f_name = camera.info().param_names[camera.info().focal_params.at(0)];
    const auto it = std::find(p.names.begin(), p.names.end(), f_name);
    if (it == p.names.end()) continue;
    const size_t k = static_cast<size_t>(it - p.names.begin());
    const double rel = p.sigmas[k] / p.values[k];
    if (rel <= s->Options().weak_focal_rel) continue;
    weak.cameras.push_back("camera " + std::to_string(camera.id));
    char text[160];
    std::snprintf(text, sizeof text, "sigma f %.2f %% of f, correlation with the camera heights %.2f (median)",
                  100.0 * rel, p.focal_height_correlation_median);
    weak.detail = text;
    weak.all_have_priors &= static_cast<size_t>(p.camera) < bundle.focal_prior_px.size() &&
                            bundle.focal_prior_px[p.camera] > 0.0;
  }
  // No covariance (report.bundle.covariance_note says why): whether the
  // block determines f is not measured, and its geometry decides.
  if (s->Options().auto_refine && !s->focal_held_flat && report.bundle.intrinsics_precision.empty() &&
      !report.bundle.covariance_note.empty()) {
    if (report.geometry.nadir_flat_single_altitude) {
      const std::vector<char> used = CamerasInUse(model);
      for (size_t c = 0; c < used.size(); ++c) {
        if (!used[c] || !FocalRefined(report.bundle, model, c)) continue;  // held (a certificate): not weak
        weak.cameras.push_back("camera " + std::to_string(model.cameras[c].id));
        weak.all_have_priors &= c < bundle.focal_prior_px.size() && bundle.focal_prior_px[c] > 0.0;
      }
      weak.detail = "its precision could not be computed: " + report.bundle.covariance_note;
    } else {
      report.refinement_reason += " (their precision could not be computed: " + report.bundle.covariance_note +
                                  "; the block is not nadir photos of flat ground at one altitude)";
    }
  }
  return weak;
}

// Every group's focal length set to its prior and held; the rest refined.
void HoldFocalAtPriors(SparseModel* model, BundleOptions* bundle) {
  for (size_t c = 0; c < model->cameras.size() && c < bundle->focal_prior_px.size(); ++c) {
    if (bundle->focal_prior_px[c] > 0.0) {
      model->cameras[c].params[model->cameras[c].info().focal_params.at(0)] = bundle->focal_prior_px[c];
    }
  }
  bundle->refine_intrinsics = IntrinsicsRefinement::kList;
  bundle->refine_params = {"cx", "cy", "k1", "k2", "k3", "p1", "p2"};
}

}  // namespace

// The block's geometry (reported); what is refined is decided from the
// intrinsics' precision after the adjustment (HoldWeakFocal), except on
// nadir photos of flat ground at one altitude without control heights:
// there f and the flying height are one unknown, which only the GPS heights'
// metres hold, and a covariance sigma under 1 % is no guarantee (0.94 % let
// f land 2.3 % off on a rendered crop-row field). Held at its EXIF /
// certificate value from the outset; the rest refined.
void ChooseRefinement(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  GeoreferenceReport& report = s->report;
  report.geometry = MeasureBlockGeometry(*s->model);
  report.refinement_auto = options.auto_refine;
  s->bundle = options.bundle;
  s->bundle.estimate_readout = options.model_rolling_shutter && options.estimate_readout;
  if (options.auto_refine) s->bundle.refine_intrinsics = IntrinsicsRefinement::kAll;
  if (!options.auto_refine || !report.geometry.nadir_flat_single_altitude) return;
  bool control_heights = false;
  for (const SurveyedPoint& p : s->surveyed) {
    control_heights |= p.role == PointRole::kControl && p.excluded.empty() && !p.source->horizontal_only;
  }
  if (control_heights || !FocalPriorsForAll(*s->model, s->bundle)) return;
  const std::vector<char> used = CamerasInUse(*s->model);
  for (size_t c = 0; c < used.size(); ++c) {
    if (used[c]) {
      s->model->cameras[c].params[s->model->cameras[c].info().focal_params.at(0)] = s->bundle.focal_prior_px[c];
    }
  }
  s->bundle.refine_intrinsics = IntrinsicsRefinement::kList;
  s->bundle.refine_params = {"cx", "cy", "k1", "k2", "k3", "p1", "p2"};
  s->focal_held_flat = true;
}

bool ControlSigmasStated(const SurveyState& s) {
  int control = 0;
  for (const SurveyedPoint& p : s.surveyed) {
    if (p.role != PointRole::kControl || !p.excluded.empty()) continue;
    ++control;
    if (!p.source->sigma_h_m && !p.source->sigma_v_m && !p.source->sigma_xyz_m) return false;
  }
  return control > 0;
}

// Ties and marks: stated when every measurement of the group carries its
// sigma_px. Control: stated in its file, and not contradicted by its scatter
// (then its variance component is estimated where the block can judge it),
// or kept as asked. GPS sigmas are the receiver's or the defaults, never
// the survey's statement: estimated.
void HoldStatedSigmas(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  auto& hold = s->bundle.hold_stated_sigmas;
  hold.fill(false);
  const bool kept = options.keep_stated_control_sigmas;
  hold[static_cast<int>(ObservationGroup::kControl)] = kept;
  if (!options.hold_stated_sigmas) return;
  const SparseModel& model = *s->model;
  bool ties = true, marks = true;
  int num_ties = 0, num_marks = 0;
  for (const Observation& obs : model.observations) {
    if (!model.images[obs.image].registered) continue;
    const bool mark = model.points[obs.point].role != PointRole::kTie;
    (mark ? num_marks : num_ties) += 1;
    (mark ? marks : ties) &= obs.sigma_px > 0.0;
  }
  hold[static_cast<int>(ObservationGroup::kTies)] = ties && num_ties > 0;
  hold[static_cast<int>(ObservationGroup::kMarks)] = marks && num_marks > 0;
  hold[static_cast<int>(ObservationGroup::kControl)] =
      kept || (ControlSigmasStated(*s) && !s->report.control_precision.deferred);
}

void AdjustBlock(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  HoldStatedSigmas(s);
  s->bundle.compute_intrinsics_covariance = true;
  s->bundle.compute_precision = s->Options().posterior_precision;
  WithholdControl(s);
  s->before_final = *s->model;
  report.bundle = AdjustBundle(s->model, s->bundle);
  report.refined = report.bundle.refined_intrinsics;
  report.refinement_reason = s->Options().auto_refine ? "every intrinsic refined: the block determines them"
                                                      : "as asked (--refine)";
  if (s->focal_held_flat) {
    report.refinement_reason =
        "focal length held at its EXIF / certificate value: nadir photos of flat ground at one altitude (depths "
        "within " + FormatPercent(report.geometry.roughness_ratio) + " of a plane in each photo) and no control "
        "heights, so f and the flying height are one unknown; the rest refined";
    report.findings.push_back(Finding::Warning("FOCAL_HELD", report.refinement_reason));
  }
}

// The readout times the adjustment estimated, into the shutters' report.
void ReportReadouts(SurveyState* s) {
  for (const BundleSummary::Readout& r : s->report.bundle.readouts) {
    if (r.camera < 0 || r.camera >= static_cast<int>(s->report.shutters.size())) continue;
    GeoreferenceReport::Shutter& shutter = s->report.shutters[r.camera];
    if (!shutter.readout_estimated) continue;
    shutter.readout_time_s = r.readout_time_s;
    shutter.readout_sigma_s = r.sigma_s;
    shutter.source = "readout estimated in the adjustment (" +
                     (shutter.readout_stated_s > 0.0 ? "the photos state " + FormatMilliseconds(shutter.readout_stated_s)
                                                     : std::string("the photos state none")) +
                     "); velocities from " + shutter.source;
  }
}

void HoldWeakFocal(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  const WeakFocal weak = FindWeakFocal(s);
  const std::string flat = report.geometry.nadir_flat_single_altitude
                               ? " (nadir photos of flat ground at one altitude: f and the flying height are one "
                                 "unknown)"
                               : "";
  if (!weak.cameras.empty() && s->Options().auto_refine && weak.all_have_priors) {
    // Hold f at the prior of every group and solve again from the same start.
    *s->model = *s->before_final;
    HoldFocalAtPriors(s->model, &s->bundle);
    report.bundle = AdjustBundle(s->model, s->bundle);
    report.refined = report.bundle.refined_intrinsics;
    report.refinement_reason = "focal length held at its EXIF / certificate value: the block does not determine "
                               "it (" + weak.detail + ")" + flat + "; the rest refined";
    report.findings.push_back(Finding::Warning("FOCAL_HELD", report.refinement_reason, weak.cameras));
  } else if (!weak.cameras.empty()) {
    report.refinement_reason += "; the focal length is weakly determined (" + weak.detail + ")" + flat;
    report.findings.push_back(Finding::Warning(
        "FOCAL_WEAKLY_DETERMINED",
        "the focal length is refined but the block does not determine it (" + weak.detail + ")" + flat +
            (s->Options().auto_refine ? "; no EXIF or certificate focal length to hold it at"
                                      : "; --refine auto holds it at its EXIF value") +
            ": camera heights and the DSM's scale follow it",
        weak.cameras));
  }
  report.bundle.outliers_removed += s->outliers_before_final;
  for (Finding& f : IntrinsicsCorrelationFindings(report.bundle.intrinsics_precision)) {
    report.findings.push_back(std::move(f));
  }
}

}  // namespace aerotri
