// SPDX-License-Identifier: BSD-3-Clause
// Compares a DSM with a truth DEM in the same CRS, inside the truth's extent
// shrunk by a margin on every side (the surveyed area away from its borders):
// prints the fraction of truth cells where the DSM has data and the
// statistics of DSM - truth there. A DSM of EGM96 heights (the deliverables'
// default: its CRS compound with EPSG:5773) against an ellipsoidal truth is
// raised by the geoid undulation at the truth's centre first, and says so.
// Benchmark, not a test.
//   dsm_vs_truth DSM.tif TRUTH.tif [margin_m (default 10)]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "georef/crs.h"
#include "libphoto/base/error.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/raster.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: dsm_vs_truth DSM.tif TRUTH.tif [margin_m]\n");
    return 2;
  }
  try {
    const aerotri::Raster dsm = aerotri::ReadRaster(argv[1]);
    const aerotri::Raster truth = aerotri::ReadRaster(argv[2]);
    const double margin = argc > 3 ? std::atof(argv[3]) : 10.0;
    double undulation = 0.0;
    if (dsm.wkt.find("EGM96") != std::string::npos && truth.wkt.find("EGM96") == std::string::npos) {
      const aerotri::Geodetic centre =
          aerotri::Crs::FromString(truth.wkt).ToGeodetic({truth.X(0.5 * truth.width), truth.Y(0.5 * truth.height), 0.0});
      undulation = aerotri::Egm96Undulation(centre.lat_deg, centre.lon_deg);
      std::printf("DSM heights are EGM96, the truth's ellipsoidal: DSM + %.3f m (geoid undulation)\n", undulation);
    }
    const int mx = static_cast<int>(margin / truth.geotransform[1]);
    const int my = static_cast<int>(margin / -truth.geotransform[5]);
    std::vector<double> err;
    long long total = 0;
    for (int y = my; y < truth.height - my; ++y) {
      for (int x = mx; x < truth.width - mx; ++x) {
        ++total;
        const auto z = aerotri::SampleRaster(dsm, truth.X(x), truth.Y(y));
        if (z) err.push_back(*z + undulation - truth.at(x, y));
      }
    }
    if (err.empty()) {
      std::printf("no overlap\n");
      return 1;
    }
    std::vector<double> abs_err;
    double sum = 0, sq = 0;
    for (double e : err) {
      abs_err.push_back(std::abs(e));
      sum += e;
      sq += e * e;
    }
    std::sort(abs_err.begin(), abs_err.end());
    std::sort(err.begin(), err.end());
    std::printf("cells_compared=%lld filled=%.4f median_abs_m=%.4f p90_abs_m=%.4f mean_m=%.4f median_m=%.4f rmse_m=%.4f\n",
                total, static_cast<double>(err.size()) / total, abs_err[abs_err.size() / 2],
                abs_err[abs_err.size() * 9 / 10], sum / err.size(), err[err.size() / 2], std::sqrt(sq / err.size()));
    return 0;
  } catch (const aerotri::Error& e) {
    std::fprintf(stderr, "dsm_vs_truth: %s\n", e.what());
    return 1;
  }
}
