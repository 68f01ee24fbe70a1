// SPDX-License-Identifier: BSD-3-Clause
// Writes a LAS 1.4 and a PLY of known points (EPSG:32632) and the expected
// values as JSON, for the independent reader check (tests/las/check_las.mjs),
// and the same cloud as LAZ (tests/las/check_laz.mjs).
//   las_fixture OUT.las OUT.ply EXPECTED.json [OUT.laz]
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "georef/crs.h"
#include "libphoto/export/point_cloud.h"

int main(int argc, char** argv) {
  if (argc != 4 && argc != 5) return 2;
  aerotri::CrsCloud cloud;
  const aerotri::Crs crs = aerotri::Crs::FromString("EPSG:32632");
  cloud.crs_wkt = crs.WktV1();
  cloud.crs_name = crs.Name();
  nlohmann::json expected;
  expected["points"] = nlohmann::json::array();
  for (int i = 0; i < 1000; ++i) {
    const double x = 384900.0 + 0.0123 * i, y = 5150700.0 - 0.0071 * i, z = 500.0 + 0.001 * (i % 97);
    cloud.xyz.emplace_back(x, y, z);
    cloud.rgb.push_back({static_cast<std::uint8_t>(i % 256), static_cast<std::uint8_t>((3 * i) % 256),
                         static_cast<std::uint8_t>(255 - i % 256)});
    // ASPRS classes as the dense stage writes them: 1, 2, 7, 18.
    const std::uint8_t classes[4] = {1, 2, 7, 18};
    cloud.classes.push_back(classes[i % 4]);
    if (i % 111 == 0) expected["points"].push_back({{"index", i}, {"x", x}, {"y", y}, {"z", z},
                                                    {"r", i % 256}, {"g", (3 * i) % 256}, {"b", 255 - i % 256},
                                                    {"class", std::vector<int>{1, 2, 7, 18}[i % 4]}});
  }
  expected["count"] = 1000;
  expected["min"] = {384900.0, 5150700.0 - 0.0071 * 999, 500.0};
  expected["max"] = {384900.0 + 0.0123 * 999, 5150700.0, 500.096};
  aerotri::WriteLas(cloud, argv[1]);
  aerotri::WritePly(cloud, argv[2]);
  if (argc == 5) aerotri::WriteLas(cloud, argv[4]);
  std::ofstream(argv[3]) << expected.dump(2);
  return 0;
}
