// SPDX-License-Identifier: BSD-3-Clause
// DSM rasterisation and GeoTIFF / COG output, checked with GDAL's own
// command-line reader (gdalinfo -json -stats), not aerotri's code.
#include "libphoto/export/dsm.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <random>

#include "georef/crs.h"
#include "libphoto/export/raster.h"
#include "libphoto/base/error.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

std::optional<nlohmann::json> GdalInfo(const std::filesystem::path& file) {
  const std::string cmd = "gdalinfo -json -stats '" + file.string() + "' 2>/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return std::nullopt;
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) out.append(buf, n);
  if (pclose(pipe) != 0 || out.empty()) return std::nullopt;
  return nlohmann::json::parse(out);
}

// A tilted plane z = 500 + 0.1 (x - x0) with a square hole in the middle.
std::vector<Eigen::Vector3d> PlaneWithHole(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 200000; ++i) {
    const double x = 384900.0 + 50.0 * u(rng), y = 5150700.0 + 40.0 * u(rng);
    if (std::abs(x - 384925.0) < 1.0 && std::abs(y - 5150720.0) < 1.0) continue;
    points.emplace_back(x, y, 500.0 + 0.1 * (x - 384900.0));
  }
  return points;
}

TEST(Dsm, GeoTiffReadsBackInGdalWithCrsNodataAndStatistics) {
  if (std::system("gdalinfo --version > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "gdalinfo not installed";
  }
  std::mt19937 rng(1);
  const auto points = PlaneWithHole(rng);
  const Crs crs = Crs::FromString("EPSG:32632");
  DsmOptions o;
  o.resolution_m = 0.25;
  o.fill_max_distance_m = 2.0;
  DsmSummary summary;
  const Raster dsm = RasterizeDsm(points, crs.Wkt(), o, &summary);
  EXPECT_GT(summary.cells_filled, 0);  // the hole was filled
  testing::TempDir dir;
  WriteRaster(dsm, dir / "dsm.tif");
  RasterWriteOptions cog;
  cog.cog = true;
  WriteRaster(dsm, dir / "dsm_cog.tif", cog);

  const auto info = GdalInfo(dir / "dsm.tif");
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ((*info)["driverShortName"], "GTiff");
  EXPECT_NE((*info)["coordinateSystem"]["wkt"].get<std::string>().find("\"EPSG\",32632"), std::string::npos);
  const auto gt = (*info)["geoTransform"];
  EXPECT_DOUBLE_EQ(gt[1].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(gt[5].get<double>(), -0.25);
  EXPECT_NEAR(gt[0].get<double>(), 384900.0, 0.25);
  const auto& band = (*info)["bands"][0];
  EXPECT_DOUBLE_EQ(band["noDataValue"].get<double>(), -9999.0);
  // The plane spans 500 .. 505 m; a median per cell keeps it within a cell's slope.
  EXPECT_NEAR(band["minimum"].get<double>(), 500.0, 0.05);
  EXPECT_NEAR(band["maximum"].get<double>(), 505.0, 0.05);
  EXPECT_NEAR(band["mean"].get<double>(), 502.5, 0.05);
  EXPECT_FALSE(band["overviews"].empty());
  // The filled hole lies on the plane.
  const auto z = SampleRaster(ReadRaster(dir / "dsm.tif"), 384925.0, 5150720.0);
  ASSERT_TRUE(z.has_value());
  EXPECT_NEAR(*z, 502.5, 0.05);

  const auto info_cog = GdalInfo(dir / "dsm_cog.tif");
  ASSERT_TRUE(info_cog.has_value());
  EXPECT_EQ((*info_cog)["metadata"]["IMAGE_STRUCTURE"]["LAYOUT"], "COG");
}

TEST(Dsm, CompoundCrsIsWrittenWithItsVerticalDatum) {
  std::mt19937 rng(2);
  const Crs crs = Crs::FromString("EPSG:32632+5773");
  DsmOptions o;
  o.resolution_m = 0.5;
  const Raster dsm = RasterizeDsm(PlaneWithHole(rng), crs.Wkt(), o);
  testing::TempDir dir;
  WriteRaster(dsm, dir / "dsm.tif");
  const auto info = GdalInfo(dir / "dsm.tif");
  if (!info) GTEST_SKIP() << "gdalinfo not installed";
  const std::string wkt = (*info)["coordinateSystem"]["wkt"];
  EXPECT_NE(wkt.find("EGM96"), std::string::npos) << wkt;
  EXPECT_NE(wkt.find("UTM zone 32N"), std::string::npos);
}

TEST(Dsm, EmptyCloudAndBadResolutionAreRefused) {
  DsmOptions o;
  EXPECT_THROW(RasterizeDsm({}, "", o), InvalidArgument);
  o.resolution_m = 0.0;
  EXPECT_THROW(RasterizeDsm({{0, 0, 0}}, "", o), InvalidArgument);
}

}  // namespace
}  // namespace aerotri
