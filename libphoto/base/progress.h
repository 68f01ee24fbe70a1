// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Progress reporting, GDAL-style: the library never prints; long work calls a
// ProgressCallback that the command line draws on stderr (and --quiet drops).

#include <functional>
#include <string>

namespace aerotri {

// fraction in [0, 1] of the current stage, or a negative value when the stage
// cannot estimate it; message is one human-readable line without a newline.
// Returning false asks the caller to stop early (it then reports so).
using ProgressCallback =
    std::function<bool(double fraction, const std::string& message)>;

// Calls progress when it is set; returns true (continue) when it is not.
inline bool ReportProgress(const ProgressCallback& progress, double fraction,
                           const std::string& message) {
  return progress ? progress(fraction, message) : true;
}

// A part [begin, end] of a stage's progress: the stage's work in phases
// (pairs, then fusion, then products) reads 0 to 1 once, not once a phase.
inline ProgressCallback ProgressPart(const ProgressCallback& progress, double begin, double end) {
  if (!progress) return progress;
  return [progress, begin, end](double fraction, const std::string& message) {
    return progress(fraction < 0 ? fraction : begin + (end - begin) * fraction, message);
  };
}

}  // namespace aerotri
