// SPDX-License-Identifier: BSD-3-Clause
// Camera positions: the GPS CSV and OpenDroneMap's geo.txt (one reader tells
// them apart by the first line). CRS resolution goes through a fixed table of
// CRSs made once (PROJ's own parser is PROJ's to fuzz): through PROJ, every
// new first line meant a database name lookup and the target ran at ~6
// inputs/s; now the tokenising, number checks and conversions run at speed.
#include <map>
#include <string>

#include "libphoto/ingest/gps_sources.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::map<std::string, aerotri::Crs> table = {
      {"EPSG:4326", aerotri::Crs::FromString("EPSG:4326")},
      {"EPSG:32632", aerotri::Crs::FromString("EPSG:32632")},
      {"WGS84 UTM 32N", aerotri::Crs::FromString("WGS84 UTM 32N")},
      {"EPSG:4978", aerotri::Crs::FromString("EPSG:4978")},
      {"LOCAL", aerotri::Crs::FromString("LOCAL")}};
  const aerotri::CrsResolver resolve = [](const std::string& line) -> std::optional<aerotri::Crs> {
    const auto it = table.find(line);
    if (it == table.end()) return std::nullopt;
    return it->second;
  };
  const std::string text(reinterpret_cast<const char*>(data), size);
  aerotri::fuzz::ExpectOnlyCleanErrors([&] {
    aerotri::ParseGpsText(text, "gps.txt", aerotri::AltitudeReference::kEllipsoid, 3.0, 5.0, resolve);
  });
  return 0;
}
