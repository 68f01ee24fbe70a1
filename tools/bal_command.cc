// SPDX-License-Identifier: BSD-3-Clause
// aerotri bal: solve a BAL benchmark problem with the bundle adjuster.
#include <cstdio>
#include <memory>
#include <sstream>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/base/error.h"
#include "libphoto/io/bal.h"
#include "tools/commands.h"

namespace aerotri {

void RegisterBalCommand(CLI::App& app, CommandAction* run) {
  auto args = std::make_shared<BalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bal", "Solve a 'Bundle Adjustment in the Large' problem (plain or .bz2) and print "
             "per-iteration cost (stderr) and a summary (stdout)");
  cmd->add_option("problem", args->problem, "BAL problem file (text, optionally bzip2)")
      ->required();
  cmd->add_option("--output,-o", args->output, "Write the solved problem here (BAL text)");
  cmd->add_option("--loss", args->loss, "Robust loss on reprojection residuals")
      ->check(CLI::IsMember({"none", "huber", "cauchy", "tukey"}))
      ->capture_default_str();
  cmd->add_option("--loss-scale", args->loss_scale_px, "Robust loss scale (pixels)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--solver", args->solver,
                  "Linear solver; auto picks dense/sparse/iterative Schur by problem size")
      ->check(CLI::IsMember({"auto", "dense_schur", "sparse_schur", "iterative_schur"}))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Threads (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations,
                  "Maximum Levenberg-Marquardt iterations")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--refine", args->refine,
                  "Intrinsics to refine: none, focal, all, or a list such as f,k1")
      ->capture_default_str();
  cmd->add_option("--outlier-threshold", args->outlier_threshold_px,
                  "After convergence reject observations with reprojection error above "
                  "this (pixels) and solve again; 0 = off")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--optimality-gap", args->optimality_gap,
                  "Stop once the cost is estimated within this fraction of the optimum (from the last "
                  "accepted decreases: the last one and its geometric extrapolation); 0 = off")
      ->check(CLI::Range(0.0, 0.999))
      ->capture_default_str();
  cmd->add_option("--function-tolerance", args->function_tolerance,
                  "Stop when one step's relative cost decrease falls below this")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--gradient-tolerance", args->gradient_tolerance,
                  "Stop when the largest gradient component falls below this")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--parameter-tolerance", args->parameter_tolerance,
                  "Stop when the step is below this, relative to the parameters")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--engine", args->engine,
                  "Who solves: aerotri (its own dense-Schur Levenberg-Marquardt, for problems whose "
                  "camera system fits in memory dense), ceres, or auto (aerotri where it applies)")
      ->check(CLI::IsMember({"auto", "aerotri", "ceres"}))
      ->capture_default_str();
  cmd->add_flag("--diagnostics", args->diagnostics,
                "After the solve, count observations behind their camera and weak images and points");
  cmd->add_flag("--solver-report", args->solver_report,
                "Print Ceres' full solver report (timings per phase) on stderr");
  *run = nullptr;
  cmd->callback([args, run]() {
    *run = [args](ToolContext& ctx) { return RunBal(*args, ctx); };
  });
}

int RunBal(const BalArgs& args, ToolContext& ctx) {
  BundleOptions options;
  ApplyAdjustmentOptions(args.loss, args.loss_scale_px, args.refine, &options);
  const auto solver = ParseLinearSolver(args.solver);
  if (!solver) throw InvalidArgument("--solver: unknown solver '" + args.solver + "'");
  options.linear_solver = *solver;
  options.num_threads = args.threads;
  options.max_iterations = args.max_iterations;
  options.outlier_threshold_px = args.outlier_threshold_px;
  options.function_tolerance = args.function_tolerance;
  options.gradient_tolerance = args.gradient_tolerance;
  options.parameter_tolerance = args.parameter_tolerance;
  options.optimality_gap = args.optimality_gap;
  options.engine = *ParseBundleEngine(args.engine);
  options.compute_diagnostics = args.diagnostics;
  options.keep_solver_report = args.solver_report;
  if (!ctx.quiet) {
    std::ostream* err = ctx.err;
    options.iteration_callback = [err](const IterationReport& it) {
      char line[128];
      std::snprintf(line, sizeof(line), "%s iter %3d  cost %.6e  time %.3f s\n",
                    it.round > 0 ? "  re-solve" : "", it.iteration, it.cost, it.time_s);
      *err << line << std::flush;
    };
  }

  SparseModel model = ReadBalProblem(args.problem);
  ctx.Info("read " + args.problem + ": " + std::to_string(model.images.size()) +
           " cameras, " + std::to_string(model.points.size()) + " points, " +
           std::to_string(model.observations.size()) + " observations (" +
           std::to_string(ctx.ElapsedS()).substr(0, 5) + " s)");

  if (model.images.size() < 2) {
    throw InvalidArgument(args.problem + ": nothing to adjust: " + std::to_string(model.images.size()) +
                          " camera (a bundle adjustment needs at least 2 cameras seeing common points)");
  }
  const BundleSummary summary = AdjustBundle(&model, options);
  if (args.solver_report) *ctx.err << summary.solver_report << std::flush;
  if (!args.output.empty()) {
    WriteBalProblem(model, args.output);
    ctx.Info("wrote " + args.output);
  }

  std::ostream& out = *ctx.out;
  out << summary.BriefReport() << "\n";
  char last[256];
  std::snprintf(last, sizeof(last),
                "initial_cost=%.6e final_cost=%.6e rms_px=%.4f iterations=%d time_s=%.3f\n",
                summary.initial_cost, summary.final_cost, summary.final_rms_px,
                summary.iterations, ctx.ElapsedS());
  out << last << std::flush;
  if (summary.termination.rfind("FAILURE", 0) == 0) {
    throw InvalidArgument(args.problem + ": the solver failed: " + summary.termination);
  }
  return 0;
}

}  // namespace aerotri
