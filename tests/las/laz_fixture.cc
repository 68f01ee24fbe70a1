// SPDX-License-Identifier: BSD-3-Clause
// The same cloud as LAS and as LAZ, for the independent decoder's check
// (tests/las/check_laz.mjs: laz-perf must decode the LAZ to the LAS's bytes).
//   laz_fixture OUT N lidar   records with every field in use (tests/las/laz_records.h)
//   laz_fixture OUT N terrain aerotri's own records of a rendered terrain (N up to billions)
// Writes OUT.las and OUT.laz; with terrain, OUT.copc.laz too (the same
// points as COPC, tests/las/check_copc.mjs).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>

#include "libphoto/export/copc.h"
#include "libphoto/export/point_cloud.h"
#include "tests/las/laz_records.h"

namespace {

void WriteLidar(const std::string& out, std::uint32_t n) {
  const std::vector<std::uint8_t> records = aerotri::test::LidarLikeRecords(n, 17);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (std::uint32_t i = 0; i < n; ++i) {
    std::int32_t xyz[3];
    std::memcpy(xyz, &records[36 * i], 12);
    const Eigen::Vector3d p(xyz[0] * 0.001, xyz[1] * 0.001, xyz[2] * 0.001);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  for (const char* ext : {".las", ".laz"}) {
    aerotri::LasWriter writer(out + ext, n, lo, hi, "LOCAL_CS[\"laz fixture\"]");
    const Eigen::Vector3d shift = (writer.offset() / 0.001).array().round();
    for (std::uint32_t i = 0; i < n; ++i) {
      std::uint8_t r[36];
      std::memcpy(r, &records[36 * i], 36);
      std::int32_t xyz[3];
      std::memcpy(xyz, r, 12);
      for (int k = 0; k < 3; ++k) xyz[k] -= static_cast<std::int32_t>(shift[k]);
      std::memcpy(r, xyz, 12);
      writer.AddRecord(r);
    }
    writer.Commit();
  }
}

// Rolling ground with colour and ground classes, row by row in tiles of
// 500 x 500 points, as the dense stage writes its tiles.
void WriteTerrain(const std::string& out, std::uint64_t n) {
  const std::uint64_t side = static_cast<std::uint64_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  const Eigen::Vector3d lo(600000.0, 5000000.0, 80.0);
  const Eigen::Vector3d hi = lo + Eigen::Vector3d(0.05 * side, 0.05 * side, 60.0);
  for (const char* ext : {".las", ".laz", ".copc.laz"}) {
    std::optional<aerotri::LasWriter> las;
    std::optional<aerotri::CopcWriter> copc;
    if (std::string(ext) == ".copc.laz") {
      copc.emplace(out + ext, n, lo, hi, "LOCAL_CS[\"laz fixture\"]");
    } else {
      las.emplace(out + ext, n, lo, hi, "LOCAL_CS[\"laz fixture\"]");
    }
    std::uint64_t written = 0;
    for (std::uint64_t ty = 0; ty < side && written < n; ty += 500) {
      for (std::uint64_t tx = 0; tx < side && written < n; tx += 500) {
        for (std::uint64_t y = ty; y < std::min(side, ty + 500) && written < n; ++y) {
          for (std::uint64_t x = tx; x < std::min(side, tx + 500) && written < n; ++x, ++written) {
            const double e = 0.05 * x, northing = 0.05 * y;
            const double h = 30.0 + 10.0 * std::sin(e / 37.0) * std::cos(northing / 23.0) + 0.01 * ((x * 7 + y * 13) % 5);
            const auto shade = static_cast<std::uint8_t>(100 + 80 * std::sin(e / 3.0) * std::sin(northing / 5.0));
            const Eigen::Vector3d p = lo + Eigen::Vector3d(e, northing, h);
            const std::array<std::uint8_t, 3> rgb = {shade, static_cast<std::uint8_t>(shade / 2 + 60), 70};
            if (las) las->Add(p, rgb, h < 28.0 ? 2 : 1);
            if (copc) copc->Add(p, rgb, h < 28.0 ? 2 : 1);
          }
        }
      }
    }
    if (las) las->Commit();
    if (copc) copc->Commit();
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: laz_fixture OUT N lidar|terrain\n");
    return 2;
  }
  const std::uint64_t n = std::stoull(argv[2]);
  if (std::string(argv[3]) == "lidar") {
    WriteLidar(argv[1], static_cast<std::uint32_t>(n));
  } else {
    WriteTerrain(argv[1], n);
  }
  return 0;
}
