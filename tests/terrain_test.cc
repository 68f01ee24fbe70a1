// SPDX-License-Identifier: BSD-3-Clause
// Ground classification (SMRF), the DTM and contours against a scene whose
// truth is known: rolling terrain with box buildings, a stereo cloud's noise
// and stray points; contours read back through OGR (GDAL's reader).
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <tuple>
#include <memory>
#include <random>

#include "georef/crs.h"
#include "libphoto/export/cloud_tiles.h"
#include "libphoto/export/contours.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/point_cloud.h"
#include "libphoto/export/terrain.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

constexpr double kX0 = 384900.0, kY0 = 5150700.0;

double Terrain(double x, double y) {
  return 500.0 + 3.0 * std::sin((x - kX0) / 15.0) + 0.05 * (y - kY0);
}

struct Box {
  double x, y, half_w, half_h, height;
  bool Contains(double px, double py) const { return std::abs(px - x) <= half_w && std::abs(py - y) <= half_h; }
};

const std::vector<Box>& Buildings() {
  static const std::vector<Box> b = {{kX0 + 15, kY0 + 15, 5, 4, 6.0},
                                     {kX0 + 45, kY0 + 30, 7, 5, 9.0},
                                     {kX0 + 28, kY0 + 40, 3, 3, 3.5}};
  return b;
}

enum class Truth { kGround, kObject, kHighNoise, kLowNoise };

struct Scene {
  std::vector<Eigen::Vector3d> xyz;
  std::vector<Truth> truth;
};

// 70 x 55 m at ~25 points/m^2, 2 cm height noise; walls sparsely sampled;
// 40 stray points 15-30 m up, 40 3-8 m under the ground.
Scene MakeScene(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  Scene s;
  for (int i = 0; i < 70 * 55 * 25; ++i) {
    const double x = kX0 + 70.0 * u(rng), y = kY0 + 55.0 * u(rng);
    double z = Terrain(x, y);
    Truth t = Truth::kGround;
    for (const Box& b : Buildings()) {
      if (b.Contains(x, y)) {
        z += b.height;
        t = Truth::kObject;
      }
    }
    s.xyz.emplace_back(x, y, z + noise(rng));
    s.truth.push_back(t);
  }
  for (const Box& b : Buildings()) {  // one wall each, a point every 10 cm^2 or so
    for (int i = 0; i < 2000; ++i) {
      const double x = b.x - b.half_w + 2 * b.half_w * u(rng), y = b.y - b.half_h;
      s.xyz.emplace_back(x, y, Terrain(x, y) + 0.5 + (b.height - 0.5) * u(rng));
      s.truth.push_back(Truth::kObject);
    }
  }
  for (int i = 0; i < 40; ++i) {
    const double x = kX0 + 5 + 60.0 * u(rng), y = kY0 + 5 + 45.0 * u(rng);
    s.xyz.emplace_back(x, y, Terrain(x, y) + 15.0 + 15.0 * u(rng));
    s.truth.push_back(Truth::kHighNoise);
    const double x2 = kX0 + 5 + 60.0 * u(rng), y2 = kY0 + 5 + 45.0 * u(rng);
    s.xyz.emplace_back(x2, y2, Terrain(x2, y2) - 3.0 - 5.0 * u(rng));
    s.truth.push_back(Truth::kLowNoise);
  }
  return s;
}

TEST(GroundFilter, SeparatesGroundFromBuildingsAndFlagsStrayPoints) {
  const Scene scene = MakeScene(3);
  GroundFilterSummary summary;
  const std::vector<std::uint8_t> classes = ClassifyGround(scene.xyz, GroundFilterOptions{}, &summary);
  ASSERT_EQ(classes.size(), scene.xyz.size());
  long long true_ground = 0, found_ground = 0, correct_ground = 0, high = 0, low = 0, high_ok = 0, low_ok = 0;
  for (size_t i = 0; i < classes.size(); ++i) {
    const bool is_ground = scene.truth[i] == Truth::kGround;
    true_ground += is_ground;
    found_ground += classes[i] == kGround;
    correct_ground += is_ground && classes[i] == kGround;
    if (scene.truth[i] == Truth::kHighNoise) high_ok += classes[i] == kHighNoise, ++high;
    if (scene.truth[i] == Truth::kLowNoise) low_ok += classes[i] == kLowNoise, ++low;
  }
  const double recall = static_cast<double>(correct_ground) / true_ground;
  const double precision = static_cast<double>(correct_ground) / found_ground;
  EXPECT_GT(recall, 0.97) << correct_ground << " of " << true_ground;
  EXPECT_GT(precision, 0.99) << correct_ground << " of " << found_ground;
  EXPECT_EQ(high_ok, high);
  EXPECT_EQ(low_ok, low);
  EXPECT_EQ(summary.ground, found_ground);
  // Roofs are never ground: every point well inside a footprint is above it.
  long long roof_as_ground = 0;
  for (size_t i = 0; i < classes.size(); ++i) {
    for (const Box& b : Buildings()) {
      const Eigen::Vector3d& p = scene.xyz[i];
      if (std::abs(p.x() - b.x) < b.half_w - 0.5 && std::abs(p.y() - b.y) < b.half_h - 0.5 &&
          scene.truth[i] == Truth::kObject) {
        roof_as_ground += classes[i] == kGround;
      }
    }
  }
  EXPECT_EQ(roof_as_ground, 0);
}

TEST(GroundFilter, FlatOpenGroundIsAllGround) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.03);
  std::vector<Eigen::Vector3d> xyz;
  for (int i = 0; i < 40000; ++i) {
    const double x = kX0 + 40 * u(rng), y = kY0 + 40 * u(rng);
    xyz.emplace_back(x, y, 480.0 + 0.15 * (x - kX0) + noise(rng));  // a steady 15 % slope
  }
  const auto classes = ClassifyGround(xyz, GroundFilterOptions{});
  const long long ground = std::count(classes.begin(), classes.end(), kGround);
  EXPECT_GT(ground, static_cast<long long>(0.995 * xyz.size()));
}

TEST(Dtm, FollowsTheBareTerrainUnderBuildings) {
  const Scene scene = MakeScene(4);
  const auto classes = ClassifyGround(scene.xyz, GroundFilterOptions{});
  DsmOptions d;
  d.resolution_m = 0.25;
  const Raster dsm = RasterizeDsm(scene.xyz, Crs::FromString("EPSG:32632").Wkt(), d);
  DtmSummary summary;
  const Raster dtm = RasterizeDtm(scene.xyz, classes, dsm, {}, &summary);
  ASSERT_EQ(dtm.width, dsm.width);
  ASSERT_EQ(dtm.height, dsm.height);
  EXPECT_EQ(dtm.geotransform, dsm.geotransform);
  std::vector<double> open_err, under_err;
  for (int y = 4; y < dtm.height - 4; ++y) {
    for (int x = 4; x < dtm.width - 4; ++x) {
      const float z = dtm.at(x, y);
      // The DTM has data exactly where the DSM has.
      ASSERT_EQ(z == static_cast<float>(dtm.nodata), dsm.at(x, y) == static_cast<float>(dsm.nodata)) << x << " " << y;
      if (z == static_cast<float>(dtm.nodata)) continue;
      bool under = false;
      for (const Box& b : Buildings()) under = under || b.Contains(dtm.X(x), dtm.Y(y));
      (under ? under_err : open_err).push_back(std::abs(z - Terrain(dtm.X(x), dtm.Y(y))));
    }
  }
  std::sort(open_err.begin(), open_err.end());
  std::sort(under_err.begin(), under_err.end());
  // Open ground: the median of ~6 points of 2 cm noise, plus the terrain's
  // curvature in a cell. Under buildings: interpolated across up to 14 m.
  EXPECT_LT(open_err[open_err.size() / 2], 0.02);
  EXPECT_GT(open_err[open_err.size() / 2], 0.001);  // not the truth copied
  EXPECT_LT(under_err[under_err.size() / 2], 0.25);
  // No roof left (they stand 3.5-9 m up); inverse-distance filling flattens
  // the 3 m swell of the terrain under the widest (14 m) roof.
  EXPECT_LT(under_err[under_err.size() * 95 / 100], 1.5);
  EXPECT_GT(summary.cells_interpolated, 0);
}

TEST(Las, ClassesRoundTrip) {
  testing::TempDir dir;
  CrsCloud cloud;
  cloud.crs_wkt = Crs::FromString("EPSG:32632").WktV1();
  for (int i = 0; i < 50; ++i) {
    cloud.xyz.emplace_back(kX0 + i, kY0, 500.0);
    cloud.rgb.push_back({1, 2, 3});
    cloud.classes.push_back(static_cast<std::uint8_t>(i % 3 == 0 ? kGround : i % 3 == 1 ? kUnclassified : kLowNoise));
  }
  WriteLas(cloud, dir.path() / "c.las");
  const CrsCloud back = ReadLas(dir.path() / "c.las");
  EXPECT_EQ(back.classes, cloud.classes);
}

// The products of a cloud written tile by tile (never whole in memory) are
// those of the whole cloud: tiles of 9 m cut through every building and the
// noise, so a cell or a noise test that missed its neighbours across a seam
// would change a height or a class.
TEST(TiledCloud, ProductsEqualTheWholeCloudsAcrossEveryTileSeam) {
  const Scene scene = MakeScene(6);
  std::vector<std::array<std::uint8_t, 3>> rgb;
  for (size_t i = 0; i < scene.xyz.size(); ++i) {
    rgb.push_back({static_cast<std::uint8_t>(i % 251), static_cast<std::uint8_t>(i % 13), 7});
  }
  const Crs crs = Crs::FromString("EPSG:32632");
  CloudProductOptions o;
  o.dsm.resolution_m = 0.25;
  o.threads = 2;
  o.las_wkt = crs.WktV1();
  o.raster_wkt = crs.Wkt();
  o.crs_name = crs.Name();
  testing::TempDir dir;
  TiledCloud tiles(dir.path() / "tiles", 9.0, CloudProductsHalo(o));
  // In batches, as fusion hands them over.
  for (size_t begin = 0; begin < scene.xyz.size(); begin += 10000) {
    const size_t end = std::min(scene.xyz.size(), begin + 10000);
    tiles.Add({scene.xyz.begin() + begin, scene.xyz.begin() + end}, {rgb.begin() + begin, rgb.begin() + end});
  }
  tiles.Finish();
  ASSERT_EQ(tiles.count(), scene.xyz.size());
  ASSERT_GE(tiles.num_tiles(), 40u);  // 70 x 55 m in 9 m tiles
  const CloudProducts tiled = WriteCloudProducts(tiles, dir.path() / "c.las", dir.path() / "c.ply", o);

  GroundFilterSummary whole_summary;
  const std::vector<std::uint8_t> classes = ClassifyGround(scene.xyz, o.ground, &whole_summary);
  DsmSummary dsm_summary;
  const Raster dsm = RasterizeDsm(scene.xyz, o.raster_wkt, o.dsm, &dsm_summary);
  DtmSummary dtm_summary;
  const Raster dtm = RasterizeDtm(scene.xyz, classes, dsm, {}, &dtm_summary);

  EXPECT_EQ(tiled.dsm.geotransform, dsm.geotransform);
  ASSERT_EQ(tiled.dsm.values.size(), dsm.values.size());
  size_t dsm_differ = 0, dtm_differ = 0;
  for (size_t k = 0; k < dsm.values.size(); ++k) dsm_differ += tiled.dsm.values[k] != dsm.values[k];
  EXPECT_EQ(dsm_differ, 0u);
  EXPECT_EQ(tiled.dsm_summary.cells_with_data, dsm_summary.cells_with_data);
  EXPECT_EQ(tiled.dsm_summary.cells_filled, dsm_summary.cells_filled);
  ASSERT_TRUE(tiled.has_dtm);
  ASSERT_EQ(tiled.dtm.values.size(), dtm.values.size());
  for (size_t k = 0; k < dtm.values.size(); ++k) dtm_differ += tiled.dtm.values[k] != dtm.values[k];
  EXPECT_EQ(dtm_differ, 0u);
  EXPECT_EQ(tiled.dtm_summary.cells_ground, dtm_summary.cells_ground);
  EXPECT_EQ(tiled.ground.ground, whole_summary.ground);
  EXPECT_EQ(tiled.ground.above, whole_summary.above);
  EXPECT_EQ(tiled.ground.noise, whole_summary.noise);
  EXPECT_GT(whole_summary.noise, 0);

  // The LAS holds every point once, with the class the whole cloud gives it.
  const CrsCloud back = ReadLas(dir.path() / "c.las");
  ASSERT_EQ(back.xyz.size(), scene.xyz.size());
  auto key = [](const Eigen::Vector3d& p) {
    return std::make_tuple(std::llround(p.x() * 1000), std::llround(p.y() * 1000), std::llround(p.z() * 1000));
  };
  std::map<std::tuple<long long, long long, long long>, std::uint8_t> expected;
  for (size_t i = 0; i < scene.xyz.size(); ++i) expected[key(scene.xyz[i])] = classes[i];
  size_t missing = 0, wrong = 0;
  for (size_t i = 0; i < back.xyz.size(); ++i) {
    const auto it = expected.find(key(back.xyz[i]));
    if (it == expected.end()) {
      ++missing;
    } else {
      wrong += it->second != back.classes[i];
      expected.erase(it);
    }
  }
  EXPECT_EQ(missing, 0u);
  EXPECT_EQ(wrong, 0u);
  EXPECT_TRUE(expected.empty());
  // The PLY: its header's count, and 27 bytes a point after it.
  std::ifstream ply(dir.path() / "c.ply", std::ios::binary);
  std::string line, header;
  long long vertices = -1;
  while (std::getline(ply, line)) {
    header += line + "\n";
    if (line.rfind("element vertex ", 0) == 0) vertices = std::stoll(line.substr(15));
    if (line == "end_header") break;
  }
  EXPECT_EQ(vertices, static_cast<long long>(scene.xyz.size()));
  EXPECT_EQ(std::filesystem::file_size(dir.path() / "c.ply"), header.size() + 27 * scene.xyz.size());
  // No tile file is left once the cloud is removed.
  tiles.Remove();
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "tiles"));
}

// A cloud that starts just past a tile's edge: the DSM's first column of
// cells has its centres in the tile to the west, which holds none of the
// cloud's points, only its halo. That tile still owns those cells.
TEST(TiledCloud, CellsCentredInATileWithoutPointsOfItsOwnAreSet) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3d> xyz;
  for (int i = 0; i < 20000; ++i) {
    // 10 m tiles; x from 10.01 m: with 0.15 m cells the grid starts at 9.9.
    const double x = kX0 + 10.01 + 4.0 * u(rng), y = kY0 + 10.01 + 4.0 * u(rng);
    xyz.emplace_back(x, y, Terrain(x, y) + 0.01 * u(rng));
  }
  CloudProductOptions o;
  o.dsm.resolution_m = 0.15;
  o.raster_wkt = Crs::FromString("EPSG:32632").Wkt();
  testing::TempDir dir;
  TiledCloud tiles(dir.path() / "tiles", 10.0, CloudProductsHalo(o));
  tiles.Add(xyz, {});
  tiles.Finish();
  const CloudProducts tiled = WriteCloudProducts(tiles, {}, {}, o);
  const Raster whole = RasterizeDsm(xyz, o.raster_wkt, o.dsm);
  ASSERT_EQ(tiled.dsm.values.size(), whole.values.size());
  ASSERT_LT(whole.geotransform[0], kX0 + 10.0);  // the case at hand: a column centred west of the edge
  size_t differ = 0;
  for (size_t k = 0; k < whole.values.size(); ++k) differ += tiled.dsm.values[k] != whole.values[k];
  EXPECT_EQ(differ, 0u);
  ASSERT_TRUE(tiled.has_dtm);
  const Raster dtm = RasterizeDtm(xyz, ClassifyGround(xyz, o.ground), whole);
  differ = 0;
  for (size_t k = 0; k < dtm.values.size(); ++k) differ += tiled.dtm.values[k] != dtm.values[k];
  EXPECT_EQ(differ, 0u);
}

// Contours through OGR: CRS, attributes, index lines, smoothing.
struct ReadContours {
  std::vector<double> elevations;
  std::vector<int> index;
  std::string srs_name;
};

ReadContours Read(const std::filesystem::path& path) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      static_cast<GDALDataset*>(GDALOpenEx(path.string().c_str(), GDAL_OF_VECTOR, nullptr, nullptr, nullptr)));
  EXPECT_TRUE(ds);
  ReadContours out;
  if (!ds) return out;
  OGRLayer* layer = ds->GetLayerByName("contours");
  EXPECT_TRUE(layer);
  if (!layer) return out;
  if (layer->GetSpatialRef()) out.srs_name = layer->GetSpatialRef()->GetName();
  for (auto& f : *layer) {
    out.elevations.push_back(f->GetFieldAsDouble("elevation"));
    out.index.push_back(f->GetFieldAsInteger("index"));
  }
  return out;
}

TEST(Contours, NoisySurfaceGivesCleanLinesWithIndexContours) {
  testing::TempDir dir;
  // A 100 x 80 m slope rising 1 m every 10 m, with a 5 cm stereo ripple.
  Raster r;
  r.width = 1000;
  r.height = 800;
  r.geotransform = {kX0, 0.1, 0.0, kY0, 0.0, -0.1};
  r.wkt = Crs::FromString("EPSG:32632+5773").Wkt();
  r.values.resize(static_cast<size_t>(r.width) * r.height);
  std::mt19937 rng(9);
  std::normal_distribution<double> ripple(0.0, 0.05);
  for (int y = 0; y < r.height; ++y) {
    for (int x = 0; x < r.width; ++x) r.at(x, y) = static_cast<float>(400.0 + 0.1 * x * 0.1 + ripple(rng));
  }
  ContourOptions o;
  o.interval_m = 1.0;
  ContourSummary s;
  WriteContours(r, dir.path() / "contours.gpkg", o, &s);
  const ReadContours c = Read(dir.path() / "contours.gpkg");
  EXPECT_EQ(c.srs_name, "WGS 84 / UTM zone 32N + EGM96 height");
  // Heights 401..409 cross the slope: one line each.
  EXPECT_EQ(c.elevations.size(), 9u);
  EXPECT_EQ(s.lines, 9);
  for (size_t i = 0; i < c.elevations.size(); ++i) {
    EXPECT_NEAR(c.elevations[i], std::round(c.elevations[i]), 1e-9);
    EXPECT_EQ(c.index[i], static_cast<long long>(std::round(c.elevations[i])) % 5 == 0 ? 1 : 0) << c.elevations[i];
  }
  // Without smoothing the ripple breaks the lines into fragments.
  ContourOptions raw = o;
  raw.smoothing_sigma_m = 0.0;
  raw.min_length_m = 0.0;
  WriteContours(r, dir.path() / "raw.gpkg", raw, &s);
  EXPECT_GT(Read(dir.path() / "raw.gpkg").elevations.size(), 50u);
  EXPECT_DOUBLE_EQ(AutomaticContourInterval(r), 0.5);  // 9.6 m of relief / 20, rounded
}

}  // namespace
}  // namespace aerotri
