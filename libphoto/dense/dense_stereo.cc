// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/dense/dense_stereo.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <mutex>
#include <optional>
#include <unordered_map>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/base/parallel.h"

namespace aerotri {
namespace {

constexpr double kDeg = M_PI / 180.0;

struct Partner {
  int image = -1;
  int shared = 0;
  double angle_deg = 0.0;
};

// Rectified stereo needs the baseline across both views, as in a survey
// strip: each optical axis at least 60 degrees from it. A pair that moved
// along its view (a ground-level walk, a strip's consecutive oblique frames)
// has its epipole in the image and rectifies into a useless sliver.
bool SideBySide(const Image& a, const Image& b) {
  const Eigen::Vector3d base = (b.pose.centre_in_world - a.pose.centre_in_world).normalized();
  const Eigen::Vector3d za = a.pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d zb = b.pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  const double limit = std::cos(60.0 * kDeg);
  return std::abs(base.dot(za)) < limit && std::abs(base.dot(zb)) < limit;
}

// For each registered image, the neighbours to match it with, best first.
std::vector<std::vector<Partner>> ChoosePartners(const SparseModel& model, const DenseOptions& o) {
  const size_t n = model.images.size();
  std::vector<std::vector<int>> images_of_point(model.points.size());
  for (const Observation& obs : model.observations) {
    if (model.images[obs.image].registered) images_of_point[obs.point].push_back(obs.image);
  }
  std::map<std::pair<int, int>, std::vector<float>> angles;
  for (size_t p = 0; p < model.points.size(); ++p) {
    const auto& ims = images_of_point[p];
    if (ims.size() < 2 || ims.size() > 40) continue;
    const Eigen::Vector3d x = model.points[p].position;
    for (size_t a = 0; a < ims.size(); ++a) {
      for (size_t b = a + 1; b < ims.size(); ++b) {
        const Eigen::Vector3d ra = (x - model.images[ims[a]].pose.centre_in_world).normalized();
        const Eigen::Vector3d rb = (x - model.images[ims[b]].pose.centre_in_world).normalized();
        auto& v = angles[{std::min(ims[a], ims[b]), std::max(ims[a], ims[b])}];
        if (v.size() < 200) v.push_back(static_cast<float>(std::acos(std::clamp(ra.dot(rb), -1.0, 1.0)) / kDeg));
      }
    }
  }
  std::vector<std::vector<std::pair<double, Partner>>> scored(n), wide_scored(n);
  for (auto& [key, v] : angles) {
    if (v.size() < 30) continue;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    const double median = v[v.size() / 2];
    const bool wide = median > o.max_angle_deg && median <= o.max_angle_across_deg;
    if (median < o.min_angle_deg || (median > o.max_angle_deg && !wide)) continue;
    if (!SideBySide(model.images[key.first], model.images[key.second])) continue;
    const double weight = (median >= 5.0 && median <= 15.0) ? 1.0 : 0.5;
    const double score = weight * static_cast<double>(v.size());
    for (int k = 0; k < 2; ++k) {
      const int i = k == 0 ? key.first : key.second;
      const int j = k == 0 ? key.second : key.first;
      (wide ? wide_scored : scored)[i].push_back({score, {j, static_cast<int>(v.size()), median}});
    }
  }
  std::vector<std::vector<Partner>> best(n);
  for (size_t i = 0; i < n; ++i) {
    std::sort(scored[i].begin(), scored[i].end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    for (size_t k = 0; k < scored[i].size() && static_cast<int>(k) < o.partners_per_image; ++k) {
      best[i].push_back(scored[i][k].second);
    }
    // A photo with no neighbour at the preferred angles (a strip flown with
    // sparse exposures, or its end at a turn) takes its best wide ones (up
    // to max_angle_across_deg) rather than none: its ground would otherwise
    // be in no depth map of its own.
    if (best[i].empty()) {
      std::sort(wide_scored[i].begin(), wide_scored[i].end(),
                [](const auto& a, const auto& b) { return a.first > b.first; });
      for (size_t k = 0; k < wide_scored[i].size() && static_cast<int>(k) < o.partners_per_image; ++k) {
        best[i].push_back(wide_scored[i][k].second);
      }
    }
    // Across the strip as well as along it: the best partner whose baseline
    // turns at least 45 degrees from the best one's (a neighbouring strip),
    // so that ground seen from two strips is matched too.
    if (!o.partner_across || best[i].empty()) continue;
    const Eigen::Vector3d ci = model.images[i].pose.centre_in_world;
    const Eigen::Vector3d along = (model.images[best[i][0].image].pose.centre_in_world - ci).normalized();
    bool have_across = false;
    for (const Partner& p : best[i]) {
      const Eigen::Vector3d b = (model.images[p.image].pose.centre_in_world - ci).normalized();
      have_across |= std::abs(b.dot(along)) < std::cos(45.0 * kDeg);
    }
    if (have_across) continue;
    // Strips are often farther apart than a pair along them: the across
    // partner may have a wider angle (up to max_angle_across_deg).
    std::sort(wide_scored[i].begin(), wide_scored[i].end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    bool found = false;
    for (const auto* list : {&scored[i], &wide_scored[i]}) {
      for (const auto& [score, p] : *list) {
        const Eigen::Vector3d b = (model.images[p.image].pose.centre_in_world - ci).normalized();
        if (std::abs(b.dot(along)) < std::cos(45.0 * kDeg)) {
          best[i].push_back(p);
          found = true;
          break;
        }
      }
      if (found) break;
    }
  }
  return best;
}

// Voxel accumulator key: 21 bits per axis around the origin. (Voxels three
// times taller than wide were tried: 12 % fewer points but the DSM's median
// error on the sample survey grew from 2.6 to 3.2 cm, so they stay cubic.)
constexpr double kVoxelDepth = 1.0;
std::uint64_t VoxelKey(const Eigen::Vector3d& x, double res) {
  const auto q = [&](double v, double size) {
    return static_cast<std::uint64_t>(
        std::clamp<long long>(std::llround(std::floor(v / size)) + (1 << 20), 0, (1 << 21) - 1));
  };
  return (q(x.x(), res) << 42) | (q(x.y(), res) << 21) | q(x.z(), kVoxelDepth * res);
}

// Fusion tiles: the tile that owns a point is the one holding its voxel
// column (voxel indices floor(x / res), tile_voxels of them per side).
struct TileGrid {
  double res = 0.0;
  long long tile_voxels = 0;  // 0: not tiled
  std::pair<long long, long long> TileOf(double x, double y) const {
    auto div = [&](double v) {
      const long long voxel = static_cast<long long>(std::floor(v / res));
      return voxel >= 0 ? voxel / tile_voxels : -((-voxel - 1) / tile_voxels) - 1;  // floor division
    };
    return {div(x), div(y)};
  }
  bool operator==(const TileGrid& other) const { return res == other.res && tile_voxels == other.tile_voxels; }
};

// The points of one depth map on disk, so that fusion can run tile by tile
// (memory bounded by a tile, not the survey) and an interrupted run resumes.
// File "AERPTS02": uint64 count, double bbox[6] (min xyz, max xyz), double
// res, int64 tile_voxels (0: not tiled), uint64 tiles, then per tile {int64
// tx, ty, uint64 first record, count}, then count records (float32 x, y, z
// in the adjustment frame, uint8 r, g, b) sorted by tile. Fusion then reads
// only the records of the tile at hand: every depth map is read once over
// all tiles, not once per tile its bounding box meets (about nine times at
// 512-voxel tiles). "AERPTS01" (no res, tiles or table) is still read.
class DepthPoints {
 public:
  static constexpr size_t kRecord = 15;
  struct TileRange {
    long long tx, ty;
    std::uint64_t first, count;
  };
  void Add(const Eigen::Vector3d& x, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    const float v[3] = {static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z())};
    const size_t at = data_.size();
    data_.resize(at + kRecord);
    std::memcpy(&data_[at], v, 12);
    data_[at + 12] = static_cast<char>(r);
    data_[at + 13] = static_cast<char>(g);
    data_[at + 14] = static_cast<char>(b);
    lo_ = lo_.cwiseMin(x);
    hi_ = hi_.cwiseMax(x);
  }
  size_t count() const { return data_.size() / kRecord; }
  // The count in the file's header (Read with or without its points).
  std::uint64_t header_count() const { return header_count_; }
  // Writes the records sorted by the tile of grid that owns them, with the
  // table of tiles (grid.tile_voxels 0: as added, no table).
  void Write(const std::filesystem::path& path, const TileGrid& grid) const {
    std::vector<TileRange> table;
    std::vector<char> sorted;
    if (grid.tile_voxels > 0 && count() > 0) {
      std::vector<std::pair<std::pair<long long, long long>, std::uint32_t>> order(count());
      for (size_t k = 0; k < count(); ++k) {
        uint8_t rgb[3];
        const Eigen::Vector3d p = Point(k, rgb);  // as stored (float): as fusion will see it
        order[k] = {grid.TileOf(p.x(), p.y()), static_cast<std::uint32_t>(k)};
      }
      std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      sorted.resize(data_.size());
      for (size_t k = 0; k < order.size(); ++k) {
        std::memcpy(&sorted[k * kRecord], &data_[order[k].second * kRecord], kRecord);
        if (table.empty() || table.back().tx != order[k].first.first || table.back().ty != order[k].first.second) {
          table.push_back({order[k].first.first, order[k].first.second, k, 0});
        }
        ++table.back().count;
      }
    }
    const std::vector<char>& records = table.empty() ? data_ : sorted;
    WriteFileAtomically(path, [&](std::ostream& out) {
      const std::uint64_t n = count(), tiles = table.size();
      const std::int64_t tile_voxels = table.empty() ? 0 : grid.tile_voxels;
      const double res = table.empty() ? 0.0 : grid.res;
      out.write("AERPTS02", 8);
      out.write(reinterpret_cast<const char*>(&n), 8);
      out.write(reinterpret_cast<const char*>(lo_.data()), 24);
      out.write(reinterpret_cast<const char*>(hi_.data()), 24);
      out.write(reinterpret_cast<const char*>(&res), 8);
      out.write(reinterpret_cast<const char*>(&tile_voxels), 8);
      out.write(reinterpret_cast<const char*>(&tiles), 8);
      for (const TileRange& t : table) {
        const std::int64_t v[4] = {t.tx, t.ty, static_cast<std::int64_t>(t.first), static_cast<std::int64_t>(t.count)};
        out.write(reinterpret_cast<const char*>(v), 32);
      }
      out.write(records.data(), static_cast<std::streamsize>(records.size()));
    });
  }
  // Reads the header (bbox, count, tile table) and, with points, the
  // records: all of them, or with a tile, those the file files under that
  // tile of the same grid (all of them when the file's grid differs or it
  // has none; fusion keeps only the points its tile owns either way).
  static DepthPoints Read(const std::filesystem::path& path, bool points,
                          const std::optional<std::pair<long long, long long>>& tile = std::nullopt,
                          const TileGrid& grid = {}) {
    std::ifstream in(path, std::ios::binary);
    char magic[8];
    std::uint64_t n = 0;
    DepthPoints d;
    auto fail = [&]() { throw IoError(path.string(), "not a complete depth-point file; delete it to recompute"); };
    if (!in.read(magic, 8) || !in.read(reinterpret_cast<char*>(&n), 8) ||
        !in.read(reinterpret_cast<char*>(d.lo_.data()), 24) || !in.read(reinterpret_cast<char*>(d.hi_.data()), 24)) {
      fail();
    }
    const bool v2 = std::memcmp(magic, "AERPTS02", 8) == 0;
    if (!v2 && std::memcmp(magic, "AERPTS01", 8) != 0) fail();
    std::uint64_t tiles = 0;
    if (v2) {
      std::int64_t tile_voxels = 0;
      if (!in.read(reinterpret_cast<char*>(&d.grid_.res), 8) || !in.read(reinterpret_cast<char*>(&tile_voxels), 8) ||
          !in.read(reinterpret_cast<char*>(&tiles), 8) || tiles > n) {
        fail();
      }
      d.grid_.tile_voxels = tile_voxels;
      d.table_.resize(tiles);
      for (TileRange& t : d.table_) {
        std::int64_t v[4];
        if (!in.read(reinterpret_cast<char*>(v), 32) || v[2] < 0 || v[3] < 0 ||
            static_cast<std::uint64_t>(v[2]) + static_cast<std::uint64_t>(v[3]) > n) {
          fail();
        }
        t = {v[0], v[1], static_cast<std::uint64_t>(v[2]), static_cast<std::uint64_t>(v[3])};
      }
    }
    d.header_count_ = n;
    if (!points) return d;
    std::uint64_t first = 0, count = n;
    if (tile && !d.table_.empty() && d.grid_ == grid) {
      count = 0;
      for (const TileRange& t : d.table_) {
        if (t.tx == tile->first && t.ty == tile->second) {
          first = t.first;
          count = t.count;
        }
      }
    }
    d.data_.resize(count * kRecord);
    in.seekg(static_cast<std::streamoff>(first * kRecord), std::ios::cur);
    if (!in.read(d.data_.data(), static_cast<std::streamsize>(d.data_.size()))) {
      throw IoError(path.string(), "truncated depth-point file; delete it to recompute");
    }
    return d;
  }
  Eigen::Vector3d Point(size_t k, std::uint8_t* rgb) const {
    float v[3];
    std::memcpy(v, &data_[k * kRecord], 12);
    for (int c = 0; c < 3; ++c) rgb[c] = static_cast<std::uint8_t>(data_[k * kRecord + 12 + c]);
    return {v[0], v[1], v[2]};
  }
  const Eigen::Vector3d& lo() const { return lo_; }
  const Eigen::Vector3d& hi() const { return hi_; }
  // The records the file holds under a tile of its grid; its whole count
  // when the grids differ or it has no table.
  std::uint64_t CountIn(const std::pair<long long, long long>& tile, const TileGrid& grid) const {
    if (table_.empty() || !(grid_ == grid)) return header_count_;
    for (const TileRange& t : table_) {
      if (t.tx == tile.first && t.ty == tile.second) return t.count;
    }
    return 0;
  }

 private:
  std::vector<char> data_;
  std::uint64_t header_count_ = 0;
  TileGrid grid_;
  std::vector<TileRange> table_;
  Eigen::Vector3d lo_ = Eigen::Vector3d::Constant(1e300);
  Eigen::Vector3d hi_ = Eigen::Vector3d::Constant(-1e300);
};

// The fusion tiles at voxel size res.
TileGrid FusionGrid(double res, const DenseOptions& o) { return {res, o.tile_voxels > 0 ? o.tile_voxels : 512}; }

// Fuses depth-point files tile by tile: a tile holds at most tile_voxels x
// tile_voxels columns of voxels, and only the records each file holds under
// it are read for it. Within a tile the points are sorted by voxel and
// reduced (a sort beats a node hash map several times over at millions of
// voxels); tiles run on all cores.
//
// A share (index of count) fuses a contiguous run of the tiles in row order,
// the runs balanced by the depth records the tiles hold: the shares in index
// order fuse every tile once and hand the sink what one call would, in its
// order.
// One depth point on its way into a voxel.
struct FusionRecord {
  std::uint64_t key;
  float x, y, z;
  std::uint16_t file;
  std::uint8_t rgb[3];
};

// The depth-point files' headers: bounding boxes and tile tables.
struct FusionInputs {
  const std::vector<std::filesystem::path>& files;
  std::vector<DepthPoints> heads;
  std::vector<Eigen::Vector3d> lo, hi;
  TileGrid grid;
  double res = 0.0, tile = 0.0;
  long long tile_voxels = 0;
  bool Meets(size_t f, long long tx, long long ty) const {
    return !(hi[f].x() < tx * tile || lo[f].x() >= (tx + 1) * tile || hi[f].y() < ty * tile ||
             lo[f].y() >= (ty + 1) * tile);
  }
};

// A share's tiles: each tile's records (from the files' tile tables), and
// the share whose run holds the tile's middle record.
std::vector<std::pair<long long, long long>> ShareTiles(const FusionInputs& in,
                                                        const std::vector<std::pair<long long, long long>>& tiles,
                                                        const DenseShare& share) {
  const std::vector<std::filesystem::path>& files = in.files;
  std::vector<double> weight(tiles.size(), 0.0);
  double total = 0.0;
  for (size_t t = 0; t < tiles.size(); ++t) {
    const auto [tx, ty] = tiles[t];
    for (size_t f = 0; f < files.size(); ++f) {
      if (!in.Meets(f, tx, ty)) continue;
      weight[t] += static_cast<double>(in.heads[f].CountIn(tiles[t], in.grid));
    }
    total += weight[t];
  }
  std::vector<std::pair<long long, long long>> mine;
  double before = 0.0;
  for (size_t t = 0; t < tiles.size(); ++t) {
    const double middle = total > 0 ? (before + 0.5 * weight[t]) / total : (t + 0.5) / tiles.size();
    before += weight[t];
    if (std::min(share.count - 1, static_cast<int>(middle * share.count)) == share.index) mine.push_back(tiles[t]);
  }
  return mine;
}

// A tile's depth records, sorted by voxel (then file): the tile owns the
// voxels whose index lies in it, so tiles have no seams.
std::vector<FusionRecord> TileRecords(const FusionInputs& in, const std::pair<long long, long long>& tile_xy) {
  const std::vector<std::filesystem::path>& files = in.files;
  const auto [tx, ty] = tile_xy;
  const double res = in.res;
  const long long tile_voxels = in.tile_voxels;
  auto meets_tile = [&](size_t f) { return in.Meets(f, tx, ty); };
  // Reserved at the most the tile can receive: address space, not memory
  // (pages are resident once written), and no reallocation, which would
  // hold the old and the new array at once (up to 3x the records).
  std::uint64_t most = 0;
  for (size_t f = 0; f < files.size(); ++f) most += meets_tile(f) ? in.heads[f].CountIn(tile_xy, in.grid) : 0;
  std::vector<FusionRecord> records;
  records.reserve(most);
  for (size_t f = 0; f < files.size(); ++f) {
    if (!meets_tile(f) || in.heads[f].CountIn(tile_xy, in.grid) == 0) continue;
    const DepthPoints d = DepthPoints::Read(files[f], true, tile_xy, in.grid);
    for (size_t k = 0; k < d.count(); ++k) {
      FusionRecord r;
      const Eigen::Vector3d x = d.Point(k, r.rgb);
      // The tile owns the voxels whose index lies in it: no seams.
      const long long ix = static_cast<long long>(std::floor(x.x() / res));
      const long long iy = static_cast<long long>(std::floor(x.y() / res));
      if (ix < tx * tile_voxels || ix >= (tx + 1) * tile_voxels || iy < ty * tile_voxels ||
          iy >= (ty + 1) * tile_voxels) {
        continue;
      }
      r.key = VoxelKey(x, res);
      r.x = static_cast<float>(x.x());
      r.y = static_cast<float>(x.y());
      r.z = static_cast<float>(x.z());
      r.file = static_cast<std::uint16_t>(f);
      records.push_back(r);
    }
  }
  std::sort(records.begin(), records.end(), [](const FusionRecord& a, const FusionRecord& b) {
    return a.key != b.key ? a.key < b.key : a.file < b.file;
  });
  return records;
}

// The voxels (runs of one key) that enough depth maps agree on, each as
// its points' mean position and colour.
DenseCloud AgreedVoxels(const std::vector<FusionRecord>& records, double res, const DenseOptions& o) {
  DenseCloud part;
  // The voxels (runs of one key) and how many depth maps put a point in
  // each; a map's vote counts in its voxel and the voxels up to
  // agreement_voxels above and below (pairs at small angles disagree in
  // depth by a voxel or two where they agree in plan).
  std::vector<size_t> start;
  for (size_t a = 0; a < records.size(); ++a) {
    if (a == 0 || records[a].key != records[a - 1].key) start.push_back(a);
  }
  start.push_back(records.size());
  const size_t voxels = start.size() - 1;
  constexpr std::uint64_t kZMask = (std::uint64_t{1} << 21) - 1;
  auto column = [](std::uint64_t key) { return key >> 21; };
  // Distinct files over the voxels v0..v1 (consecutive runs).
  auto count_files = [&](size_t v0, size_t v1) {
    std::vector<std::uint16_t> files;
    for (size_t k = start[v0]; k < start[v1 + 1]; ++k) files.push_back(records[k].file);
    std::sort(files.begin(), files.end());
    return static_cast<int>(std::unique(files.begin(), files.end()) - files.begin());
  };
  // Where one depth map alone saw the ground (a strip's rim, seen by one
  // pair of photos), there is no second opinion to ask: its points stand.
  // A coarse cell (16 x 16 voxel columns) with points of two or more maps
  // asks for agreement.
  auto cell_of = [&](std::uint64_t key) { return ((key >> 46) << 17) | ((key >> 25) & 0x1FFFF); };
  std::unordered_map<std::uint64_t, std::pair<std::uint16_t, int>> maps_in_cell;  // first file, distinct files
  if (o.single_map_where_alone) {
    for (const FusionRecord& r : records) {
      auto [it, inserted] = maps_in_cell.try_emplace(cell_of(r.key), r.file, 1);
      if (!inserted && it->second.second == 1 && it->second.first != r.file) it->second.second = 2;
    }
  }
  for (size_t v = 0; v < voxels; ++v) {
    const std::uint64_t key = records[start[v]].key;
    const std::uint64_t z = key & kZMask;
    auto near = [&](size_t u) {
      const std::uint64_t other = records[start[u]].key;
      const std::uint64_t dz = (other & kZMask) > z ? (other & kZMask) - z : z - (other & kZMask);
      return column(other) == column(key) && dz <= static_cast<std::uint64_t>(o.agreement_voxels);
    };
    size_t v0 = v, v1 = v;
    while (v0 > 0 && near(v0 - 1)) --v0;
    while (v1 + 1 < voxels && near(v1 + 1)) ++v1;
    const int views = count_files(v0, v1);
    bool keep = views >= o.min_views;
    if (!keep && o.single_map_where_alone) {
      const auto it = maps_in_cell.find(cell_of(key));
      keep = it != maps_in_cell.end() && it->second.second == 1;
    }
    if (!keep) continue;
    double sum[3] = {0, 0, 0};
    std::uint32_t rgb[3] = {0, 0, 0};
    for (size_t k = start[v]; k < start[v + 1]; ++k) {
      const FusionRecord& r = records[k];
      sum[0] += r.x;
      sum[1] += r.y;
      sum[2] += r.z;
      for (int c = 0; c < 3; ++c) rgb[c] += r.rgb[c];
    }
    const double n = static_cast<double>(start[v + 1] - start[v]);
    part.positions.emplace_back(sum[0] / n, sum[1] / n, sum[2] / n);
    part.colours.push_back({static_cast<std::uint8_t>(rgb[0] / n), static_cast<std::uint8_t>(rgb[1] / n),
                            static_cast<std::uint8_t>(rgb[2] / n)});
    part.views.push_back(static_cast<std::uint16_t>(views));
  }
  part.resolution_m = res;
  return part;
}

void Fuse(const std::vector<std::filesystem::path>& files, double res, const DenseOptions& o,
          const FusedTileSink& sink, DenseSummary* s, const ProgressCallback& progress = {},
          const DenseShare& share = {}) {
  DenseSummary unused;
  if (s == nullptr) s = &unused;
  if (files.empty()) return;
  FusionInputs in{files, {}, {}, {}, FusionGrid(res, o), res, 0.0, 0};
  Eigen::Vector2d all_lo(1e300, 1e300), all_hi(-1e300, -1e300);
  for (const auto& f : files) {
    in.heads.push_back(DepthPoints::Read(f, false));
    const DepthPoints& h = in.heads.back();
    in.lo.push_back(h.lo());
    in.hi.push_back(h.hi());
    all_lo = all_lo.cwiseMin(h.lo().head<2>());
    all_hi = all_hi.cwiseMax(h.hi().head<2>());
  }
  in.tile_voxels = in.grid.tile_voxels;
  in.tile = in.tile_voxels * res;
  const double tile = in.tile;
  const long long x0 = static_cast<long long>(std::floor(all_lo.x() / tile));
  const long long y0 = static_cast<long long>(std::floor(all_lo.y() / tile));
  const long long x1 = static_cast<long long>(std::floor(all_hi.x() / tile));
  const long long y1 = static_cast<long long>(std::floor(all_hi.y() / tile));
  std::vector<std::pair<long long, long long>> tiles;
  for (long long ty = y0; ty <= y1; ++ty) {
    for (long long tx = x0; tx <= x1; ++tx) tiles.push_back({tx, ty});
  }
  if (share.count > 1) tiles = ShareTiles(in, tiles, share);
  // Tiles on all cores, handed to the sink in tile order (the same cloud
  // every run); at most two tiles a thread wait for their turn.
  const unsigned threads = ThreadCount(o.num_threads);
  std::vector<DenseCloud> parts(tiles.size());
  auto fuse_tile = [&](size_t t) {
    DenseCloud& part = parts[t];
    part = AgreedVoxels(TileRecords(in, tiles[t]), res, o);
    if (sink.prepare && !part.positions.empty()) sink.prepare(&part);
  };
  ParallelForInOrder(
      tiles.size(), threads, fuse_tile,
      [&](size_t t) {
        DenseCloud part = std::move(parts[t]);
        parts[t] = DenseCloud();
        if (part.positions.empty()) return;
        ++s->tiles;
        s->fused_points += static_cast<long long>(part.positions.size());
        sink.consume(std::move(part));
        ReportProgress(progress, static_cast<double>(t + 1) / tiles.size(),
                       "fusion: tile " + std::to_string(t + 1) + " of " + std::to_string(tiles.size()) + ", " +
                           std::to_string(s->fused_points) + " points");
        // A tile's arrays below glibc's (dynamic, up to 32 MB) mmap
        // threshold come from the heap, and free() keeps those pages.
        ReleaseFreedMemory();
      },
      2 * threads);
}

// A sink that gathers the tiles into one cloud.
FusedTileSink Gather(DenseCloud* cloud) {
  FusedTileSink sink;
  sink.consume = [cloud](DenseCloud&& part) {
    cloud->positions.insert(cloud->positions.end(), part.positions.begin(), part.positions.end());
    cloud->colours.insert(cloud->colours.end(), part.colours.begin(), part.colours.end());
    cloud->views.insert(cloud->views.end(), part.views.begin(), part.views.end());
  };
  return sink;
}

}  // namespace

DenseCloud FuseDepthMaps(const std::vector<std::filesystem::path>& files, double res, const DenseOptions& options,
                         DenseSummary* summary) {
  DenseCloud cloud;
  cloud.resolution_m = res;
  Fuse(files, res, options, Gather(&cloud), summary);
  return cloud;
}

void WriteDepthMap(const std::filesystem::path& path, const std::vector<Eigen::Vector3d>& points,
                   const std::vector<std::array<std::uint8_t, 3>>& colours, double res, long long tile_voxels) {
  DepthPoints d;
  for (size_t k = 0; k < points.size(); ++k) {
    const auto rgb = k < colours.size() ? colours[k] : std::array<std::uint8_t, 3>{128, 128, 128};
    d.Add(points[k], rgb[0], rgb[1], rgb[2]);
  }
  d.Write(path, res > 0 && tile_voxels > 0 ? TileGrid{res, tile_voxels} : TileGrid{});
}

double MedianGsd(const SparseModel& model) {
  std::vector<double> gsd;
  for (const Observation& obs : model.observations) {
    const Image& image = model.images[obs.image];
    if (!image.registered) continue;
    const double z = image.pose.CamFromWorld(model.points[obs.point].position).z();
    if (z > 0) gsd.push_back(z / model.cameras[image.camera].focal_px());
  }
  if (gsd.empty()) return 0.0;
  std::nth_element(gsd.begin(), gsd.begin() + gsd.size() / 2, gsd.end());
  return gsd[gsd.size() / 2];
}

// Depth points of image i matched with j, written to path. False when the
// pair cannot be matched (an image unreadable, too few sparse points).
// A photo's border in the rectified frame (columns u, rows v at focal
// length f), each coordinate within `most` of its principal ray.
struct RectifiedExtent {
  double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
};

RectifiedExtent ExtentOf(const Image& im, const Camera& cam, const Eigen::Matrix3d& rect_from_world, double f,
                         double most) {
  const Eigen::Matrix3d rect_from_cam = rect_from_world * im.pose.cam_from_world.toRotationMatrix().transpose();
  const Eigen::Vector3d axis = rect_from_cam.col(2);
  const double au = f * axis.x() / axis.z(), av = f * axis.y() / axis.z();
  RectifiedExtent e;
  constexpr int kSteps = 32;  // per side: the border bends under distortion
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k <= kSteps; ++k) {
      const double t = static_cast<double>(k) / kSteps;
      const double x = side < 2 ? t * cam.width - 0.5 : (side == 2 ? -0.5 : cam.width - 0.5);
      const double y = side < 2 ? (side == 0 ? -0.5 : cam.height - 0.5) : t * cam.height - 0.5;
      const auto ray = cam.RayFromImage(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const Eigen::Vector3d r = rect_from_cam * *ray;
      if (r.z() <= 1e-3) continue;
      const double u = std::clamp(f * r.x() / r.z(), au - most, au + most);
      const double v = std::clamp(f * r.y() / r.z(), av - most, av + most);
      e.u0 = std::min(e.u0, u), e.u1 = std::max(e.u1, u);
      e.v0 = std::min(e.v0, v), e.v1 = std::max(e.v1, v);
    }
  }
  return e;
}

// The remap of a photo into the rectified frame (width x height, principal
// point cx, cy); -1 outside the photo (remaps to black). A rolling-shutter
// photo is remapped as the global-shutter camera at its mid-readout pose
// would have seen the plane at depth plane_depth along the rectified axis
// (from plane_origin): each rectified ray meets that plane, and the point
// is found in the photo at the row whose camera saw it (ProjectIntoImage).
// Exact on the plane; off it, the error is the camera's motion during the
// readout times the point's relative height off the plane (2 cm for 0.5 m
// of motion and 4 % relief).
void RectificationMap(const Image& im, const Camera& cam, const Eigen::Matrix3d& rect_from_world, double f,
                      double cx, double cy, int width, int height, double image_scale,
                      const Eigen::Vector3d& plane_origin, double plane_depth, cv::Mat* mx, cv::Mat* my) {
  mx->create(height, width, CV_32F);
  my->create(height, width, CV_32F);
  const Eigen::Matrix3d cam_from_rect = im.pose.cam_from_world.toRotationMatrix() * rect_from_world.transpose();
  const Eigen::Matrix3d world_from_cam = im.pose.cam_from_world.conjugate().toRotationMatrix();
  const Eigen::Vector3d zhat = rect_from_world.row(2).transpose();
  const bool rolling = im.rolling_shutter && im.rolling_shutter->readout_time_s != 0.0 && plane_depth > 0.0;
  const double centre_depth = zhat.dot(im.pose.centre_in_world - plane_origin);
  for (int v = 0; v < height; ++v) {
    float* px = mx->ptr<float>(v);
    float* py = my->ptr<float>(v);
    for (int u = 0; u < width; ++u) {
      const Eigen::Vector3d ray = cam_from_rect * Eigen::Vector3d((u - cx) / f, (v - cy) / f, 1.0);
      if (ray.z() <= 0) {
        px[u] = py[u] = -1.0f;
        continue;
      }
      // A rolling shutter's point on the plane, found at its row; else the ray's own pixel.
      Eigen::Vector2d xy;
      const Eigen::Vector3d dir = rolling ? Eigen::Vector3d(world_from_cam * ray) : Eigen::Vector3d::Zero();
      if (const double along = zhat.dot(dir); along > 1e-6) {
        xy = ProjectIntoImage(cam, im, im.pose.centre_in_world + (plane_depth - centre_depth) / along * dir);
      } else {
        xy = cam.ImageFromCamera(ray);
      }
      if (xy.x() < -0.5 || xy.y() < -0.5 || xy.x() > cam.width - 0.5 || xy.y() > cam.height - 0.5) {
        px[u] = py[u] = -1.0f;
        continue;
      }
      px[u] = static_cast<float>((xy.x() + 0.5) * image_scale - 0.5);
      py[u] = static_cast<float>((xy.y() + 0.5) * image_scale - 0.5);
    }
  }
}

bool DepthPointsOfPair(const SparseModel& model, int i, int j, const std::function<cv::Mat(int)>& load_image,
                       const DenseOptions& o, const TileGrid& grid, const std::filesystem::path& path,
                       long long* num_points) {
  const Image& a = model.images[i];
  const Image& b = model.images[j];
  const Camera& ca = model.cameras[a.camera];
  const Camera& cb = model.cameras[b.camera];
  cv::Mat img_a = load_image(i), img_b = load_image(j);
  if (img_a.empty() || img_b.empty()) return false;
  if (o.image_scale != 1.0) {
    cv::resize(img_a, img_a, cv::Size(), o.image_scale, o.image_scale, cv::INTER_AREA);
    cv::resize(img_b, img_b, cv::Size(), o.image_scale, o.image_scale, cv::INTER_AREA);
  }
  // Fusiello rectification.
  const Eigen::Vector3d ci = a.pose.centre_in_world, cj = b.pose.centre_in_world;
  const double baseline = (cj - ci).norm();
  const Eigen::Vector3d xhat = (cj - ci) / baseline;
  const Eigen::Vector3d za = a.pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d zb = b.pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d yhat = (za + zb).normalized().cross(xhat).normalized();
  const Eigen::Vector3d zhat = xhat.cross(yhat);
  Eigen::Matrix3d rect_from_world;
  rect_from_world.row(0) = xhat;
  rect_from_world.row(1) = yhat;
  rect_from_world.row(2) = zhat;
  const double f = 0.5 * (ca.focal_px() + cb.focal_px()) * o.image_scale;
  // The rectified frame holds the whole of photo a: the bounding box of its
  // border in rectified coordinates (columns), within the rows where both
  // photos have content (rows are shared). A frame of the photos' own size
  // cuts a band off each side of the strip whenever the flight runs along
  // the photos' y axis (rectification turns them by 90 degrees), and with
  // it the block's rim from the DSM.
  const double most = 1.5 * std::max(img_a.cols, img_a.rows);  // from the principal ray, either way
  const RectifiedExtent ea = ExtentOf(a, ca, rect_from_world, f, most), eb = ExtentOf(b, cb, rect_from_world, f, most);
  const double v0 = std::max(ea.v0, eb.v0), v1 = std::min(ea.v1, eb.v1);
  if (!(ea.u1 > ea.u0) || !(eb.u1 > eb.u0) || !(v1 > v0)) return false;
  // Disparity range from image a's sparse points (2nd to 98th percentile,
  // widened by 15 % of depth either way).
  std::vector<double> disparities;
  for (const Observation& obs : model.observations) {
    if (obs.image != i) continue;
    const double z = zhat.dot(model.points[obs.point].position - ci);
    if (z > 0) disparities.push_back(f * baseline / z);
  }
  if (disparities.size() < 20) return false;
  std::sort(disparities.begin(), disparities.end());
  // The plane a rolling shutter is undone on: the sparse points' median depth.
  const double median_depth = f * baseline / disparities[disparities.size() / 2];
  const double dlo = disparities[disparities.size() / 50];
  const double dhi = disparities[disparities.size() - 1 - disparities.size() / 50];
  // Photo b's frame is shifted onto a's so that the search starts at
  // disparity 0 (u_a - u_b = f B / z + cxa - cxb): SGBM leaves the first
  // min + num columns of a unmatched, and a wide pair's disparities of a
  // thousand pixels would leave nothing. Photo b needs only the columns
  // that a's ground falls on.
  const int width = static_cast<int>(std::ceil(ea.u1 - ea.u0)) + 1;
  const int height = static_cast<int>(std::ceil(v1 - v0)) + 1;
  const double offset = 8.0 - std::floor(dlo * 0.85);
  const double cxa = -ea.u0, cxb = cxa - offset, cy = -v0;
  cv::Mat mxa, mya, mxb, myb, ra, rb;
  RectificationMap(a, ca, rect_from_world, f, cxa, cy, width, height, o.image_scale, ci, median_depth, &mxa, &mya);
  RectificationMap(b, cb, rect_from_world, f, cxb, cy, width, height, o.image_scale, ci, median_depth, &mxb, &myb);
  cv::remap(img_a, ra, mxa, mya, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  cv::remap(img_b, rb, mxb, myb, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  const int min_disp = 0;
  int num_disp = static_cast<int>(std::ceil(dhi * 1.15 + offset)) + 8;
  num_disp = std::clamp(((num_disp + 15) / 16) * 16, 16, 1024);
  // SGBM matches the columns [max(0, min+num), width + min(0, min)) of image
  // a; a pair whose search range leaves too few of them (a close-range,
  // wide-baseline pair) is skipped, not handed to OpenCV (which would
  // ask for a buffer of negative size).
  const int matched_columns = width + std::min(0, min_disp) - std::max(0, min_disp + num_disp);
  if (matched_columns < width / 4) return false;
  cv::Mat ga, gb, disp;
  cv::cvtColor(ra, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(rb, gb, cv::COLOR_BGR2GRAY);
  const int bs = o.block_size;
  cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(min_disp, num_disp, bs, 8 * bs * bs, 32 * bs * bs, 1, 0,
                                                        10, 100, 2, cv::StereoSGBM::MODE_SGBM_3WAY);
  sgbm->compute(ga, gb, disp);
  const Eigen::Matrix3d world_from_rect = rect_from_world.transpose();
  DepthPoints points;
  for (int v = 0; v < height; ++v) {
    const std::int16_t* d = disp.ptr<std::int16_t>(v);
    const float* valid = mxa.ptr<float>(v);
    const float* valid_b = mxb.ptr<float>(v);
    const cv::Vec3b* colour = ra.ptr<cv::Vec3b>(v);
    for (int u = 0; u < width; ++u) {
      if (d[u] <= min_disp * 16 || valid[u] < 0) continue;
      // Its match must lie on photo b too (not on the black beyond it).
      const int ub = static_cast<int>(std::lround(u - d[u] / 16.0));
      if (ub < 0 || ub >= width || valid_b[ub] < 0) continue;
      const double dd = d[u] / 16.0 - offset;
      if (dd <= 0) continue;
      const double z = f * baseline / dd;
      const Eigen::Vector3d x = ci + world_from_rect * (z * Eigen::Vector3d((u - cxa) / f, (v - cy) / f, 1.0));
      points.Add(x, colour[u][2], colour[u][1], colour[u][0]);
    }
  }
  *num_points = static_cast<long long>(points.count());
  points.Write(path, grid);
  return true;
}

DenseCloud ComputeDenseCloud(const SparseModel& model, const std::function<cv::Mat(int)>& load_image,
                             const DenseOptions& o, const ProgressCallback& progress, DenseSummary* summary) {
  DenseCloud cloud;
  DenseSummary local;
  DenseSummary& s = summary ? *summary : local;
  ComputeDenseCloud(model, load_image, o, progress, Gather(&cloud), &s);
  cloud.resolution_m = s.resolution_m;
  return cloud;
}

namespace {

// The pairs of the dense stage, in image order, and their depth-map files.
struct DensePairs {
  double res = 0.0;
  std::vector<std::pair<int, int>> order;
  std::vector<std::filesystem::path> paths;
};

DensePairs PlanPairs(const SparseModel& model, const DenseOptions& o) {
  DensePairs plan;
  const double gsd = MedianGsd(model);
  plan.res = o.resolution_m > 0 ? o.resolution_m : gsd / o.image_scale;
  if (!(plan.res > 0)) throw InvalidArgument("dense matching needs a registered model with points");
  if (o.work_dir.empty()) throw InvalidArgument("dense matching needs a folder for its depth points");
  const std::vector<std::vector<Partner>> partners = ChoosePartners(model, o);
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (!model.images[i].registered) continue;
    for (const Partner& p : partners[i]) plan.order.push_back({static_cast<int>(i), p.image});
  }
  for (const auto& [i, j] : plan.order) {
    plan.paths.push_back(o.work_dir / (model.images[i].name + "+" + model.images[j].name + ".pts"));
  }
  return plan;
}

// The share's run of the pairs (in image order, so mostly neighbours).
std::pair<size_t, size_t> ShareOfPairs(const DensePairs& plan, const DenseShare& share) {
  return {plan.order.size() * share.index / share.count, plan.order.size() * (share.index + 1) / share.count};
}

void CheckShare(const DenseShare& share) {
  if (share.count < 1 || share.index < 0 || share.index >= share.count) {
    throw InvalidArgument("a share of the dense work must be 1 to " + std::to_string(share.count) + " of " +
                          std::to_string(share.count) + ", got " + std::to_string(share.index + 1));
  }
}

}  // namespace

void ComputeDenseCloud(const SparseModel& model, const std::function<cv::Mat(int)>& load_image,
                       const DenseOptions& o, const ProgressCallback& progress, const FusedTileSink& sink,
                       DenseSummary* summary) {
  // Depth maps are most of the work; fusion the rest.
  ComputeDepthMaps(model, load_image, o, DenseShare{}, ProgressPart(progress, 0.0, 0.85), summary);
  FuseModelDepthMaps(model, o, DenseShare{}, ProgressPart(progress, 0.85, 1.0), sink, summary);
}

void ComputeDepthMaps(const SparseModel& model, const std::function<cv::Mat(int)>& load_image,
                      const DenseOptions& o, const DenseShare& share, const ProgressCallback& progress,
                      DenseSummary* summary) {
  CheckShare(share);
  DenseSummary local;
  DenseSummary& s = summary ? *summary : local;
  const DensePairs plan = PlanPairs(model, o);
  const double res = plan.res;
  s.resolution_m = res;
  std::filesystem::create_directories(o.work_dir);
  const auto [first, last] = ShareOfPairs(plan, share);
  const std::vector<std::pair<int, int>> order(plan.order.begin() + first, plan.order.begin() + last);
  const std::vector<std::filesystem::path> paths(plan.paths.begin() + first, plan.paths.begin() + last);
  // Pairs on all cores (OpenCV's SGBM runs on one); each writes its own file.
  const ProgressCallback& pairs_progress = progress;
  std::vector<char> ok(order.size(), 0);
  std::mutex mutex;
  size_t done = 0;
  ParallelFor(order.size(), ThreadCount(o.num_threads), [&](size_t k) {
    const auto [i, j] = order[k];
    long long n = 0;
    bool computed = false;
    if (std::filesystem::exists(paths[k])) {
      ok[k] = 1;  // computed by an earlier, interrupted run
    } else {
      ok[k] = DepthPointsOfPair(model, i, j, load_image, o, FusionGrid(res, o), paths[k], &n) ? 1 : 0;
      computed = true;
    }
    std::lock_guard<std::mutex> lock(mutex);
    ++done;
    if (ok[k]) {
      ++s.pairs;
      s.depth_points += n;
    } else {
      ++s.pairs_failed;
    }
    if (computed) {
      ReportProgress(pairs_progress, static_cast<double>(done) / order.size(),
                     model.images[i].name + " + " + model.images[j].name + ": " + std::to_string(n) + " depth points");
    }
  });
}

std::vector<std::filesystem::path> DepthMapPaths(const SparseModel& model, const DenseOptions& o,
                                                 const DenseShare& share) {
  CheckShare(share);
  const DensePairs plan = PlanPairs(model, o);
  const auto [first, last] = ShareOfPairs(plan, share);
  return {plan.paths.begin() + first, plan.paths.begin() + last};
}

void FuseModelDepthMaps(const SparseModel& model, const DenseOptions& o, const DenseShare& share,
                        const ProgressCallback& progress, const FusedTileSink& sink, DenseSummary* summary) {
  CheckShare(share);
  DenseSummary local;
  DenseSummary& s = summary ? *summary : local;
  const DensePairs plan = PlanPairs(model, o);
  s.resolution_m = plan.res;
  // A pair's file exists exactly when its depth map was made (written
  // atomically; a pair that failed writes none).
  std::vector<std::filesystem::path> files;
  for (const std::filesystem::path& path : plan.paths) {
    if (std::filesystem::exists(path)) files.push_back(path);
  }
  Fuse(files, plan.res, o, sink, &s, progress, share);
}


}  // namespace aerotri
