// SPDX-License-Identifier: BSD-3-Clause
#include "tools/tool_context.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "libphoto/base/error.h"
#include "tools/commands.h"

namespace aerotri {

void ToolContext::CloseLine() const {
  if (*open_line_) {
    *err << "\n";
    *open_line_ = false;
  }
}

void ToolContext::Info(const std::string& line) const {
  if (quiet) return;
  CloseLine();
  *err << line << "\n" << std::flush;
}

void ToolContext::Warn(const std::string& line) const {
  CloseLine();
  *err << "warning: " << line << "\n" << std::flush;
}

void ToolContext::Error(const std::string& line) const {
  CloseLine();
  *err << "error: " << line << "\n" << std::flush;
}

std::string FormatDuration(double seconds) {
  const long s = std::lround(std::max(0.0, seconds));
  char buf[32];
  if (s < 60) {
    std::snprintf(buf, sizeof(buf), "%ld s", s);
  } else if (s < 3600) {
    std::snprintf(buf, sizeof(buf), "%ld:%02ld", s / 60, s % 60);
  } else {
    std::snprintf(buf, sizeof(buf), "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  }
  return buf;
}

std::string FormatProgressLine(const std::string& stage, double fraction, const std::string& message,
                               double elapsed_s) {
  std::string line = stage + ": ";
  if (fraction >= 0.0) {
    char pct[16];
    std::snprintf(pct, sizeof(pct), "%3.0f%% ", 100.0 * std::min(1.0, fraction));
    line += pct;
  }
  line += message + " [elapsed " + FormatDuration(elapsed_s);
  if (fraction >= 0.02 && fraction < 1.0) line += ", ETA " + FormatDuration(elapsed_s * (1.0 - fraction) / fraction);
  return line + "]";
}

ProgressCallback ToolContext::Progress(const std::string& stage) const {
  if (quiet) return nullptr;
  std::ostream* stream = err;
  const auto stage_start = std::chrono::steady_clock::now();
  const bool rewrite = rewrite_progress;
  std::shared_ptr<bool> open = open_line_;
  return [stream, stage, stage_start, rewrite, open](double fraction, const std::string& message) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start).count();
    const std::string line = FormatProgressLine(stage, fraction, message, elapsed);
    if (rewrite) {
      // Carriage return and erase-line: the update replaces the last one.
      *stream << "\r\033[K" << line;
      *open = fraction >= 0.0 && fraction < 1.0;
      if (!*open) *stream << "\n";
      *stream << std::flush;
    } else {
      *stream << line << "\n" << std::flush;
    }
    return true;
  };
}

void ApplyAdjustmentOptions(const std::string& loss, double loss_scale_px, const std::string& refine,
                            BundleOptions* options) {
  const auto parsed_loss = ParseLossType(loss);
  if (!parsed_loss) throw InvalidArgument("--loss: unknown loss '" + loss + "'");
  options->loss = *parsed_loss;
  options->loss_scale_px = loss_scale_px;
  ApplyRefineOption(refine, options);
}

void ApplyRefineOption(const std::string& refine, BundleOptions* options) {
  const auto parsed_refine = ParseIntrinsicsRefinement(refine, &options->refine_params);
  if (!parsed_refine) {
    throw InvalidArgument("--refine: expected none, focal, focal,pp, all or a list of f, cx, cy, k1, k2, k3, "
                          "p1, p2; got '" + refine + "'");
  }
  options->refine_intrinsics = *parsed_refine;
}

}  // namespace aerotri
