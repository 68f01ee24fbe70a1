// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Shared by the fuzz targets: the parsers read files by path, so each input
// is written to a file in a per-process folder on /dev/shm (memory, fast),
// and the errors a parser is allowed to throw for bad input (aerotri::Error:
// ParseError, IoError, InvalidArgument, CrsError) are caught; anything else
// -- a crash, a sanitizer report, std::bad_alloc, another exception --
// reaches libFuzzer as a finding.

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "libphoto/base/error.h"

namespace aerotri::fuzz {

inline std::filesystem::path WorkDir() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path base = std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
    std::filesystem::path d = base / ("aerotri_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

inline std::filesystem::path WriteInput(const std::string& name, const uint8_t* data, size_t size) {
  const std::filesystem::path path = WorkDir() / name;
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(data),
                                                                 static_cast<std::streamsize>(size));
  return path;
}

// Runs parse(); the project's own errors are the expected outcome of bad input.
template <typename Fn>
void ExpectOnlyCleanErrors(Fn&& parse) {
  try {
    parse();
  } catch (const aerotri::Error&) {
  }
}

}  // namespace aerotri::fuzz
