// SPDX-License-Identifier: BSD-3-Clause
// OpenDroneMap gcp_list.txt / check-point files, both pixel conventions. The
// CRS line is only tokenised here (ReadGcpFile); CRS resolution is PROJ's.
#include "georef/gcp_file.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = aerotri::fuzz::WriteInput("gcp_list.txt", data, size);
  for (aerotri::PixelOrigin origin : {aerotri::PixelOrigin::kCentre, aerotri::PixelOrigin::kCorner}) {
    aerotri::fuzz::ExpectOnlyCleanErrors([&] { aerotri::ReadGcpFile(path, origin); });
  }
  return 0;
}
