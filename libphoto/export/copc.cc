// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/copc.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <deque>
#include <future>
#include <set>
#include <thread>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/export/laz.h"
#include "libphoto/export/point_cloud.h"

namespace aerotri {
namespace {

constexpr int kGrid = 128;                    // cells per node axis: one point each above the leaves
constexpr std::uint64_t kLeafPoints = 50000;  // about, on a surface-like cloud

template <typename T>
void Append(std::vector<std::uint8_t>* out, T v) {
  const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
  out->insert(out->end(), b, b + sizeof(T));
}

// The COPC info VLR's 160 bytes.
std::vector<std::uint8_t> InfoPayload(const Eigen::Vector3d& centre, double halfsize, std::uint64_t hierarchy_at,
                                      std::uint64_t hierarchy_bytes) {
  std::vector<std::uint8_t> out;
  for (int k = 0; k < 3; ++k) Append(&out, centre[k]);
  Append(&out, halfsize);
  Append(&out, 2.0 * halfsize / kGrid);  // the root's point spacing
  Append(&out, hierarchy_at);
  Append(&out, hierarchy_bytes);
  Append(&out, 0.0);  // GPS time range: no times
  Append(&out, 0.0);
  out.resize(160, 0);  // reserved
  return out;
}

struct Written {
  CopcKey key;
  std::uint64_t offset = 0;
  std::uint32_t bytes = 0, points = 0;
};

}  // namespace

CopcWriter::CopcWriter(const std::filesystem::path& path, std::uint64_t count, const Eigen::Vector3d& lo_in,
                       const Eigen::Vector3d& hi_in, const std::string& crs_wkt, std::uint64_t spill_bytes)
    : path_(path), tmp_(TemporaryPathFor(path)), count_(count), crs_wkt_(crs_wkt), spill_bytes_(spill_bytes) {
  lo_ = count ? lo_in : Eigen::Vector3d::Zero();
  hi_ = count ? hi_in : Eigen::Vector3d::Zero();
  offset_ = LasOffsetFor(lo_, hi_);
  const Eigen::Vector3d centre = 0.5 * (lo_ + hi_);
  halfsize_ = std::max(0.5 * (hi_ - lo_).maxCoeff(), 0.5) + 0.001;
  cube_min_ = centre.array() - halfsize_;
  while (leaf_level_ < 12 && static_cast<double>(count) / std::pow(4.0, leaf_level_) > kLeafPoints) ++leaf_level_;
  taken_.resize(static_cast<std::size_t>(leaf_level_));
  scratch_path_ = tmp_.string() + ".points";
}

CopcWriter::~CopcWriter() {
  std::error_code ec;
  if (scratch_.is_open()) scratch_.close();
  std::filesystem::remove(scratch_path_, ec);
  if (!committed_) std::filesystem::remove(tmp_, ec);
}

CopcKey CopcWriter::KeyOf(const Eigen::Vector3d& q) {
  // The shallowest level with the point's cell free; else the leaf level.
  int level = leaf_level_;
  const Eigen::Vector3d rel = (q - cube_min_) / (2.0 * halfsize_);  // in [0, 1)
  for (int d = 0; d < leaf_level_; ++d) {
    const std::int64_t cells = std::int64_t{kGrid} << d;
    std::uint64_t key = 0;
    for (int k = 0; k < 3; ++k) {
      const auto i = std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(rel[k] * cells)), 0, cells - 1);
      key |= static_cast<std::uint64_t>(i) << (21 * k);
    }
    if (taken_[static_cast<std::size_t>(d)].insert(key).second) {
      level = d;
      break;
    }
  }
  CopcKey key;
  key.level = level;
  const std::int64_t nodes = std::int64_t{1} << level;
  std::int32_t* xyz[3] = {&key.x, &key.y, &key.z};
  for (int k = 0; k < 3; ++k) {
    *xyz[k] = static_cast<std::int32_t>(
        std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(rel[k] * nodes)), 0, nodes - 1));
  }
  return key;
}

void CopcWriter::Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& rgb, std::uint8_t asprs_class) {
  if (written_ >= count_) throw InvalidArgument(path_.string() + ": more points than the " + std::to_string(count_) + " announced");
  if ((p - lo_).minCoeff() < -1e-6 || (hi_ - p).minCoeff() < -1e-6) {
    throw InvalidArgument(path_.string() + ": a point outside the bounds announced in the header");
  }
  std::uint8_t record[36];
  MakeLasRecord(p, offset_, rgb, asprs_class, record);
  std::int32_t xyz[3];
  std::memcpy(xyz, record, 12);
  // The node from the position a reader sees: the millimetre-quantised one.
  const Eigen::Vector3d q = offset_ + kLasScale * Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
  Node& node = nodes_[KeyOf(q)];
  node.buffer.insert(node.buffer.end(), record, record + 36);
  ++node.points;
  ++written_;
  buffered_ += 36;
  if (buffered_ > spill_bytes_) Spill();
}

void CopcWriter::Spill() {
  if (!scratch_.is_open()) {
    scratch_.open(scratch_path_, std::ios::binary | std::ios::in | std::ios::out | std::ios::trunc);
    if (!scratch_) throw IoError(scratch_path_.string(), std::string("cannot open for writing: ") + std::strerror(errno));
  }
  scratch_.seekp(static_cast<std::streamoff>(scratch_size_));
  for (auto& [key, node] : nodes_) {
    if (node.buffer.empty()) continue;
    scratch_.write(reinterpret_cast<const char*>(node.buffer.data()), static_cast<std::streamsize>(node.buffer.size()));
    node.spilled.emplace_back(scratch_size_, node.buffer.size());
    scratch_size_ += node.buffer.size();
    std::vector<std::uint8_t>().swap(node.buffer);
  }
  if (!scratch_) throw IoError(scratch_path_.string(), "write failed (disk full?)");
  buffered_ = 0;
}

std::vector<std::uint8_t> CopcWriter::Records(const Node& node) {
  std::vector<std::uint8_t> out;
  out.reserve(node.points * 36);
  for (const auto& [at, bytes] : node.spilled) {
    out.resize(out.size() + bytes);
    scratch_.seekg(static_cast<std::streamoff>(at));
    if (!scratch_.read(reinterpret_cast<char*>(out.data() + out.size() - bytes), static_cast<std::streamsize>(bytes))) {
      throw IoError(scratch_path_.string(), "cannot read back the points spilled there");
    }
  }
  out.insert(out.end(), node.buffer.begin(), node.buffer.end());
  return out;
}

void CopcWriter::Commit() {
  if (written_ != count_) {
    throw InvalidArgument(path_.string() + ": " + std::to_string(written_) + " points written, " +
                          std::to_string(count_) + " announced");
  }
  if (scratch_.is_open()) scratch_.flush();
  LasHeaderLayout layout;
  layout.count = count_;
  layout.lo = lo_;
  layout.hi = hi_;
  layout.offset = offset_;
  layout.compressed = true;
  const Eigen::Vector3d centre = cube_min_.array() + halfsize_;
  layout.vlrs.push_back({"copc", 1, "COPC info", InfoPayload(centre, halfsize_, 0, 0)});
  layout.vlrs.push_back({"laszip encoded", 22204, "LAZ 1.4 layered chunked",
                         laz::LaszipVlrPayload(7, laz::kVariableChunkSize)});
  if (!crs_wkt_.empty()) layout.vlrs.push_back(WktVlr(crs_wkt_));
  std::ofstream out;
  OpenCloudFile(&out, tmp_, path_);
  const std::uint32_t point_offset = PutLasHeader(out, layout);
  const std::int64_t no_table = -1;
  out.write(reinterpret_cast<const char*>(&no_table), 8);

  // One chunk per node, in key order (the root first), compressed on all
  // cores while earlier ones are written.
  std::vector<Written> written;
  std::deque<std::future<std::vector<std::uint8_t>>> pending;
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  auto write_oldest = [&]() {
    const std::vector<std::uint8_t> bytes = pending.front().get();
    pending.pop_front();
    Written& w = written[written.size() - pending.size() - 1];
    w.offset = static_cast<std::uint64_t>(out.tellp());
    w.bytes = static_cast<std::uint32_t>(bytes.size());
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  };
  for (auto& [key, node] : nodes_) {
    std::vector<std::uint8_t> records = Records(node);
    written.push_back({key, 0, 0, static_cast<std::uint32_t>(node.points)});
    node = Node();
    pending.push_back(std::async(std::launch::async, [r = std::move(records)]() {
      return laz::CompressChunk(7, r.data(), static_cast<std::uint32_t>(r.size() / 36));
    }));
    while (pending.size() > threads) write_oldest();
  }
  while (!pending.empty()) write_oldest();

  std::vector<laz::Chunk> chunks;
  for (const Written& w : written) chunks.push_back({w.points, w.bytes});
  const std::int64_t table_at = static_cast<std::int64_t>(out.tellp());
  const std::vector<std::uint8_t> table = laz::EncodeChunkTable(chunks, true);
  out.write(reinterpret_cast<const char*>(table.data()), static_cast<std::streamsize>(table.size()));

  // The hierarchy: every node with points, and every ancestor of one (a
  // node of no points of its own says so with a count of 0).
  std::map<CopcKey, const Written*> entries;
  for (const Written& w : written) {
    entries[w.key] = &w;
    for (CopcKey k = w.key; k.level > 0;) {
      k = {k.level - 1, k.x / 2, k.y / 2, k.z / 2};
      entries.emplace(k, nullptr);
    }
  }
  if (entries.empty()) entries.emplace(CopcKey{}, nullptr);
  std::vector<std::uint8_t> page;
  for (const auto& [k, w] : entries) {
    for (std::int32_t v : {k.level, k.x, k.y, k.z}) Append(&page, v);
    Append(&page, w ? w->offset : std::uint64_t{0});
    Append(&page, w ? static_cast<std::int32_t>(w->bytes) : std::int32_t{0});
    Append(&page, w ? static_cast<std::int32_t>(w->points) : std::int32_t{0});
  }
  const auto evlr_at = static_cast<std::uint64_t>(out.tellp());
  std::vector<std::uint8_t> evlr;
  Append(&evlr, std::uint16_t{0});
  std::string user("copc");
  user.resize(16, '\0');
  evlr.insert(evlr.end(), user.begin(), user.end());
  Append(&evlr, std::uint16_t{1000});
  Append(&evlr, static_cast<std::uint64_t>(page.size()));
  std::string description("EPT hierarchy");
  description.resize(32, '\0');
  evlr.insert(evlr.end(), description.begin(), description.end());
  out.write(reinterpret_cast<const char*>(evlr.data()), static_cast<std::streamsize>(evlr.size()));
  out.write(reinterpret_cast<const char*>(page.data()), static_cast<std::streamsize>(page.size()));

  // Now that the hierarchy's place is known: the header and info again,
  // and the chunk table's offset.
  layout.vlrs[0].payload = InfoPayload(centre, halfsize_, evlr_at + evlr.size(), page.size());
  layout.first_evlr = evlr_at;
  layout.evlrs = 1;
  out.seekp(0);
  PutLasHeader(out, layout);
  out.seekp(point_offset);
  out.write(reinterpret_cast<const char*>(&table_at), 8);
  out.seekp(0, std::ios::end);
  CommitCloudFile(&out, tmp_, path_);
  committed_ = true;
  scratch_.close();
  std::error_code ec;
  std::filesystem::remove(scratch_path_, ec);
}

}  // namespace aerotri
