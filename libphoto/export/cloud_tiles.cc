// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/cloud_tiles.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>

#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/base/parallel.h"
#include "libphoto/export/copc.h"
#include "libphoto/export/point_cloud.h"

namespace aerotri {
namespace {

// x, y, z (double), r, g, b: 27 bytes, as PLY's.
constexpr std::size_t kRecord = 27;
constexpr std::size_t kFlushBytes = std::size_t{1} << 19;

long long TileIndex(double v, double tile_m) { return static_cast<long long>(std::floor(v / tile_m)); }

void ReadRecords(const std::filesystem::path& path, CloudTile* tile) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return;
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  if (ec || bytes % kRecord != 0) throw IoError(path.string(), "a damaged tile of the dense cloud");
  std::ifstream in(path, std::ios::binary);
  std::vector<char> data(bytes);
  if (!in.read(data.data(), static_cast<std::streamsize>(bytes))) {
    throw IoError(path.string(), "cannot read a tile of the dense cloud");
  }
  const std::size_t n = bytes / kRecord;
  tile->xyz.reserve(tile->xyz.size() + n);
  tile->rgb.reserve(tile->rgb.size() + n);
  for (std::size_t k = 0; k < n; ++k) {
    const char* r = data.data() + k * kRecord;
    Eigen::Vector3d p;
    std::memcpy(p.data(), r, 24);
    std::array<std::uint8_t, 3> c;
    std::memcpy(c.data(), r + 24, 3);
    tile->xyz.push_back(p);
    tile->rgb.push_back(c);
  }
}

}  // namespace

TiledCloud::TiledCloud(const std::filesystem::path& dir, double tile_m, double halo_m)
    : dir_(dir), tile_m_(tile_m), halo_m_(halo_m) {
  if (!(tile_m > 0) || !(halo_m >= 0) || !(halo_m < tile_m)) {
    throw InvalidArgument("tiled cloud: tiles of " + std::to_string(tile_m) + " m with a halo of " +
                          std::to_string(halo_m) + " m (a positive tile, a smaller halo expected)");
  }
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
  std::filesystem::create_directories(dir_, ec);
  if (ec) throw IoError(dir_.string(), "cannot create folder: " + ec.message());
}

TiledCloud::~TiledCloud() { Remove(); }

std::filesystem::path TiledCloud::File(long long tx, long long ty, bool halo) const {
  return dir_ / (std::to_string(tx) + "_" + std::to_string(ty) + (halo ? ".halo" : ".own"));
}

void TiledCloud::FlushTile(long long tx, long long ty, Buffers* b, std::size_t at_least) {
  for (const bool halo : {false, true}) {
    std::vector<char>& buffer = halo ? b->halo : b->own;
    if (buffer.empty() || buffer.size() < at_least) continue;
    const std::filesystem::path path = File(tx, ty, halo);
    std::ofstream out(path, std::ios::binary | std::ios::app);
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    out.close();
    if (!out) {
      throw IoError(path.string(), std::string("write failed: ") + std::strerror(errno) +
                                       " (disk full? the dense cloud's tiles need about 28 bytes a point)");
    }
    buffer.clear();
    buffer.shrink_to_fit();
  }
}

void TiledCloud::Append(long long tx, long long ty, bool halo, const char* record) {
  Buffers& b = buffers_[{tx, ty}];
  std::vector<char>& buffer = halo ? b.halo : b.own;
  buffer.insert(buffer.end(), record, record + kRecord);
  ++(halo ? b.halo_count : b.own_count);
  if (buffer.size() >= kFlushBytes) FlushTile(tx, ty, &b, kFlushBytes);
}

void TiledCloud::Add(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::array<std::uint8_t, 3>>& rgb) {
  if (!tiles_.empty()) throw InvalidArgument("tiled cloud: points added after Finish()");
  char record[kRecord];
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    const Eigen::Vector3d& p = xyz[i];
    if (!p.allFinite()) continue;
    std::memcpy(record, p.data(), 24);
    const std::array<std::uint8_t, 3> c = i < rgb.size() ? rgb[i] : std::array<std::uint8_t, 3>{0, 0, 0};
    std::memcpy(record + 24, c.data(), 3);
    const long long tx = TileIndex(p.x(), tile_m_), ty = TileIndex(p.y(), tile_m_);
    Append(tx, ty, false, record);
    // The halo of the neighbours whose square, grown by halo_m, holds it.
    const long long hx0 = TileIndex(p.x() - halo_m_, tile_m_), hx1 = TileIndex(p.x() + halo_m_, tile_m_);
    const long long hy0 = TileIndex(p.y() - halo_m_, tile_m_), hy1 = TileIndex(p.y() + halo_m_, tile_m_);
    for (long long y = hy0; y <= hy1; ++y) {
      for (long long x = hx0; x <= hx1; ++x) {
        if (x != tx || y != ty) Append(x, y, true, record);
      }
    }
    lo_ = lo_.cwiseMin(p);
    hi_ = hi_.cwiseMax(p);
    ++count_;
  }
}

void TiledCloud::Finish() {
  for (auto& [key, b] : buffers_) {
    FlushTile(key.first, key.second, &b, 0);
    // A tile with a halo alone still owns the cells centred in it whose
    // points lie across its edge (a cloud starting just past a tile's edge).
    tiles_.push_back(key);
  }
  buffers_.clear();
  std::sort(tiles_.begin(), tiles_.end(),
            [](const auto& a, const auto& b) { return a.second != b.second ? a.second < b.second : a.first < b.first; });
  ReleaseFreedMemory();
}

CloudTile TiledCloud::Read(std::size_t k) const {
  CloudTile tile;
  tile.tx = tiles_.at(k).first;
  tile.ty = tiles_.at(k).second;
  ReadRecords(File(tile.tx, tile.ty, false), &tile);
  tile.own = tile.xyz.size();
  ReadRecords(File(tile.tx, tile.ty, true), &tile);
  return tile;
}

bool TiledCloud::Owns(long long tx, long long ty, const Eigen::Vector2d& xy) const {
  return TileIndex(xy.x(), tile_m_) == tx && TileIndex(xy.y(), tile_m_) == ty;
}

void TiledCloud::Remove() {
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

double CloudProductsHalo(const CloudProductOptions& o) {
  // A cell owned by a tile has its centre in it, so its points lie within
  // half a cell of the tile; the noise test of such a point looks one
  // ground-filter cell further (GroundFilter::Reach). A margin for rounding.
  const double cell = o.classify ? o.ground.cell_m : 0.0;
  return 0.5 * std::max(o.dsm.resolution_m, cell) + cell + 0.01;
}

CloudProducts WriteCloudProducts(const TiledCloud& cloud, const std::filesystem::path& las,
                                 const std::filesystem::path& ply, const CloudProductOptions& o,
                                 const ProgressCallback& progress) {
  if (cloud.count() == 0) throw InvalidArgument("cloud products: the point cloud is empty");
  if (cloud.halo_m() + 1e-9 < CloudProductsHalo(o)) {
    throw InvalidArgument("cloud products: tiles with a halo of " + std::to_string(cloud.halo_m()) + " m; " +
                          std::to_string(CloudProductsHalo(o)) + " m needed");
  }
  const std::size_t n = cloud.num_tiles();
  CloudProducts out;
  out.dsm = DsmGrid(cloud.lo().head<2>(), cloud.hi().head<2>(), o.raster_wkt, o.dsm);
  std::unique_ptr<GroundFilter> filter;
  if (o.classify) filter = std::make_unique<GroundFilter>(cloud.lo(), cloud.hi(), o.ground);
  std::vector<std::vector<bool>> isolated(n);

  // Pass 1: DSM cells, minimum-surface cells, isolated points.
  std::mutex mutex;
  std::size_t done = 0;
  ParallelFor(n, o.threads, [&](std::size_t k) {
    const CloudTile tile = cloud.Read(k);
    auto owns = [&](const Eigen::Vector2d& xy) { return cloud.Owns(tile.tx, tile.ty, xy); };
    SetCellMedians(&out.dsm, tile.xyz, nullptr, owns);
    if (filter) {
      isolated[k] = filter->Isolated(tile.xyz);
      filter->AddMinimumSurface(tile.xyz, isolated[k], owns);
    }
    std::lock_guard<std::mutex> lock(mutex);
    ++done;
    ReportProgress(progress, 0.5 * done / n, "tile " + std::to_string(done) + " of " + std::to_string(n) + ": surfaces");
  });
  ReleaseFreedMemory();
  FillDsmHoles(&out.dsm, o.dsm, &out.dsm_summary);
  if (filter) filter->FinishSurface();

  // Pass 2: classes, DTM cells, the files (when any is asked for).
  const bool files = !las.empty() || !ply.empty();
  if (!files && !filter) return out;
  Raster dtm = out.dsm;
  std::fill(dtm.values.begin(), dtm.values.end(), static_cast<float>(dtm.nodata));
  std::optional<LasWriter> las_writer;
  std::optional<CopcWriter> copc_writer;  // a path ending in .copc.laz
  std::optional<PlyWriter> ply_writer;
  if (IsCopcPath(las)) {
    copc_writer.emplace(las, cloud.count(), cloud.lo(), cloud.hi(), o.las_wkt);
  } else if (!las.empty()) {
    las_writer.emplace(las, cloud.count(), cloud.lo(), cloud.hi(), o.las_wkt);
  }
  if (!ply.empty()) ply_writer.emplace(ply, cloud.count(), o.crs_name);
  struct Done {
    CloudTile tile;
    std::vector<std::uint8_t> classes;
    GroundFilterSummary summary;
  };
  std::vector<Done> slots(n);
  ParallelForInOrder(
      n, o.threads,
      [&](std::size_t k) {
        Done d;
        d.tile = cloud.Read(k);
        const CloudTile& tile = d.tile;
        d.classes.assign(tile.xyz.size(), kUnclassified);
        if (filter) {
          for (std::size_t i = 0; i < tile.xyz.size(); ++i) {
            d.classes[i] = filter->Classify(tile.xyz[i], isolated[k][i], i < tile.own ? &d.summary : nullptr);
          }
          auto owns = [&](const Eigen::Vector2d& xy) { return cloud.Owns(tile.tx, tile.ty, xy); };
          SetCellMedians(&dtm, tile.xyz, [&](std::size_t i) { return d.classes[i] == kGround; }, owns);
        }
        isolated[k] = std::vector<bool>();
        slots[k] = std::move(d);
      },
      [&](std::size_t k) {
        Done d = std::move(slots[k]);
        slots[k] = Done();
        for (std::size_t i = 0; i < d.tile.own; ++i) {
          if (las_writer) las_writer->Add(d.tile.xyz[i], d.tile.rgb[i], d.classes[i]);
          if (copc_writer) copc_writer->Add(d.tile.xyz[i], d.tile.rgb[i], d.classes[i]);
          if (ply_writer) ply_writer->Add(d.tile.xyz[i], d.tile.rgb[i]);
        }
        out.ground.ground += d.summary.ground;
        out.ground.above += d.summary.above;
        out.ground.noise += d.summary.noise;
        ReportProgress(progress, 0.5 + 0.5 * (k + 1) / n,
                       "tile " + std::to_string(k + 1) + " of " + std::to_string(n) + ": classes and files");
        ReleaseFreedMemory();
      },
      2 * std::max(1u, o.threads));
  if (las_writer) las_writer->Commit();
  if (copc_writer) copc_writer->Commit();
  if (ply_writer) ply_writer->Commit();
  if (filter) {
    out.ground.grid_width = filter->grid_width();
    out.ground.grid_height = filter->grid_height();
    if (out.ground.ground > 0) {
      FinishDtm(&dtm, out.dsm, o.dsm.work_dir, &out.dtm_summary);
      out.dtm = std::move(dtm);
      out.has_dtm = true;
    }
  }
  return out;
}

}  // namespace aerotri
