// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/terrain.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <opencv2/imgproc.hpp>

#include "libphoto/base/error.h"
#include "libphoto/export/cell_heights.h"
#include "libphoto/export/dsm.h"

namespace aerotri {
namespace {

constexpr float kNodata = -9999.0f;

// Bilinear value of a full (no nodata) grid at fractional cell (fx, fy),
// clamped to the grid.
float Bilinear(const cv::Mat& grid, double fx, double fy) {
  fx = std::clamp(fx, 0.0, grid.cols - 1.0);
  fy = std::clamp(fy, 0.0, grid.rows - 1.0);
  const int x0 = std::min(static_cast<int>(fx), grid.cols - 2 < 0 ? 0 : grid.cols - 2);
  const int y0 = std::min(static_cast<int>(fy), grid.rows - 2 < 0 ? 0 : grid.rows - 2);
  const int x1 = std::min(x0 + 1, grid.cols - 1), y1 = std::min(y0 + 1, grid.rows - 1);
  const double tx = fx - x0, ty = fy - y0;
  const float a = grid.at<float>(y0, x0), b = grid.at<float>(y0, x1);
  const float c = grid.at<float>(y1, x0), d = grid.at<float>(y1, x1);
  return static_cast<float>((a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty);
}

// Nodata cells of `grid` filled from the cells with data, all of them.
cv::Mat Filled(const cv::Mat& grid) {
  Raster r;
  r.width = grid.cols;
  r.height = grid.rows;
  r.nodata = kNodata;
  r.values.assign(grid.begin<float>(), grid.end<float>());
  const std::vector<float> filled = FilledNodata(r, std::max(r.width, r.height) + 1.0);
  cv::Mat out(grid.rows, grid.cols, CV_32F);
  std::copy(filled.begin(), filled.end(), out.begin<float>());
  return out;
}

}  // namespace

std::vector<std::uint8_t> ClassifyGround(const std::vector<Eigen::Vector3d>& xyz, const GroundFilterOptions& o,
                                         GroundFilterSummary* summary) {
  if (!(o.cell_m > 0) || !(o.max_window_m > 0) || !(o.slope >= 0) || !(o.elevation_threshold_m >= 0)) {
    throw InvalidArgument("ground filter: cell, window and thresholds must be positive");
  }
  std::vector<std::uint8_t> classes(xyz.size(), kUnclassified);
  if (xyz.empty()) return classes;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const auto& p : xyz) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  const double c = o.cell_m;
  const int nx = static_cast<int>((hi.x() - lo.x()) / c) + 1, ny = static_cast<int>((hi.y() - lo.y()) / c) + 1;
  if (static_cast<double>(nx) * ny > 2e8) {
    throw InvalidArgument("ground filter: " + std::to_string(nx) + " x " + std::to_string(ny) +
                          " cells is too many; choose a larger cell");
  }
  auto cell_of = [&](const Eigen::Vector3d& p) {
    return std::pair<int, int>(std::min(nx - 1, static_cast<int>((p.x() - lo.x()) / c)),
                               std::min(ny - 1, static_cast<int>((hi.y() - p.y()) / c)));
  };

  // Isolated points: a 3D voxel grid of half a cell; a point with fewer than
  // noise_min_neighbours others in its voxel and the 26 around it is noise.
  const double v = 0.5 * c;
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return ((i & 0x1FFFFF) << 42) | ((j & 0x1FFFFF) << 21) | (k & 0x1FFFFF);
  };
  std::unordered_map<std::int64_t, int> voxels;
  voxels.reserve(xyz.size() / 4 + 16);
  const double z0 = xyz.front().z();
  auto voxel_of = [&](const Eigen::Vector3d& p) {
    return Eigen::Matrix<std::int64_t, 3, 1>(static_cast<std::int64_t>(std::floor((p.x() - lo.x()) / v)),
                                             static_cast<std::int64_t>(std::floor((p.y() - lo.y()) / v)),
                                             static_cast<std::int64_t>(std::floor((p.z() - z0) / v)) + (1 << 19));
  };
  for (const auto& p : xyz) {
    const auto q = voxel_of(p);
    ++voxels[key(q[0], q[1], q[2])];
  }
  std::vector<bool> isolated(xyz.size(), false);
  for (size_t i = 0; i < xyz.size(); ++i) {
    const auto q = voxel_of(xyz[i]);
    int n = -1;  // not itself
    for (int dz = -1; dz <= 1 && n < o.noise_min_neighbours; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = voxels.find(key(q[0] + dx, q[1] + dy, q[2] + dz));
          if (it != voxels.end()) n += it->second;
        }
      }
    }
    isolated[i] = n < o.noise_min_neighbours;
  }

  // 1. Minimum surface: the 5th percentile of each cell's heights.
  cv::Mat zmin(ny, nx, CV_32F, cv::Scalar(kNodata));
  {
    CellHeights heights(static_cast<size_t>(nx) * ny);
    for (size_t i = 0; i < xyz.size(); ++i) {
      if (isolated[i]) continue;
      const auto [x, y] = cell_of(xyz[i]);
      heights.Count(static_cast<size_t>(y) * nx + x);
    }
    heights.Allocate();
    for (size_t i = 0; i < xyz.size(); ++i) {
      if (isolated[i]) continue;
      const auto [x, y] = cell_of(xyz[i]);
      heights.Add(static_cast<size_t>(y) * nx + x, static_cast<float>(xyz[i].z()));
    }
    for (int y = 0; y < ny; ++y) {
      for (int x = 0; x < nx; ++x) {
        const size_t cell = static_cast<size_t>(y) * nx + x;
        if (heights.empty(cell)) continue;
        float* k = heights.begin(cell) + heights.size(cell) / 20;
        std::nth_element(heights.begin(cell), k, heights.end(cell));
        zmin.at<float>(y, x) = *k;
      }
    }
  }
  const cv::Mat empty = zmin == kNodata;
  cv::Mat surface = Filled(zmin);

  // 2. Progressive openings by discs: a cell that drops by more than the
  // slope allows over the radius is part of an object.
  cv::Mat object(ny, nx, CV_8U, cv::Scalar(0));
  cv::Mat previous = surface.clone();
  const int max_radius = std::max(1, static_cast<int>(std::ceil(0.5 * o.max_window_m / c)));
  for (int r = 1; r <= max_radius; ++r) {
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
    cv::Mat opened;
    cv::morphologyEx(previous, opened, cv::MORPH_OPEN, disc, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
    const cv::Mat drop = previous - opened;
    object |= drop > o.slope * r * c;
    previous = opened;
  }

  // 3. Provisional ground: the minimum surface without objects, filled under them.
  cv::Mat ground = zmin.clone();
  ground.setTo(kNodata, object | empty);
  if (cv::countNonZero(ground != kNodata) == 0) ground = zmin.clone();  // all objects: keep the surface
  ground = Filled(ground);
  cv::Mat gx, gy;
  cv::Sobel(ground, gx, CV_32F, 1, 0, 3, 1.0 / (8.0 * c), 0, cv::BORDER_REPLICATE);
  cv::Sobel(ground, gy, CV_32F, 0, 1, 3, 1.0 / (8.0 * c), 0, cv::BORDER_REPLICATE);
  cv::Mat slope;
  cv::magnitude(gx, gy, slope);

  // 4. Points by their height above that ground.
  GroundFilterSummary s;
  s.grid_width = nx;
  s.grid_height = ny;
  for (size_t i = 0; i < xyz.size(); ++i) {
    const double fx = (xyz[i].x() - lo.x()) / c - 0.5, fy = (hi.y() - xyz[i].y()) / c - 0.5;
    const double dz = xyz[i].z() - Bilinear(ground, fx, fy);
    const double band = o.elevation_threshold_m + o.elevation_scalar * Bilinear(slope, fx, fy);
    if (isolated[i] && dz > band) {
      classes[i] = kHighNoise;
      ++s.noise;
    } else if (isolated[i] || dz < -o.noise_below_m) {
      classes[i] = kLowNoise;
      ++s.noise;
    } else if (std::abs(dz) <= band) {
      classes[i] = kGround;
      ++s.ground;
    } else {
      ++s.above;
    }
  }
  if (summary) *summary = s;
  return classes;
}

Raster RasterizeDtm(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::uint8_t>& classes,
                    const Raster& dsm, const std::filesystem::path& work_dir, DtmSummary* summary) {
  if (classes.size() != xyz.size()) throw InvalidArgument("DTM: one class per point is needed");
  Raster dtm = dsm;
  const float nd = static_cast<float>(dsm.nodata);
  const double x0 = dsm.geotransform[0], y0 = dsm.geotransform[3];
  const double dx = dsm.geotransform[1], dy = -dsm.geotransform[5];
  auto cell_of = [&](size_t i) -> long long {
    if (classes[i] != kGround) return -1;
    const int cx = static_cast<int>(std::floor((xyz[i].x() - x0) / dx));
    const int cy = static_cast<int>(std::floor((y0 - xyz[i].y()) / dy));
    if (cx < 0 || cy < 0 || cx >= dsm.width || cy >= dsm.height) return -1;
    return static_cast<long long>(cy) * dsm.width + cx;
  };
  CellHeights cells(dsm.values.size());
  for (size_t i = 0; i < xyz.size(); ++i) {
    const long long c = cell_of(i);
    if (c >= 0) cells.Count(static_cast<size_t>(c));
  }
  cells.Allocate();
  for (size_t i = 0; i < xyz.size(); ++i) {
    const long long c = cell_of(i);
    if (c >= 0) cells.Add(static_cast<size_t>(c), static_cast<float>(xyz[i].z()));
  }
  DtmSummary s;
  for (size_t k = 0; k < dsm.values.size(); ++k) {
    if (cells.empty(k)) {
      dtm.values[k] = nd;
      continue;
    }
    float* mid = cells.begin(k) + cells.size(k) / 2;
    std::nth_element(cells.begin(k), mid, cells.end(k));
    dtm.values[k] = *mid;
    ++s.cells_ground;
  }
  if (s.cells_ground == 0) throw InvalidArgument("DTM: no ground points");
  const std::vector<float> filled = FilledNodata(dtm, std::max(dtm.width, dtm.height) + 1.0, work_dir);
  for (size_t k = 0; k < dtm.values.size(); ++k) {
    if (dsm.values[k] == nd) {
      dtm.values[k] = nd;
    } else if (dtm.values[k] == nd) {
      dtm.values[k] = filled[k];
      ++s.cells_interpolated;
    }
  }
  if (summary) *summary = s;
  return dtm;
}

}  // namespace aerotri
