// SPDX-License-Identifier: BSD-3-Clause
// The orthomosaic of rendered photos against the ground's true colours: the
// geometry by phase correlation in tiles, coverage, seams and radiometry;
// the file through GDAL.
#include "libphoto/ortho/orthomosaic.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <set>

#include <opencv2/imgproc.hpp>

#include "libphoto/base/error.h"
#include "libphoto/simulate/render.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

struct Scene {
  SparseModel truth;
  std::vector<cv::Mat> photos;
  Raster surface;  // the terrain on a local grid (the world frame itself)
  double gsd = 0;
  double half_w = 0, half_h = 0;
};

Scene MakeScene(double relief_m) {
  SyntheticSurveyOptions s;
  s.seed = 11;
  s.width = 320;
  s.height = 240;
  s.brown_params = {260.0, 161.0, 119.0, -0.05, 0.02, 0.0, 0.0003, -0.0002};
  s.area_width_m = 30.0;
  s.area_height_m = 22.0;
  s.flight_height_m = 30.0;
  s.relief_m = relief_m;
  s.num_tie_points = 50;
  s.num_control_points = 0;
  s.num_check_points = 0;
  const SyntheticSurvey survey = MakeSyntheticSurvey(s);
  Scene scene;
  scene.truth = survey.truth;
  scene.gsd = survey.gsd_m;
  scene.half_w = 0.5 * s.area_width_m;
  scene.half_h = 0.5 * s.area_height_m;
  RenderOptions r;
  r.relief_m = relief_m;
  for (size_t i = 0; i < scene.truth.images.size(); ++i) {
    r.seed = static_cast<std::uint32_t>(100 + i);
    scene.photos.push_back(RenderImage(scene.truth.cameras[0], scene.truth.images[i].pose, r));
  }
  Raster& d = scene.surface;
  d.width = 200;
  d.height = 160;
  const double res = 0.25;
  d.geotransform = {-25.0, res, 0.0, 20.0, 0.0, -res};
  d.values.resize(static_cast<size_t>(d.width) * d.height);
  for (int y = 0; y < d.height; ++y) {
    for (int x = 0; x < d.width; ++x) d.at(x, y) = static_cast<float>(TerrainHeight(d.X(x), d.Y(y), relief_m));
  }
  return scene;
}

struct Read {
  cv::Mat bgr, alpha;
  double gt[6];
};

Read ReadOrtho(const std::filesystem::path& path) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(static_cast<GDALDataset*>(GDALOpen(path.string().c_str(), GA_ReadOnly)));
  Read r;
  EXPECT_TRUE(ds);
  if (!ds) return r;
  ds->GetGeoTransform(r.gt);
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  cv::Mat c[3];
  for (int b = 0; b < 3; ++b) {
    c[2 - b] = cv::Mat(h, w, CV_8U);
    EXPECT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Read, 0, 0, w, h, c[2 - b].data, w, h, GDT_Byte, 0, 0), CE_None);
  }
  cv::merge(c, 3, r.bgr);
  r.alpha = cv::Mat(h, w, CV_8U);
  GDALRasterBand* mask = ds->GetRasterCount() >= 4 ? ds->GetRasterBand(4) : ds->GetRasterBand(1)->GetMaskBand();
  EXPECT_EQ(mask->RasterIO(GF_Read, 0, 0, w, h, r.alpha.data, w, h, GDT_Byte, 0, 0), CE_None);
  return r;
}

struct Figures {
  double fill = 0;              // of the flown area
  double rmse_shift_px = 0;     // tiles' offsets against the truth
  double max_shift_px = 0;
  double median_abs_dn = 0;     // grey, after the mean gain
  int tiles = 0;
};

Figures Compare(const Scene& scene, const Read& o) {
  Figures f;
  const double res = o.gt[1];
  cv::Mat truth(o.bgr.size(), CV_8UC3);
  for (int y = 0; y < truth.rows; ++y) {
    for (int x = 0; x < truth.cols; ++x) {
      const double e = o.gt[0] + (x + 0.5) * res, n = o.gt[3] - (y + 0.5) * res;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int sy = -1; sy <= 1; ++sy) {
        for (int sx = -1; sx <= 1; ++sx) sum += GroundAlbedo(e + sx * res / 3, n + sy * res / 3, {});
      }
      for (int k = 0; k < 3; ++k) truth.at<cv::Vec3b>(y, x)[2 - k] = cv::saturate_cast<std::uint8_t>(255.0 * sum[k] / 9);
    }
  }
  long long inside = 0, filled = 0;
  for (int y = 0; y < truth.rows; ++y) {
    for (int x = 0; x < truth.cols; ++x) {
      const double e = o.gt[0] + (x + 0.5) * res, n = o.gt[3] - (y + 0.5) * res;
      if (std::abs(e) > scene.half_w || std::abs(n) > scene.half_h) continue;
      ++inside;
      filled += o.alpha.at<std::uint8_t>(y, x) > 127;
    }
  }
  f.fill = static_cast<double>(filled) / std::max(1LL, inside);
  cv::Mat g_truth, g_ortho;
  cv::cvtColor(truth, g_truth, cv::COLOR_BGR2GRAY);
  cv::cvtColor(o.bgr, g_ortho, cv::COLOR_BGR2GRAY);
  g_truth.convertTo(g_truth, CV_32F);
  g_ortho.convertTo(g_ortho, CV_32F);
  const int T = 64;
  double sum2 = 0;
  std::vector<float> diffs;
  for (int y = 0; y + T <= truth.rows; y += T) {
    for (int x = 0; x + T <= truth.cols; x += T) {
      const cv::Rect r(x, y, T, T);
      if (cv::countNonZero(o.alpha(r) > 127) < T * T) continue;
      cv::Mat window;
      cv::createHanningWindow(window, r.size(), CV_32F);
      const cv::Point2d d = cv::phaseCorrelate(g_truth(r), g_ortho(r), window);
      sum2 += d.dot(d);
      f.max_shift_px = std::max(f.max_shift_px, std::hypot(d.x, d.y));
      ++f.tiles;
      const double gain = cv::mean(g_truth(r))[0] / std::max(1.0, cv::mean(g_ortho(r))[0]);
      cv::Mat diff = cv::abs(g_truth(r) - gain * g_ortho(r));
      diffs.insert(diffs.end(), diff.begin<float>(), diff.end<float>());
    }
  }
  f.rmse_shift_px = std::sqrt(sum2 / std::max(1, f.tiles));
  if (!diffs.empty()) {
    std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
    f.median_abs_dn = diffs[diffs.size() / 2];
  }
  return f;
}

void RunOrtho(const Scene& scene, const OrthoOptions& options, const std::filesystem::path& path, OrthoSummary* s) {
  const CrsToWorldFactory identity = []() -> CrsToWorld { return [](const Eigen::Vector3d& p) { return p; }; };
  WriteOrthomosaic(
      scene.truth, [&](int i) { return scene.photos[i].clone(); }, scene.surface, identity, options, path, nullptr, s);
}

class Orthomosaic : public ::testing::TestWithParam<double> {};

TEST_P(Orthomosaic, MatchesTheTrueGroundWithinAFractionOfACell) {
  const Scene scene = MakeScene(GetParam());
  testing::TempDir dir;
  OrthoOptions o;
  o.resolution_m = std::round(scene.gsd * 1000.0) / 1000.0;
  o.tile_size = 128;  // several tiles, so that their borders are tested too
  o.compress = "DEFLATE";
  OrthoSummary summary;
  RunOrtho(scene, o, dir.path() / "ortho.tif", &summary);
  const Read read = ReadOrtho(dir.path() / "ortho.tif");
  const Figures f = Compare(scene, read);
  std::printf("relief %.1f m: %d x %d cells, %d images, fill %.4f, %d tiles, shift rmse %.3f max %.3f px, median |dgrey| %.2f DN\n",
              GetParam(), summary.width, summary.height, summary.images_used, f.fill, f.tiles, f.rmse_shift_px,
              f.max_shift_px, f.median_abs_dn);
  EXPECT_EQ(summary.images_used, static_cast<int>(scene.truth.images.size())) << "every photo has a part";
  EXPECT_GT(summary.tiles, 4);
  EXPECT_GE(f.fill, 0.98);
  ASSERT_GT(f.tiles, 10);
  // Geometry: the cameras and surface are exact, so what is left is the
  // resampling (bilinear, twice) and the renderer's noise: a tenth of a cell.
  EXPECT_LT(f.rmse_shift_px, 0.25) << "relief " << GetParam();
  EXPECT_LT(f.max_shift_px, 0.6);
  // Radiometry: sensor noise (1.5 DN), JPEG-free here, bilinear smoothing.
  EXPECT_LT(f.median_abs_dn, 12.0);
  EXPECT_GT(f.median_abs_dn, 0.1);  // not the truth copied
}

INSTANTIATE_TEST_SUITE_P(FlatAndHilly, Orthomosaic, ::testing::Values(0.5, 12.0));

TEST(OrthomosaicFile, IsACloudOptimisedGeoTiffWithAMaskAndOverviews) {
  const Scene scene = MakeScene(4.0);
  testing::TempDir dir;
  OrthoOptions o;
  o.resolution_m = 0.05;  // finer than the GSD: large enough for overviews
  o.metadata["AEROTRI_SURFACE"] = "test";
  RunOrtho(scene, o, dir.path() / "ortho.tif", nullptr);
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      static_cast<GDALDataset*>(GDALOpen((dir.path() / "ortho.tif").string().c_str(), GA_ReadOnly)));
  ASSERT_TRUE(ds);
  EXPECT_STREQ(ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE"), "COG");
  EXPECT_STREQ(ds->GetMetadataItem("COMPRESSION", "IMAGE_STRUCTURE"), "YCbCr JPEG");
  EXPECT_STREQ(ds->GetMetadataItem("AEROTRI_SURFACE"), "test");
  EXPECT_EQ(ds->GetRasterCount(), 3);  // JPEG: the alpha is a mask band
  EXPECT_EQ(ds->GetRasterBand(1)->GetMaskFlags(), GMF_PER_DATASET);
  EXPECT_GT(ds->GetRasterBand(1)->GetOverviewCount(), 0);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "ortho.tif.building.tif"));
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1) << "only ortho.tif is left";
}

// The orthomosaic in shares of tile rows, as a split workflow's jobs draw it
// (one share empty: more shares than rows would leave some so), joined by
// AssembleOrthomosaic: the file one call writes, cell for cell and band for
// band (alpha included), from the same photos.
TEST(OrthomosaicFile, BandsOfSharesAssembleToTheOneCallOrthomosaic) {
  const Scene scene = MakeScene(4.0);
  testing::TempDir dir;
  OrthoOptions o;
  o.resolution_m = std::round(scene.gsd * 1000.0) / 1000.0;
  o.tile_size = 128;
  o.compress = "DEFLATE";
  o.cog = false;
  OrthoSummary whole;
  RunOrtho(scene, o, dir.path() / "whole.tif", &whole);
  const int rows = (whole.height + o.tile_size - 1) / o.tile_size;
  ASSERT_GE(rows, 3);
  o.share_count = rows + 1;  // one share has no row
  std::vector<std::filesystem::path> bands;
  std::set<int> images;
  long long surface = 0, filled = 0;
  int empty = 0, covered = 0;
  for (int k = 0; k < o.share_count; ++k) {
    o.share_index = k;
    OrthoSummary s;
    const std::filesystem::path band = dir.path() / ("band" + std::to_string(k) + ".tif");
    RunOrtho(scene, o, band, &s);
    if (s.band_height == 0) {
      ++empty;
      EXPECT_FALSE(std::filesystem::exists(band));
      continue;
    }
    EXPECT_EQ(s.band_y, covered) << "share " << k;
    covered += s.band_height;
    bands.push_back(band);
    images.insert(s.images.begin(), s.images.end());
    surface += s.cells_with_surface;
    filled += s.cells_filled;
  }
  EXPECT_EQ(empty, 1);
  EXPECT_EQ(covered, whole.height);
  EXPECT_EQ(static_cast<int>(images.size()), whole.images_used);
  EXPECT_EQ(surface, whole.cells_with_surface);
  EXPECT_EQ(filled, whole.cells_filled);
  o.share_count = 1;
  o.share_index = 0;
  AssembleOrthomosaic(bands, o, dir.path() / "joined.tif");
  GDALAllRegister();
  std::unique_ptr<GDALDataset> a(
      static_cast<GDALDataset*>(GDALOpen((dir.path() / "whole.tif").string().c_str(), GA_ReadOnly)));
  std::unique_ptr<GDALDataset> b(
      static_cast<GDALDataset*>(GDALOpen((dir.path() / "joined.tif").string().c_str(), GA_ReadOnly)));
  ASSERT_TRUE(a && b);
  ASSERT_EQ(a->GetRasterXSize(), b->GetRasterXSize());
  ASSERT_EQ(a->GetRasterYSize(), b->GetRasterYSize());
  ASSERT_EQ(a->GetRasterCount(), 4);
  ASSERT_EQ(b->GetRasterCount(), 4);
  double ga[6], gb[6];
  a->GetGeoTransform(ga);
  b->GetGeoTransform(gb);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(ga[k], gb[k]) << k;
  const int w = a->GetRasterXSize(), h = a->GetRasterYSize();
  std::vector<std::uint8_t> pa(static_cast<size_t>(w) * h), pb(pa.size());
  for (int band = 1; band <= 4; ++band) {
    ASSERT_EQ(a->GetRasterBand(band)->RasterIO(GF_Read, 0, 0, w, h, pa.data(), w, h, GDT_Byte, 0, 0), CE_None);
    ASSERT_EQ(b->GetRasterBand(band)->RasterIO(GF_Read, 0, 0, w, h, pb.data(), w, h, GDT_Byte, 0, 0), CE_None);
    size_t differ = 0;
    for (size_t k = 0; k < pa.size(); ++k) differ += pa[k] != pb[k];
    EXPECT_EQ(differ, 0u) << "band " << band;
  }
}

TEST(OrthomosaicFile, BadOptionsAreRefused) {
  Scene scene;
  scene.surface.width = scene.surface.height = 2;
  scene.surface.values = {1, 1, 1, 1};
  testing::TempDir dir;
  OrthoOptions o;
  EXPECT_THROW(RunOrtho(scene, o, dir.path() / "o.tif", nullptr), InvalidArgument);  // no resolution
  o.resolution_m = 0.1;
  o.compress = "LZMA";
  EXPECT_THROW(RunOrtho(scene, o, dir.path() / "o.tif", nullptr), InvalidArgument);
}

}  // namespace
}  // namespace aerotri
