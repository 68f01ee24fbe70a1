// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What a subcommand needs from its surroundings: where data goes (stdout),
// where progress goes (stderr, silenced by --quiet), and the process clock.
// Commands are library functions `int RunX(const XArgs&, ToolContext&)` so
// tests can call them in-process with string streams.

#include <chrono>
#include <iostream>
#include <string>
#include <vector>

#include "libphoto/base/progress.h"

namespace aerotri {

struct ToolContext {
  std::ostream* out = &std::cout;  // data
  std::ostream* err = &std::cerr;  // progress and messages
  bool quiet = false;
  std::vector<std::string> command_line;  // argv, recorded in report.json
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();

  // One line of progress on stderr unless quiet.
  void Info(const std::string& line) const;
  // A warning is shown even with --quiet.
  void Warn(const std::string& line) const;
  // An error line ("error: ..."), shown even with --quiet.
  void Error(const std::string& line) const;
  // A progress callback for a named stage: draws "stage: 42% message".
  ProgressCallback Progress(const std::string& stage) const;
  double ElapsedS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
};

// The version line: aerotri and every dependency's version.
std::string VersionString();

}  // namespace aerotri
