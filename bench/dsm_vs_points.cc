// SPDX-License-Identifier: BSD-3-Clause
// Compares a DSM with reference points (text "x y z" per line, same CRS):
// the DSM minus reference heights where the DSM has data, as a median offset
// (datum / georeferencing difference) and the spread around it (surface
// agreement). Benchmark, not a test.
//   dsm_vs_points DSM.tif POINTS.xyz
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include "libphoto/base/error.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/raster.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: dsm_vs_points DSM.tif POINTS.xyz\n");
    return 2;
  }
  try {
    const aerotri::Raster dsm = aerotri::ReadRaster(argv[1]);
    std::ifstream in(argv[2]);
    double x, y, z;
    std::vector<double> d;
    long long total = 0;
    while (in >> x >> y >> z) {
      ++total;
      if (const auto h = aerotri::SampleRaster(dsm, x, y)) d.push_back(*h - z);
    }
    if (d.empty()) {
      std::printf("no overlap (%lld reference points)\n", total);
      return 1;
    }
    std::sort(d.begin(), d.end());
    const double median = d[d.size() / 2];
    std::vector<double> dev;
    for (double v : d) dev.push_back(std::abs(v - median));
    std::sort(dev.begin(), dev.end());
    std::printf("reference_points=%lld with_dsm=%zu median_offset_m=%.3f mad_m=%.3f p90_abs_dev_m=%.3f\n", total,
                d.size(), median, dev[dev.size() / 2], dev[dev.size() * 9 / 10]);
    return 0;
  } catch (const aerotri::Error& e) {
    std::fprintf(stderr, "dsm_vs_points: %s\n", e.what());
    return 1;
  }
}
