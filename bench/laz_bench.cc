// SPDX-License-Identifier: BSD-3-Clause
// LAZ against LAS on one cloud, side by side in one run: the cloud (a LAS or
// LAZ file, e.g. a survey's cloud.las) is read once into memory, then written
// as LAS and as LAZ in alternation (three rounds each), then each file is read
// back. Prints sizes, times and their ratios.
//   laz_bench CLOUD.las OUT_DIR
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <vector>

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
  return n_las == cloud.xyz.size() && n_laz == cloud.xyz.size() ? 0 : 1;
}
