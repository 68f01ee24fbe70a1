// SPDX-License-Identifier: BSD-3-Clause
// Leave-one-out from the survey's optimum against N separate adjustments,
// side by side in one run (the machine is noisy: ratios, not seconds).
//
// Usage: loo_bench MODEL_DIR GPS_CSV GCP_FILE [CHECKS_FILE]
//   e.g. (S=sample_surveys/synthetic_meadow)
//        build/bench/loo_bench $S/model $S/gps.csv $S/gcp_list.txt $S/checkpoints.txt
//
// Prints the adjustment's time without and with leave-one-out (the
// block-deletion update at the survey's optimum, out of its own precision
// pass), that of N cold adjustments each without one control point (every
// phase, from the model as given), and the largest difference between the
// two tables per point and axis.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

#include "georef/gcp_file.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/survey/georeferencing.h"

using namespace aerotri;  // NOLINT: a benchmark's main

namespace {
double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: loo_bench MODEL_DIR GPS_CSV GCP_FILE [CHECKS_FILE]\n");
    return 2;
  }
  const SparseModel start = ReadColmapText(argv[1]);
  const auto gps = ReadGpsFile(argv[2], AltitudeReference::kEgm96, 3.0, 5.0);
  const GcpFile control = ReadGcpFile(argv[3]);
  std::optional<GcpFile> checks;
  if (argc > 4) checks = ReadGcpFile(argv[4]);
  GeoreferenceOptions options;
  options.bundle.estimate_variance_components = true;  // the command line's default (auto)

  options.leave_one_out = false;
  SparseModel once = start;
  auto t = std::chrono::steady_clock::now();
  GeoreferenceAndAdjust(&once, gps, &control, checks ? &*checks : nullptr, options);
  const double t_adjust = Seconds(t);

  // Leave-one-out's cost: the whole run with it, less the run without (the
  // updates come out of the adjustment's own precision pass, so its phase
  // alone would hide them).
  options.leave_one_out = true;
  SparseModel with = start;
  t = std::chrono::steady_clock::now();
  const GeoreferenceReport warm = GeoreferenceAndAdjust(&with, gps, &control, checks ? &*checks : nullptr, options);
  const double t_warm = std::max(Seconds(t) - t_adjust, 1e-3);

  options.leave_one_out = false;
  double t_cold = 0.0, max_diff = 0.0;
  std::string worst;
  for (size_t k = 0; k < control.points.size(); ++k) {
    GcpFile without = control, alone = control;
    without.points.erase(without.points.begin() + static_cast<long>(k));
    alone.points = {control.points[k]};
    SparseModel copy = start;
    t = std::chrono::steady_clock::now();
    const GeoreferenceReport cold = GeoreferenceAndAdjust(&copy, gps, &without, &alone, options);
    t_cold += Seconds(t);
    const GroundPointResult& a = warm.leave_one_out.points.at(k);
    const GroundPointResult& b = cold.check.at(0);
    if (!a.solved || !b.solved) continue;
    const double diff = (a.d_m - b.d_m).cwiseAbs().maxCoeff();
    if (diff > max_diff) max_diff = diff, worst = a.name;
  }
  std::printf("control points: %zu\n", control.points.size());
  std::printf("adjustment without leave-one-out: %.2f s; with it: %.2f s\n", t_adjust, t_adjust + t_warm);
  std::printf("leave-one-out, updated at the optimum: adds %.2f s (%.2f of one adjustment; below 0.01 s: within the "
              "runs' noise); %d of %zu points updated, %d solve(s) of its own\n",
              t_warm, t_warm / t_adjust, warm.leave_one_out.updated, control.points.size(),
              warm.leave_one_out.adjustments);
  std::printf("leave-one-out, %zu separate adjustments: %.2f s (%.1f adjustments' time)\n", control.points.size(),
              t_cold, t_cold / t_adjust);
  std::printf("largest difference of the tables: %.3f mm (%s)\n", 1000.0 * max_diff, worst.c_str());
  return 0;
}
