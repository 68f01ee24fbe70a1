// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// COPC (Cloud-Optimised Point Cloud, copc.io 1.0): a LAZ 1.4 file whose
// points are ordered into an octree, one LAZ chunk per node, with the
// octree's hierarchy in an EVLR, so that QGIS (3.26 and later), PDAL, web
// viewers and range requests on cloud storage read the nodes they need in
// place.
//
// The octree: a cube about the cloud's bounds. Each node keeps at most one
// point per cell of a 128^3 grid over its cube (the first point to reach a
// free cell); a point whose cells are taken at every level above the leaf
// level goes to its leaf node. The leaf level is chosen from the point count
// so that leaves hold some 50,000 points on a surface-like cloud. Every point
// is in exactly one node, inside that node's cube.
//
// CopcWriter takes the points in any order (the dense stage's CRS tiles) and
// never holds the cloud: records go to per-node buffers, spilled to a
// scratch file beside the output when they pass 64 MB together; Commit()
// compresses node by node (on all cores, as LasWriter does) and writes the
// header, the COPC info VLR (first, as the format requires), the LASzip VLR
// (chunks of varying size), the CRS, the chunks, the chunk table and the
// hierarchy EVLR. The file is written to a temporary name and renamed.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <unordered_set>
#include <vector>

namespace aerotri {

struct CopcKey {
  std::int32_t level = 0, x = 0, y = 0, z = 0;
  bool operator<(const CopcKey& o) const {
    return std::array<std::int32_t, 4>{level, x, y, z} < std::array<std::int32_t, 4>{o.level, o.x, o.y, o.z};
  }
};

class CopcWriter {
 public:
  // spill_bytes: the buffered records that go to the scratch file together.
  CopcWriter(const std::filesystem::path& path, std::uint64_t count, const Eigen::Vector3d& lo,
             const Eigen::Vector3d& hi, const std::string& crs_wkt, std::uint64_t spill_bytes = 64u << 20);
  ~CopcWriter();
  CopcWriter(const CopcWriter&) = delete;
  CopcWriter& operator=(const CopcWriter&) = delete;
  void Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& rgb, std::uint8_t asprs_class);
  void Commit();  // throws unless exactly `count` points were added

  int leaf_level() const { return leaf_level_; }

 private:
  struct Node {
    std::vector<std::uint8_t> buffer;                           // records not yet spilled
    std::vector<std::pair<std::uint64_t, std::uint64_t>> spilled;  // (offset, bytes) in the scratch file
    std::uint64_t points = 0;
  };
  CopcKey KeyOf(const Eigen::Vector3d& q);
  void Spill();
  std::vector<std::uint8_t> Records(const Node& node);

  std::filesystem::path path_, tmp_, scratch_path_;
  std::uint64_t count_ = 0, written_ = 0;
  Eigen::Vector3d lo_, hi_, offset_, cube_min_;
  double halfsize_ = 0;
  int leaf_level_ = 0;
  std::string crs_wkt_;
  std::vector<std::unordered_set<std::uint64_t>> taken_;  // cells taken, per level above the leaves
  std::map<CopcKey, Node> nodes_;
  std::fstream scratch_;
  std::uint64_t scratch_size_ = 0, buffered_ = 0, spill_bytes_;
  bool committed_ = false;
};

}  // namespace aerotri
