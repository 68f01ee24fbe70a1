// SPDX-License-Identifier: BSD-3-Clause
#include "tools/tool_context.h"

#include <cstdio>
#include <sstream>

#include "libphoto/base/error.h"
#include "tools/commands.h"

namespace aerotri {

void ToolContext::Info(const std::string& line) const {
  if (!quiet) *err << line << "\n" << std::flush;
}

void ToolContext::Warn(const std::string& line) const {
  *err << "warning: " << line << "\n" << std::flush;
}

void ToolContext::Error(const std::string& line) const {
  *err << "error: " << line << "\n" << std::flush;
}

ProgressCallback ToolContext::Progress(const std::string& stage) const {
  if (quiet) return nullptr;
  std::ostream* stream = err;
  return [stream, stage](double fraction, const std::string& message) {
    if (fraction >= 0.0) {
      char pct[16];
      std::snprintf(pct, sizeof(pct), "%3.0f%%", 100.0 * fraction);
      *stream << stage << ": " << pct << " " << message << "\n" << std::flush;
    } else {
      *stream << stage << ": " << message << "\n" << std::flush;
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
