// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/dsm.h"

#include <gdal_alg.h>
#include <gdal_priv.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include <opencv2/imgproc.hpp>

#include "libphoto/base/error.h"
#include "libphoto/export/cell_heights.h"

namespace aerotri {

std::vector<float> FilledNodata(const Raster& r, double max_distance_px, const std::filesystem::path& work_dir_in,
                                int smoothing_iterations) {
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> ds(mem->Create("", r.width, r.height, 1, GDT_Float32, nullptr));
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(r.nodata);
  if (band->RasterIO(GF_Write, 0, 0, r.width, r.height, const_cast<float*>(r.values.data()), r.width, r.height,
                     GDT_Float32, 0, 0) != CE_None) {
    throw IoError("raster", "cannot fill the in-memory raster");
  }
  // GDAL puts its work files in CPL_TMPDIR, else the current directory.
  std::error_code ec;
  const std::filesystem::path work_dir = work_dir_in.empty() ? std::filesystem::temp_directory_path(ec) : work_dir_in;
  const std::string previous_tmpdir = CPLGetThreadLocalConfigOption("CPL_TMPDIR", "");
  CPLSetThreadLocalConfigOption("CPL_TMPDIR", work_dir.string().c_str());
  const CPLErr filled_ok = GDALFillNodata(band, nullptr, max_distance_px, 0, smoothing_iterations, nullptr, nullptr, nullptr);
  CPLSetThreadLocalConfigOption("CPL_TMPDIR", previous_tmpdir.empty() ? nullptr : previous_tmpdir.c_str());
  if (filled_ok != CE_None) throw IoError("raster", std::string("GDALFillNodata failed: ") + CPLGetLastErrorMsg());
  std::vector<float> out(r.values.size());
  if (band->RasterIO(GF_Read, 0, 0, r.width, r.height, out.data(), r.width, r.height, GDT_Float32, 0, 0) != CE_None) {
    throw IoError("raster", "cannot read the filled in-memory raster");
  }
  return out;
}

Raster DsmGrid(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, const std::string& wkt, const DsmOptions& o) {
  if (!(o.resolution_m > 0)) throw InvalidArgument("DSM: resolution must be > 0");
  if (!(hi.x() >= lo.x() && hi.y() >= lo.y())) throw InvalidArgument("DSM: the point cloud is empty");
  const double res = o.resolution_m;
  Raster r;
  const double x0 = std::floor(lo.x() / res) * res, y1 = std::ceil(hi.y() / res) * res;
  r.width = static_cast<int>(std::ceil((hi.x() - x0) / res)) + 1;
  r.height = static_cast<int>(std::ceil((y1 - lo.y()) / res)) + 1;
  if (static_cast<double>(r.width) * r.height > 4e8) {
    throw InvalidArgument("DSM: " + std::to_string(r.width) + " x " + std::to_string(r.height) +
                          " cells at " + std::to_string(res) + " m is too large; choose a coarser resolution");
  }
  r.geotransform = {x0, res, 0.0, y1, 0.0, -res};
  r.wkt = wkt;
  r.nodata = o.nodata;
  r.values.assign(static_cast<size_t>(r.width) * r.height, static_cast<float>(o.nodata));
  return r;
}

long long SetCellMedians(Raster* raster, const std::vector<Eigen::Vector3d>& xyz,
                         const std::function<bool(size_t)>& use,
                         const std::function<bool(const Eigen::Vector2d&)>& owns) {
  Raster& r = *raster;
  const double x0 = r.geotransform[0], y0 = r.geotransform[3];
  const double dx = r.geotransform[1], dy = -r.geotransform[5];
  auto cell_xy = [&](size_t i, int* cx, int* cy) {
    if (use && !use(i)) return false;
    *cx = static_cast<int>(std::floor((xyz[i].x() - x0) / dx));
    *cy = static_cast<int>(std::floor((y0 - xyz[i].y()) / dy));
    return *cx >= 0 && *cy >= 0 && *cx < r.width && *cy < r.height;
  };
  // Cells numbered within the points' bounding window: a tile of a large
  // cloud needs counters for its own cells, not the whole raster's.
  int wx0 = r.width, wy0 = r.height, wx1 = -1, wy1 = -1;
  for (size_t i = 0; i < xyz.size(); ++i) {
    int cx, cy;
    if (!cell_xy(i, &cx, &cy)) continue;
    wx0 = std::min(wx0, cx), wx1 = std::max(wx1, cx), wy0 = std::min(wy0, cy), wy1 = std::max(wy1, cy);
  }
  if (wx1 < 0) return 0;
  const int w = wx1 - wx0 + 1;
  auto local = [&](size_t i) -> long long {
    int cx, cy;
    if (!cell_xy(i, &cx, &cy)) return -1;
    return static_cast<long long>(cy - wy0) * w + (cx - wx0);
  };
  CellHeights cells(static_cast<size_t>(w) * (wy1 - wy0 + 1));
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (const long long c = local(i); c >= 0) cells.Count(static_cast<size_t>(c));
  }
  cells.Allocate();
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (const long long c = local(i); c >= 0) cells.Add(static_cast<size_t>(c), static_cast<float>(xyz[i].z()));
  }
  long long set = 0;
  for (int cy = wy0; cy <= wy1; ++cy) {
    for (int cx = wx0; cx <= wx1; ++cx) {
      const size_t c = static_cast<size_t>(cy - wy0) * w + (cx - wx0);
      if (cells.empty(c)) continue;
      if (owns && !owns({x0 + (cx + 0.5) * dx, y0 - (cy + 0.5) * dy})) continue;
      float* mid = cells.begin(c) + cells.size(c) / 2;
      std::nth_element(cells.begin(c), mid, cells.end(c));
      r.at(cx, cy) = *mid;
      ++set;
    }
  }
  return set;
}

void FillDsmHoles(Raster* raster, const DsmOptions& o, DsmSummary* summary) {
  Raster& r = *raster;
  const double res = r.geotransform[1];
  long long with_data = 0;
  for (float v : r.values) with_data += v != static_cast<float>(o.nodata);
  long long filled = 0;
  if (o.fill_max_distance_m > 0) {
    const double max_px = o.fill_max_distance_m / res;
    const std::vector<float> filled_values = FilledNodata(r, max_px, o.work_dir);
    // Fill holes, do not grow the edges: keep a filled cell only inside the
    // morphological closing of the cells with data (dilate, then erode, by
    // the fill distance). Without this every isolated point becomes a disc.
    const int radius = std::max(1, static_cast<int>(std::lround(max_px)));
    cv::Mat mask(r.height, r.width, CV_8U);
    for (int y = 0; y < r.height; ++y) {
      for (int x = 0; x < r.width; ++x) mask.at<std::uint8_t>(y, x) = r.at(x, y) != static_cast<float>(o.nodata) ? 255 : 0;
    }
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
    cv::Mat closed;
    cv::morphologyEx(mask, closed, cv::MORPH_CLOSE, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, 0);
    for (int y = 0; y < r.height; ++y) {
      for (int x = 0; x < r.width; ++x) {
        if (closed.at<std::uint8_t>(y, x)) r.at(x, y) = filled_values[static_cast<size_t>(y) * r.width + x];
      }
    }
    long long now = 0;
    for (float v : r.values) now += v != static_cast<float>(o.nodata);
    filled = now - with_data;
  }
  if (summary) {
    summary->width = r.width;
    summary->height = r.height;
    summary->cells_with_data = with_data;
    summary->cells_filled = filled;
  }
}

Raster RasterizeDsm(const std::vector<Eigen::Vector3d>& xyz, const std::string& wkt,
                    const DsmOptions& o, DsmSummary* summary) {
  if (xyz.empty()) throw InvalidArgument("DSM: the point cloud is empty");
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const auto& p : xyz) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  Raster r = DsmGrid(lo, hi, wkt, o);
  SetCellMedians(&r, xyz, nullptr, nullptr);
  FillDsmHoles(&r, o, summary);
  return r;
}

std::optional<double> SampleRaster(const Raster& r, double x, double y) {
  const double px = (x - r.geotransform[0]) / r.geotransform[1] - 0.5;
  const double py = (y - r.geotransform[3]) / r.geotransform[5] - 0.5;
  const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= r.width || y0 + 1 >= r.height) return std::nullopt;
  const double tx = px - x0, ty = py - y0;
  const float nd = static_cast<float>(r.nodata);
  const float a = r.at(x0, y0), b = r.at(x0 + 1, y0), c = r.at(x0, y0 + 1), d = r.at(x0 + 1, y0 + 1);
  if (a == nd || b == nd || c == nd || d == nd) return std::nullopt;
  return (a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty;
}

}  // namespace aerotri
