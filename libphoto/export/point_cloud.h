// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Point clouds in the output CRS, written as LAS 1.4 and PLY, atomically.
//
// LAS 1.4 (ASPRS R15, 2019): point data record format 7 (XYZ, RGB, GPS time),
// the CRS as OGC WKT in a LASF_Projection VLR (record 2112) with the WKT bit
// of the global encoding set; scale 0.001 (millimetre) and offsets at the
// cloud's minimum, so integer coordinates stay small. Colours are 16-bit
// (8-bit x 257), the ASPRS classification per point (CrsCloud::classes;
// 1, unclassified, when absent).
// PLY: binary little-endian, double x y z in the output CRS, uchar RGB, the
// CRS named in a comment.
// LAZ: a path ending in .laz is written compressed (laz.h: LASzip's LAS 1.4
// layered compression, chunks of 50,000 points; the same records), and read
// back the same way.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <string>
#include <memory>
#include <vector>

#include "libphoto/export/laz.h"

namespace aerotri {

struct CrsCloud {
  std::vector<Eigen::Vector3d> xyz;  // output CRS
  std::vector<std::array<std::uint8_t, 3>> rgb;
  std::vector<std::uint8_t> classes;  // ASPRS classes (LAS only); empty: all 1
  std::string crs_wkt;   // OGC WKT (WKT1 for LAS readers of today)
  std::string crs_name;  // for humans (PLY comment)
};

// The file's name decides: .las, .laz (LasWriter), .copc.laz (CopcWriter).
void WriteLas(const CrsCloud& cloud, const std::filesystem::path& path);
bool IsCopcPath(const std::filesystem::path& path);  // a name ending in .copc.laz

// The LAS 1.4 pieces aerotri's writers share (LasWriter, CopcWriter):
// millimetre scale, offsets at whole kilometres below the cloud's minimum,
// point format 7 records of returns 1 of 1.
constexpr double kLasScale = 0.001;
Eigen::Vector3d LasOffsetFor(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);  // throws beyond 2,100 km
void MakeLasRecord(const Eigen::Vector3d& p, const Eigen::Vector3d& offset, const std::array<std::uint8_t, 3>& rgb,
                   std::uint8_t asprs_class, std::uint8_t* record36);
struct LasVlr {
  std::string user;
  std::uint16_t record = 0;
  std::string description;
  std::vector<std::uint8_t> payload;
};
LasVlr WktVlr(const std::string& crs_wkt);  // LASF_Projection 2112, OGC WKT
struct LasHeaderLayout {
  std::uint64_t count = 0;
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero(), offset = Eigen::Vector3d::Zero();
  bool compressed = false;
  std::vector<LasVlr> vlrs;  // in file order
  std::uint64_t first_evlr = 0;
  std::uint32_t evlrs = 0;
};
// Opens `tmp` (creating path's folder), and closes it and renames it onto
// path once written; a failed write removes it and throws IoError.
void OpenCloudFile(std::ofstream* out, const std::filesystem::path& tmp, const std::filesystem::path& path);
void CommitCloudFile(std::ofstream* out, const std::filesystem::path& tmp, const std::filesystem::path& path);
// Writes the header and VLRs; returns the offset of the point data.
std::uint32_t PutLasHeader(std::ostream& out, const LasHeaderLayout& layout);
void WritePly(const CrsCloud& cloud, const std::filesystem::path& path);

// The same files for a cloud written in batches (never all in memory): the
// header, with the count and bounds known beforehand, then the points, then
// Commit() renames the finished file onto path. Destroyed uncommitted (an
// exception on the way), the temporary file is removed and path untouched.
// A .laz path holds one chunk in memory, never the cloud.
class LasWriter {
 public:
  LasWriter(const std::filesystem::path& path, std::uint64_t count, const Eigen::Vector3d& lo,
            const Eigen::Vector3d& hi, const std::string& crs_wkt);
  ~LasWriter();
  LasWriter(const LasWriter&) = delete;
  LasWriter& operator=(const LasWriter&) = delete;
  void Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& rgb, std::uint8_t asprs_class);
  // A whole point record of format 7 (36 bytes: intensity, returns, GPS
  // time... as the caller has them), its X, Y, Z integers on the header's
  // grid: (p - offset()) / 0.001.
  void AddRecord(const std::uint8_t* record);
  const Eigen::Vector3d& offset() const { return offset_; }
  void Commit();  // throws unless exactly `count` points were added

 private:
  void Flush();
  void WriteChunk();
  void WriteOldestChunk();
  std::filesystem::path path_, tmp_;
  std::unique_ptr<laz::ChunkEncoder> laz_;  // null: plain LAS
  std::vector<std::future<std::vector<std::uint8_t>>> pending_;  // chunks being compressed, in file order
  unsigned threads_ = 1;
  std::vector<laz::Chunk> chunks_;
  std::uint64_t chunk_table_pointer_ = 0;  // where the chunk table's offset goes
  std::ofstream out_;
  std::vector<char> buffer_;
  std::size_t used_ = 0;
  std::uint64_t count_ = 0, written_ = 0;
  Eigen::Vector3d offset_, lo_, hi_;
  bool committed_ = false;
};

class PlyWriter {
 public:
  PlyWriter(const std::filesystem::path& path, std::uint64_t count, const std::string& crs_name);
  ~PlyWriter();
  PlyWriter(const PlyWriter&) = delete;
  PlyWriter& operator=(const PlyWriter&) = delete;
  void Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& rgb);
  void Commit();  // throws unless exactly `count` points were added

 private:
  std::filesystem::path path_, tmp_;
  std::ofstream out_;
  std::vector<char> buffer_;
  std::size_t used_ = 0;
  std::uint64_t count_ = 0, written_ = 0;
  bool committed_ = false;
};

// Reads LAS 1.2-1.4 point formats 0-3 and 6-8 (XYZ, classes, RGB where
// present, the WKT VLR where present), and LAZ of formats 6 and 7 (laz.h).
// Throws ParseError for anything else, and for a truncated file.
CrsCloud ReadLas(const std::filesystem::path& path);

// The same, batch_points at a time, for a cloud too large to hold; returns
// the header's count and CRS (each batch carries the CRS too).
struct LasHeader {
  std::uint64_t count = 0;
  std::string crs_wkt;
};
LasHeader ReadLasInBatches(const std::filesystem::path& path, const std::function<void(CrsCloud&&)>& consume,
                           std::size_t batch_points = std::size_t{1} << 20);

}  // namespace aerotri
