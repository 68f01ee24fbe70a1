// SPDX-License-Identifier: BSD-3-Clause
// Camera positions: the GPS CSV and OpenDroneMap's geo.txt (one reader tells
// them apart by the first line).
#include "libphoto/ingest/gps_sources.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = aerotri::fuzz::WriteInput("gps.txt", data, size);
  aerotri::fuzz::ExpectOnlyCleanErrors(
      [&] { aerotri::ReadGpsFile(path, aerotri::AltitudeReference::kEllipsoid, 3.0, 5.0); });
  return 0;
}
