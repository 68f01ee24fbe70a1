// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/terrain.h"

#include <algorithm>
#include <functional>
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
float Bilinear(const std::vector<float>& grid, int cols, int rows, double fx, double fy) {
  fx = std::clamp(fx, 0.0, cols - 1.0);
  fy = std::clamp(fy, 0.0, rows - 1.0);
  const int x0 = std::min(static_cast<int>(fx), cols - 2 < 0 ? 0 : cols - 2);
  const int y0 = std::min(static_cast<int>(fy), rows - 2 < 0 ? 0 : rows - 2);
  const int x1 = std::min(x0 + 1, cols - 1), y1 = std::min(y0 + 1, rows - 1);
  const double tx = fx - x0, ty = fy - y0;
  auto at = [&](int y, int x) { return grid[static_cast<size_t>(y) * cols + x]; };
  const float a = at(y0, x0), b = at(y0, x1);
  const float c = at(y1, x0), d = at(y1, x1);
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

GroundFilter::GroundFilter(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const GroundFilterOptions& o)
    : o_(o), lo_(lo), hi_(hi) {
  if (!(o.cell_m > 0) || !(o.max_window_m > 0) || !(o.slope >= 0) || !(o.elevation_threshold_m >= 0)) {
    throw InvalidArgument("ground filter: cell, window and thresholds must be positive");
  }
  nx_ = static_cast<int>((hi.x() - lo.x()) / o.cell_m) + 1;
  ny_ = static_cast<int>((hi.y() - lo.y()) / o.cell_m) + 1;
  if (!(hi.x() >= lo.x() && hi.y() >= lo.y()) || static_cast<double>(nx_) * ny_ > 2e8) {
    throw InvalidArgument("ground filter: " + std::to_string(nx_) + " x " + std::to_string(ny_) +
                          " cells is too many; choose a larger cell");
  }
  zmin_.assign(static_cast<size_t>(nx_) * ny_, kNodata);
}

double GroundFilter::Reach() const { return o_.cell_m; }

long long GroundFilter::CellOf(const Eigen::Vector3d& p) const {
  const int x = std::min(nx_ - 1, static_cast<int>((p.x() - lo_.x()) / o_.cell_m));
  const int y = std::min(ny_ - 1, static_cast<int>((hi_.y() - p.y()) / o_.cell_m));
  return static_cast<long long>(y) * nx_ + x;
}

Eigen::Vector2d GroundFilter::CellCentre(long long cell) const {
  const long long y = cell / nx_, x = cell % nx_;
  return {lo_.x() + (x + 0.5) * o_.cell_m, hi_.y() - (y + 0.5) * o_.cell_m};
}

std::vector<bool> GroundFilter::Isolated(const std::vector<Eigen::Vector3d>& xyz) const {
  // A 3D voxel grid of half a cell; a point with fewer than
  // noise_min_neighbours others in its voxel and the 26 around it is noise.
  const double v = 0.5 * o_.cell_m;
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return ((i & 0x1FFFFF) << 42) | ((j & 0x1FFFFF) << 21) | (k & 0x1FFFFF);
  };
  auto voxel_of = [&](const Eigen::Vector3d& p) {
    return Eigen::Matrix<std::int64_t, 3, 1>(static_cast<std::int64_t>(std::floor((p.x() - lo_.x()) / v)),
                                             static_cast<std::int64_t>(std::floor((p.y() - lo_.y()) / v)),
                                             static_cast<std::int64_t>(std::floor((p.z() - lo_.z()) / v)) + (1 << 19));
  };
  std::unordered_map<std::int64_t, int> voxels;
  voxels.reserve(xyz.size() / 4 + 16);
  for (const auto& p : xyz) {
    const auto q = voxel_of(p);
    ++voxels[key(q[0], q[1], q[2])];
  }
  std::vector<bool> isolated(xyz.size(), false);
  for (size_t i = 0; i < xyz.size(); ++i) {
    const auto q = voxel_of(xyz[i]);
    int n = -1;  // not itself
    for (int dz = -1; dz <= 1 && n < o_.noise_min_neighbours; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = voxels.find(key(q[0] + dx, q[1] + dy, q[2] + dz));
          if (it != voxels.end()) n += it->second;
        }
      }
    }
    isolated[i] = n < o_.noise_min_neighbours;
  }
  return isolated;
}

void GroundFilter::AddMinimumSurface(const std::vector<Eigen::Vector3d>& xyz, const std::vector<bool>& isolated,
                                     const std::function<bool(const Eigen::Vector2d&)>& owns) {
  // The 5th percentile of each cell's heights, isolated points aside; the
  // cells are numbered within the points' own bounding window.
  int x0 = nx_, y0 = ny_, x1 = -1, y1 = -1;
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (isolated[i]) continue;
    const long long c = CellOf(xyz[i]);
    const int x = static_cast<int>(c % nx_), y = static_cast<int>(c / nx_);
    x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
  if (x1 < 0) return;
  const int w = x1 - x0 + 1;
  auto local = [&](size_t i) -> long long {
    if (isolated[i]) return -1;
    const long long c = CellOf(xyz[i]);
    return static_cast<long long>(c / nx_ - y0) * w + (c % nx_ - x0);
  };
  CellHeights heights(static_cast<size_t>(w) * (y1 - y0 + 1));
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (const long long c = local(i); c >= 0) heights.Count(static_cast<size_t>(c));
  }
  heights.Allocate();
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (const long long c = local(i); c >= 0) heights.Add(static_cast<size_t>(c), static_cast<float>(xyz[i].z()));
  }
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const size_t cell = static_cast<size_t>(y - y0) * w + (x - x0);
      if (heights.empty(cell)) continue;
      const long long global = static_cast<long long>(y) * nx_ + x;
      if (owns && !owns(CellCentre(global))) continue;
      float* k = heights.begin(cell) + heights.size(cell) / 20;
      std::nth_element(heights.begin(cell), k, heights.end(cell));
      zmin_[static_cast<size_t>(y) * nx_ + x] = *k;
    }
  }
}

void GroundFilter::FinishSurface() {
  const cv::Mat zmin(ny_, nx_, CV_32F, zmin_.data());
  const cv::Mat empty = zmin == kNodata;
  const double c = o_.cell_m;
  cv::Mat surface = Filled(zmin);

  // 2. Progressive openings by discs: a cell that drops by more than the
  // slope allows over the radius is part of an object.
  cv::Mat object(ny_, nx_, CV_8U, cv::Scalar(0));
  cv::Mat previous = surface.clone();
  const int max_radius = std::max(1, static_cast<int>(std::ceil(0.5 * o_.max_window_m / c)));
  for (int r = 1; r <= max_radius; ++r) {
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
    cv::Mat opened;
    cv::morphologyEx(previous, opened, cv::MORPH_OPEN, disc, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
    const cv::Mat drop = previous - opened;
    object |= drop > o_.slope * r * c;
    previous = opened;
  }

  // 3. Provisional ground: the minimum surface without objects, filled under them.
  cv::Mat ground = zmin.clone();
  ground.setTo(kNodata, object | empty);
  if (cv::countNonZero(ground != kNodata) == 0) ground = zmin.clone();  // all objects: keep the surface
  ground = Filled(ground);
  cv::Mat gx, gy, slope;
  cv::Sobel(ground, gx, CV_32F, 1, 0, 3, 1.0 / (8.0 * c), 0, cv::BORDER_REPLICATE);
  cv::Sobel(ground, gy, CV_32F, 0, 1, 3, 1.0 / (8.0 * c), 0, cv::BORDER_REPLICATE);
  cv::magnitude(gx, gy, slope);
  ground_.assign(ground.begin<float>(), ground.end<float>());
  slope_.assign(slope.begin<float>(), slope.end<float>());
}

std::uint8_t GroundFilter::Classify(const Eigen::Vector3d& p, bool isolated, GroundFilterSummary* s) const {
  // 4. Points by their height above that ground.
  if (ground_.empty()) throw InvalidArgument("ground filter: FinishSurface() first");
  const double c = o_.cell_m;
  const double fx = (p.x() - lo_.x()) / c - 0.5, fy = (hi_.y() - p.y()) / c - 0.5;
  const double dz = p.z() - Bilinear(ground_, nx_, ny_, fx, fy);
  const double band = o_.elevation_threshold_m + o_.elevation_scalar * Bilinear(slope_, nx_, ny_, fx, fy);
  if (isolated && dz > band) {
    if (s) ++s->noise;
    return kHighNoise;
  }
  if (isolated || dz < -o_.noise_below_m) {
    if (s) ++s->noise;
    return kLowNoise;
  }
  if (std::abs(dz) <= band) {
    if (s) ++s->ground;
    return kGround;
  }
  if (s) ++s->above;
  return kUnclassified;
}

std::vector<std::uint8_t> ClassifyGround(const std::vector<Eigen::Vector3d>& xyz, const GroundFilterOptions& o,
                                         GroundFilterSummary* summary) {
  if (!(o.cell_m > 0) || !(o.max_window_m > 0) || !(o.slope >= 0) || !(o.elevation_threshold_m >= 0)) {
    throw InvalidArgument("ground filter: cell, window and thresholds must be positive");
  }
  std::vector<std::uint8_t> classes(xyz.size(), kUnclassified);
  if (xyz.empty()) return classes;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& p : xyz) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  GroundFilter filter(lo, hi, o);
  const std::vector<bool> isolated = filter.Isolated(xyz);
  filter.AddMinimumSurface(xyz, isolated, nullptr);
  filter.FinishSurface();
  GroundFilterSummary s;
  s.grid_width = filter.grid_width();
  s.grid_height = filter.grid_height();
  for (size_t i = 0; i < xyz.size(); ++i) classes[i] = filter.Classify(xyz[i], isolated[i], &s);
  if (summary) *summary = s;
  return classes;
}

Raster RasterizeDtm(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::uint8_t>& classes,
                    const Raster& dsm, const std::filesystem::path& work_dir, DtmSummary* summary) {
  if (classes.size() != xyz.size()) throw InvalidArgument("DTM: one class per point is needed");
  Raster dtm = dsm;
  std::fill(dtm.values.begin(), dtm.values.end(), static_cast<float>(dsm.nodata));
  SetCellMedians(&dtm, xyz, [&](size_t i) { return classes[i] == kGround; }, nullptr);
  FinishDtm(&dtm, dsm, work_dir, summary);
  return dtm;
}

void FinishDtm(Raster* dtm_in, const Raster& dsm, const std::filesystem::path& work_dir, DtmSummary* summary) {
  Raster& dtm = *dtm_in;
  const float nd = static_cast<float>(dsm.nodata);
  DtmSummary s;
  for (float v : dtm.values) s.cells_ground += v != nd;
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
}

}  // namespace aerotri
