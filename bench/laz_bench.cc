// SPDX-License-Identifier: BSD-3-Clause
// LAZ and COPC against LAS on one cloud, side by side in one run:
// 1. the writers alone: the cloud (a LAS or LAZ file, e.g. a survey's cloud)
//    is read once into memory, then written as LAS and as LAZ in alternation
//    (best of three each), then each file is read back;
// 2. the dense stage's cloud-products step as a survey runs it: the cloud in
//    CRS tiles on disk, ground classes, DSM and DTM, and the cloud file as
//    LAS, LAZ and COPC in turn (the PLY left out).
// Prints sizes, times and their ratios.
//   laz_bench CLOUD.las|.laz OUT_DIR
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <vector>

#include "libphoto/export/cloud_tiles.h"
#include "libphoto/export/point_cloud.h"

namespace {

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double Write(const aerotri::CrsCloud& cloud, const std::filesystem::path& path) {
  const auto t0 = std::chrono::steady_clock::now();
  aerotri::WriteLas(cloud, path);
  return Seconds(t0);
}

double Read(const std::filesystem::path& path, std::uint64_t* points) {
  const auto t0 = std::chrono::steady_clock::now();
  *points = 0;
  aerotri::ReadLasInBatches(path, [&](aerotri::CrsCloud&& batch) { *points += batch.xyz.size(); });
  return Seconds(t0);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: laz_bench CLOUD.las OUT_DIR\n");
    return 2;
  }
  const aerotri::CrsCloud cloud = aerotri::ReadLas(argv[1]);
  const std::filesystem::path dir = argv[2];
  std::filesystem::create_directories(dir);
  const std::filesystem::path las = dir / "bench.las", laz = dir / "bench.laz";
  double t_las = std::numeric_limits<double>::max(), t_laz = t_las;
  for (int round = 0; round < 3; ++round) {
    t_las = std::min(t_las, Write(cloud, las));
    t_laz = std::min(t_laz, Write(cloud, laz));
  }
  std::uint64_t n_las = 0, n_laz = 0;
  const double r_las = Read(las, &n_las), r_laz = Read(laz, &n_laz);
  const double s_las = static_cast<double>(std::filesystem::file_size(las));
  const double s_laz = static_cast<double>(std::filesystem::file_size(laz));
  std::printf("points            %zu\n", cloud.xyz.size());
  std::printf("size    LAS %8.1f MB   LAZ %8.1f MB   LAZ/LAS %.3f\n", s_las / 1e6, s_laz / 1e6, s_laz / s_las);
  std::printf("write   LAS %8.2f s    LAZ %8.2f s    LAZ/LAS %.2f (best of 3, alternating)\n", t_las, t_laz, t_laz / t_las);
  std::printf("read    LAS %8.2f s    LAZ %8.2f s    LAZ/LAS %.2f (%llu and %llu points)\n", r_las, r_laz, r_laz / r_las,
              static_cast<unsigned long long>(n_las), static_cast<unsigned long long>(n_laz));

  // The products step, from CRS tiles on disk.
  aerotri::CloudProductOptions products;
  products.dsm.resolution_m = 0.1;
  products.dsm.work_dir = dir;
  products.threads = 2;
  products.las_wkt = cloud.crs_wkt;
  aerotri::TiledCloud tiles(dir / "tiles", 50.0, aerotri::CloudProductsHalo(products));
  for (std::size_t at = 0; at < cloud.xyz.size(); at += 1000000) {
    const std::size_t end = std::min(cloud.xyz.size(), at + 1000000);
    tiles.Add({cloud.xyz.begin() + at, cloud.xyz.begin() + end}, {cloud.rgb.begin() + at, cloud.rgb.begin() + end});
  }
  tiles.Finish();
  double step[3];
  const char* names[3] = {"step.las", "step.laz", "step.copc.laz"};
  for (int k = 0; k < 3; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    aerotri::WriteCloudProducts(tiles, dir / names[k], {}, products);
    step[k] = Seconds(t0);
  }
  std::printf("products step (tiles -> classes, DSM, DTM, cloud file; %zu tiles)\n", tiles.num_tiles());
  for (int k = 0; k < 3; ++k) {
    std::printf("  %-14s %8.2f s  %8.1f MB   time/LAS %.2f\n", names[k], step[k],
                static_cast<double>(std::filesystem::file_size(dir / names[k])) / 1e6, step[k] / step[0]);
  }
  return n_las == cloud.xyz.size() && n_laz == cloud.xyz.size() ? 0 : 1;
}
