// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What a subcommand needs from its surroundings: where data goes (stdout),
// where progress goes (stderr, silenced by --quiet), and the process clock.
// Commands are library functions `int RunX(const XArgs&, ToolContext&)` so
// tests can call them in-process with string streams.

#include <chrono>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "libphoto/base/progress.h"

namespace aerotri {

struct ToolContext {
  std::ostream* out = &std::cout;  // data
  std::ostream* err = &std::cerr;  // progress and messages
  bool quiet = false;
  // Progress lines are rewritten in place (carriage return) when stderr is
  // a terminal; in a pipe or file each update is a line of its own.
  bool rewrite_progress = false;
  std::vector<std::string> command_line;  // argv, recorded in report.json
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();

  // One line of progress on stderr unless quiet.
  void Info(const std::string& line) const;
  // A warning is shown even with --quiet.
  void Warn(const std::string& line) const;
  // An error line ("error: ..."), shown even with --quiet.
  void Error(const std::string& line) const;
  // A progress callback for a named stage: draws
  // "stage: 42% message [elapsed 1:05, ETA 1:30]", the ETA extrapolated from
  // the stage's elapsed time and fraction done.
  ProgressCallback Progress(const std::string& stage) const;
  double ElapsedS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  // Ends a progress line left open on a terminal (no newline yet); every
  // message does this first.
  void CloseLine() const;

 private:
  std::shared_ptr<bool> open_line_ = std::make_shared<bool>(false);
};

// "stage: 42% message [elapsed 1:05, ETA 1:30]"; fraction < 0: no percentage
// and no ETA. The ETA appears once 2 % is done: elapsed (1 − f) / f.
std::string FormatProgressLine(const std::string& stage, double fraction, const std::string& message,
                               double elapsed_s);
// Seconds as "42 s", "3:07" or "1:02:03".
std::string FormatDuration(double seconds);

// The version line: aerotri and every dependency's version.
std::string VersionString();

}  // namespace aerotri
