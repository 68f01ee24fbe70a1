// SPDX-License-Identifier: BSD-3-Clause
// Leave-one-out over the control points (survey_phases.h LeaveControlOut).
#include <chrono>

#include "libphoto/survey/survey_phases.h"

namespace aerotri {

// Each control point withheld in turn: the block adjusted again from the
// survey's start without it, at the weights the survey's own adjustment
// arrived at, and the point triangulated as an independent check.
void LeaveControlOut(SurveyState* s) {
  const GeoreferenceOptions& options = s->Options();
  if (!options.leave_one_out) return;
  LeaveOneOut& loo = s->report.leave_one_out;
  const auto loo_start = std::chrono::steady_clock::now();
  const GcpFile* control = s->control;
  const int n = control ? static_cast<int>(control->points.size()) : 0;
  if (n < 4) {
    loo.note = "needs 4 or more control points (have " + std::to_string(n) + "): 3 must hold the datum";
  } else {
    GeoreferenceOptions once = options;
    once.leave_one_out = false;
    once.progress = nullptr;
    once.posterior_precision = false;
    for (const VarianceComponent& vc : s->report.bundle.variance_components) {
      once.bundle.sigma_scale[static_cast<int>(vc.group)] = vc.scale;
    }
    once.bundle.estimate_variance_components = false;
    std::vector<Eigen::Vector3d> d;
    for (int k = 0; k < n; ++k) {
      ReportProgress(options.progress, 0.9 + 0.1 * k / n, "leave-one-out: without " + control->points[k].name);
      GcpFile without = *control;
      without.points.erase(without.points.begin() + k);
      GcpFile alone = *control;
      alone.points = {control->points[k]};
      SparseModel copy = *s->start;
      const GeoreferenceReport r = GeoreferenceAndAdjust(&copy, s->gps, &without, &alone, once);
      GroundPointResult p = r.check.at(0);
      p.role = PointRole::kControl;
      if (p.solved) d.push_back(p.d_m);
      loo.points.push_back(p);
      ++loo.adjustments;
    }
    loo.stats = AccuracyStats::FromResiduals(d);
    loo.computed = true;
  }
  loo.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loo_start).count();
}

}  // namespace aerotri
