// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/point_cloud.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <cerrno>
#include <ctime>
#include <fstream>
#include <limits>
#include <optional>
#include <thread>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/export/copc.h"

namespace aerotri {
namespace {

template <typename T>
void Put(std::ostream& out, T v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

void PutChars(std::ostream& out, const std::string& s, size_t n) {
  std::string padded = s.substr(0, n);
  padded.resize(n, '\0');
  out.write(padded.data(), static_cast<std::streamsize>(n));
}

template <typename T>
T Get(const std::string& data, size_t offset, const std::string& path) {
  if (offset + sizeof(T) > data.size()) throw ParseError(path, 0, "truncated LAS file");
  T v;
  std::memcpy(&v, data.data() + offset, sizeof(T));
  return v;
}

bool HasLazExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".laz";
}

void PutVlrHeader(std::ostream& out, const char* user, std::uint16_t record, std::size_t length, const char* what) {
  Put<std::uint16_t>(out, 0);
  PutChars(out, user, 16);
  Put<std::uint16_t>(out, record);
  Put<std::uint16_t>(out, static_cast<std::uint16_t>(length));
  PutChars(out, what, 32);
}

}  // namespace


void OpenCloudFile(std::ofstream* out, const std::filesystem::path& tmp, const std::filesystem::path& path) {
  if (path.has_parent_path() && !std::filesystem::exists(path.parent_path())) {
    std::error_code ec;
    std::filesystem::create_directories(path.parent_path(), ec);
    if (ec) throw IoError(path.parent_path().string(), "cannot create folder: " + ec.message());
  }
  out->open(tmp, std::ios::binary | std::ios::trunc);
  if (!*out) throw IoError(tmp.string(), std::string("cannot open for writing: ") + std::strerror(errno));
}

void CommitCloudFile(std::ofstream* out, const std::filesystem::path& tmp, const std::filesystem::path& path) {
  out->flush();
  const bool ok = static_cast<bool>(*out);
  const int e = errno;
  out->close();
  if (!ok || !*out) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw IoError(path.string(), std::string("write failed: ") + (e ? std::strerror(e) : "stream error") +
                                     " (disk full or a size limit?); nothing was kept of it");
  }
  CommitTemporaryFile(tmp, path);
}


Eigen::Vector3d LasOffsetFor(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d offset = (lo.array() / 1000.0).floor() * 1000.0;
  if (((hi - offset) / kLasScale).maxCoeff() > 2.1e9 || ((lo - offset) / kLasScale).minCoeff() < -2.1e9) {
    throw InvalidArgument("LAS: the cloud spans more than 2,100 km at millimetre scale");
  }
  return offset;
}

void MakeLasRecord(const Eigen::Vector3d& p, const Eigen::Vector3d& offset, const std::array<std::uint8_t, 3>& c,
                   std::uint8_t asprs_class, std::uint8_t* record) {
  std::memset(record, 0, 36);
  const Eigen::Vector3d q = ((p - offset) / kLasScale).array().round();
  const std::int32_t xyz[3] = {static_cast<std::int32_t>(q.x()), static_cast<std::int32_t>(q.y()),
                               static_cast<std::int32_t>(q.z())};
  std::memcpy(record, xyz, 12);
  record[14] = 0x11;  // return 1 of 1
  record[16] = asprs_class;
  const std::uint16_t rgb[3] = {static_cast<std::uint16_t>(c[0] * 257), static_cast<std::uint16_t>(c[1] * 257),
                                static_cast<std::uint16_t>(c[2] * 257)};
  std::memcpy(record + 30, rgb, 6);
}

std::uint32_t PutLasHeader(std::ostream& out, const LasHeaderLayout& h) {
  std::uint32_t point_offset = 375;
  for (const LasVlr& v : h.vlrs) point_offset += 54 + static_cast<std::uint32_t>(v.payload.size());
  const bool wkt = std::any_of(h.vlrs.begin(), h.vlrs.end(), [](const LasVlr& v) { return v.record == 2112; });
  out.write("LASF", 4);
  Put<std::uint16_t>(out, 0);                    // file source id
  Put<std::uint16_t>(out, wkt ? 0x10 : 0);       // global encoding: WKT
  out.write(std::string(16, '\0').data(), 16);   // GUID
  Put<std::uint8_t>(out, 1);
  Put<std::uint8_t>(out, 4);
  PutChars(out, "aerotri", 32);
  PutChars(out, "aerotri dense matching", 32);
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  Put<std::uint16_t>(out, static_cast<std::uint16_t>(tm.tm_yday + 1));
  Put<std::uint16_t>(out, static_cast<std::uint16_t>(tm.tm_year + 1900));
  Put<std::uint16_t>(out, 375);
  Put<std::uint32_t>(out, point_offset);
  Put<std::uint32_t>(out, static_cast<std::uint32_t>(h.vlrs.size()));
  Put<std::uint8_t>(out, h.compressed ? 0x87 : 7);  // bit 7: compressed (LASzip's mark)
  Put<std::uint16_t>(out, 36);
  Put<std::uint32_t>(out, 0);  // legacy counts are 0 for formats 6-10
  for (int r = 0; r < 5; ++r) Put<std::uint32_t>(out, 0);
  for (int k = 0; k < 3; ++k) Put<double>(out, kLasScale);
  for (int k = 0; k < 3; ++k) Put<double>(out, h.offset[k]);
  for (int k = 0; k < 3; ++k) {
    Put<double>(out, h.hi[k]);
    Put<double>(out, h.lo[k]);
  }
  Put<std::uint64_t>(out, 0);  // waveform
  Put<std::uint64_t>(out, h.first_evlr);
  Put<std::uint32_t>(out, h.evlrs);
  Put<std::uint64_t>(out, h.count);
  Put<std::uint64_t>(out, h.count);  // all first returns
  for (int r = 1; r < 15; ++r) Put<std::uint64_t>(out, 0);
  for (const LasVlr& v : h.vlrs) {
    PutVlrHeader(out, v.user.c_str(), v.record, v.payload.size(), v.description.c_str());
    out.write(reinterpret_cast<const char*>(v.payload.data()), static_cast<std::streamsize>(v.payload.size()));
  }
  return point_offset;
}

LasVlr WktVlr(const std::string& crs_wkt) {
  const std::string wkt = crs_wkt + std::string(1, '\0');
  return {"LASF_Projection", 2112, "OGC WKT coordinate system", std::vector<std::uint8_t>(wkt.begin(), wkt.end())};
}

LasWriter::LasWriter(const std::filesystem::path& path, std::uint64_t count, const Eigen::Vector3d& lo_in,
                     const Eigen::Vector3d& hi_in, const std::string& crs_wkt)
    : path_(path), tmp_(TemporaryPathFor(path)), count_(count) {
  Eigen::Vector3d lo = lo_in, hi = hi_in;
  if (count == 0) lo = hi = Eigen::Vector3d::Zero();
  offset_ = LasOffsetFor(lo, hi);
  lo_ = lo;
  hi_ = hi;
  if (IsCopcPath(path)) throw InvalidArgument(path.string() + ": a COPC file is CopcWriter's to write (copc.h)");
  buffer_.resize(1 << 20);
  LasHeaderLayout layout;
  layout.count = count;
  layout.lo = lo;
  layout.hi = hi;
  layout.offset = offset_;
  if (HasLazExtension(path)) {
    laz_ = std::make_unique<laz::ChunkEncoder>(7);
    threads_ = std::max(1u, std::thread::hardware_concurrency());
    layout.compressed = true;
    layout.vlrs.push_back({"laszip encoded", 22204, "LAZ 1.4 layered chunked", laz::LaszipVlrPayload(7, laz::kDefaultChunkSize)});
  }
  if (!crs_wkt.empty()) layout.vlrs.push_back(WktVlr(crs_wkt));
  OpenCloudFile(&out_, tmp_, path_);
  const std::uint32_t point_offset = PutLasHeader(out_, layout);
  if (laz_) {
    chunk_table_pointer_ = point_offset;
    Put<std::int64_t>(out_, -1);  // the chunk table's offset, set by Commit
  }
}

LasWriter::~LasWriter() {
  for (auto& chunk : pending_) chunk.wait();  // before the buffers go
  if (committed_) return;
  out_.close();
  std::error_code ec;
  std::filesystem::remove(tmp_, ec);
}

void LasWriter::Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& c, std::uint8_t asprs_class) {
  if ((p - lo_).minCoeff() < -1e-6 || (hi_ - p).minCoeff() < -1e-6) {
    throw InvalidArgument(path_.string() + ": a point outside the bounds announced in the header");
  }
  std::uint8_t record[36];
  MakeLasRecord(p, offset_, c, asprs_class, record);
  AddRecord(record);
}

void LasWriter::AddRecord(const std::uint8_t* record) {
  if (written_ >= count_) throw InvalidArgument(path_.string() + ": more points than the " + std::to_string(count_) + " announced");
  ++written_;
  if (laz_) {
    laz_->Add(record);
    if (laz_->points() == laz::kDefaultChunkSize) WriteChunk();
    return;
  }
  std::memcpy(buffer_.data() + used_, record, 36);
  used_ += 36;
  if (used_ + 36 > buffer_.size()) Flush();
}

void LasWriter::Flush() {
  out_.write(buffer_.data(), static_cast<std::streamsize>(used_));
  used_ = 0;
}

// A full chunk is compressed on a thread of its own while the next one
// fills (chunks are independent); at most `threads_` wait, so memory stays
// a few chunks. They reach the file in order.
void LasWriter::WriteChunk() {
  chunks_.push_back({laz_->points(), 0});
  pending_.push_back(std::async(std::launch::async, [chunk = laz_->Release()]() mutable { return chunk.Compress(); }));
  while (pending_.size() > threads_) WriteOldestChunk();
}

void LasWriter::WriteOldestChunk() {
  const std::vector<std::uint8_t> bytes = pending_.front().get();
  pending_.erase(pending_.begin());
  out_.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  chunks_[chunks_.size() - pending_.size() - 1].bytes = static_cast<std::uint32_t>(bytes.size());
}

void LasWriter::Commit() {
  if (written_ != count_) {
    throw InvalidArgument(path_.string() + ": " + std::to_string(written_) + " points written, " +
                          std::to_string(count_) + " announced");
  }
  Flush();
  if (laz_) {
    if (laz_->points() > 0) WriteChunk();
    while (!pending_.empty()) WriteOldestChunk();
    const std::int64_t table_at = static_cast<std::int64_t>(out_.tellp());
    const std::vector<std::uint8_t> table = laz::EncodeChunkTable(chunks_, false);
    out_.write(reinterpret_cast<const char*>(table.data()), static_cast<std::streamsize>(table.size()));
    out_.seekp(static_cast<std::streamoff>(chunk_table_pointer_));
    Put<std::int64_t>(out_, table_at);
    out_.seekp(0, std::ios::end);
  }
  CommitCloudFile(&out_, tmp_, path_);
  committed_ = true;
}

PlyWriter::PlyWriter(const std::filesystem::path& path, std::uint64_t count, const std::string& crs_name)
    : path_(path), tmp_(TemporaryPathFor(path)), count_(count) {
  buffer_.resize(1 << 20);
  OpenCloudFile(&out_, tmp_, path_);
  out_ << "ply\nformat binary_little_endian 1.0\ncomment generated by aerotri\n";
  if (!crs_name.empty()) out_ << "comment crs " << crs_name << "\n";
  out_ << "element vertex " << count << "\n"
       << "property double x\nproperty double y\nproperty double z\n"
       << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
}

PlyWriter::~PlyWriter() {
  if (committed_) return;
  out_.close();
  std::error_code ec;
  std::filesystem::remove(tmp_, ec);
}

void PlyWriter::Add(const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& c) {
  if (written_ >= count_) throw InvalidArgument(path_.string() + ": more points than the " + std::to_string(count_) + " announced");
  char* record = buffer_.data() + used_;
  for (int k = 0; k < 3; ++k) std::memcpy(record + 8 * k, &p[k], 8);
  std::memcpy(record + 24, c.data(), 3);
  used_ += 27;
  ++written_;
  if (used_ + 27 > buffer_.size()) {
    out_.write(buffer_.data(), static_cast<std::streamsize>(used_));
    used_ = 0;
  }
}

void PlyWriter::Commit() {
  if (written_ != count_) {
    throw InvalidArgument(path_.string() + ": " + std::to_string(written_) + " points written, " +
                          std::to_string(count_) + " announced");
  }
  out_.write(buffer_.data(), static_cast<std::streamsize>(used_));
  used_ = 0;
  CommitCloudFile(&out_, tmp_, path_);
  committed_ = true;
}

bool IsCopcPath(const std::filesystem::path& path) {
  const std::string name = path.filename().string();
  return name.size() > 9 && name.compare(name.size() - 9, 9, ".copc.laz") == 0;
}

void WriteLas(const CrsCloud& cloud, const std::filesystem::path& path) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : cloud.xyz) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  auto write = [&](auto& writer) {
    for (size_t i = 0; i < cloud.xyz.size(); ++i) {
      writer.Add(cloud.xyz[i], i < cloud.rgb.size() ? cloud.rgb[i] : std::array<std::uint8_t, 3>{0, 0, 0},
                 i < cloud.classes.size() ? cloud.classes[i] : 1);  // 1: unclassified
    }
    writer.Commit();
  };
  if (IsCopcPath(path)) {
    CopcWriter copc(path, cloud.xyz.size(), lo, hi, cloud.crs_wkt);
    write(copc);
  } else {
    LasWriter las(path, cloud.xyz.size(), lo, hi, cloud.crs_wkt);
    write(las);
  }
}

void WritePly(const CrsCloud& cloud, const std::filesystem::path& path) {
  PlyWriter ply(path, cloud.xyz.size(), cloud.crs_name);
  for (size_t i = 0; i < cloud.xyz.size(); ++i) {
    ply.Add(cloud.xyz[i], i < cloud.rgb.size() ? cloud.rgb[i] : std::array<std::uint8_t, 3>{0, 0, 0});
  }
  ply.Commit();
}

namespace {

// The points of a LAZ file, chunk by chunk (the chunk table first: it is
// written last, so a file cut short has none, or a wrong one).
void ReadLazPoints(std::ifstream& in, const std::string& p, std::uint64_t point_offset, std::uint64_t data_end,
                   std::uint64_t n, const laz::LaszipVlr& vlr, std::size_t record_length, std::size_t batch_points,
                   const std::function<void(const std::string&, std::uint64_t)>& deliver) {
  std::int64_t table_at = -1;
  if (!in.seekg(static_cast<std::streamoff>(point_offset)) || !in.read(reinterpret_cast<char*>(&table_at), 8)) {
    throw ParseError(p, 0, "truncated LAZ point data");
  }
  if (table_at <= static_cast<std::int64_t>(point_offset + 8) || static_cast<std::uint64_t>(table_at) >= data_end) {
    throw ParseError(p, 0, "LAZ chunk table offset " + std::to_string(table_at) +
                               " outside the point data (a file cut short, or never finished)");
  }
  std::string table(data_end - static_cast<std::uint64_t>(table_at), '\0');
  if (!in.seekg(table_at) || !in.read(table.data(), static_cast<std::streamsize>(table.size()))) {
    throw ParseError(p, 0, "truncated LAZ chunk table");
  }
  const std::vector<laz::Chunk> chunks = laz::DecodeChunkTable(reinterpret_cast<const std::uint8_t*>(table.data()),
                                                               table.size(), vlr.chunk_size, n, p.c_str());
  std::uint64_t total = 0, bytes = 0;
  for (const laz::Chunk& c : chunks) {
    total += c.points;
    bytes += c.bytes;
  }
  if (total != n || point_offset + 8 + bytes != static_cast<std::uint64_t>(table_at)) {
    throw ParseError(p, 0, "LAZ chunk table (" + std::to_string(total) + " points in " + std::to_string(bytes) +
                               " bytes) does not match the header's " + std::to_string(n) + " points");
  }
  in.seekg(static_cast<std::streamoff>(point_offset + 8));
  std::string chunk, records;
  std::uint64_t held = 0;
  for (const laz::Chunk& c : chunks) {
    chunk.resize(c.bytes);
    if (!in.read(chunk.data(), static_cast<std::streamsize>(c.bytes))) throw ParseError(p, 0, "truncated LAZ chunk");
    laz::ChunkDecoder decoder(vlr.point_format, reinterpret_cast<const std::uint8_t*>(chunk.data()), chunk.size(), p.c_str());
    if (decoder.points() != c.points) {
      throw ParseError(p, 0, "LAZ chunk of " + std::to_string(decoder.points()) + " points where the table says " +
                                 std::to_string(c.points));
    }
    for (std::uint32_t i = 0; i < c.points; ++i) {
      records.resize((held + 1) * record_length);
      decoder.Next(reinterpret_cast<std::uint8_t*>(records.data()) + held * record_length);
      if (++held == batch_points) {
        deliver(records, held);
        held = 0;
      }
    }
  }
  if (held) deliver(records, held);
}

}  // namespace

LasHeader ReadLasInBatches(const std::filesystem::path& path, const std::function<void(CrsCloud&&)>& consume,
                           std::size_t batch_points) {
  const std::string p = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(p, std::string("cannot open: ") + std::strerror(errno));
  std::error_code ec;
  const std::uintmax_t file_size = std::filesystem::file_size(path, ec);
  std::string head(227, '\0');
  if (ec || !in.read(head.data(), 227) || head.compare(0, 4, "LASF") != 0) throw ParseError(p, 0, "not a LAS file");
  const auto minor = Get<std::uint8_t>(head, 25, p);
  const auto header_size = Get<std::uint16_t>(head, 94, p);
  const auto point_offset = Get<std::uint32_t>(head, 96, p);
  if (point_offset < header_size || point_offset > file_size) {
    throw ParseError(p, 0, "point data offset " + std::to_string(point_offset) + " outside the file");
  }
  // The header and the VLRs, all that precedes the points.
  head.resize(point_offset);
  if (!in.seekg(0) || !in.read(head.data(), point_offset)) throw ParseError(p, 0, "truncated LAS header");
  const auto num_vlrs = Get<std::uint32_t>(head, 100, p);
  const auto format = Get<std::uint8_t>(head, 104, p) & 0x3F;
  const auto record_length = Get<std::uint16_t>(head, 105, p);
  std::uint64_t n = Get<std::uint32_t>(head, 107, p);
  if (minor >= 4 && header_size >= 375) n = Get<std::uint64_t>(head, 247, p);
  double scale[3], offset[3];
  for (int k = 0; k < 3; ++k) {
    scale[k] = Get<double>(head, 131 + 8 * k, p);
    offset[k] = Get<double>(head, 155 + 8 * k, p);
  }
  int rgb_at = -1;
  switch (format) {
    case 0: case 1: case 6: break;
    case 2: rgb_at = 20; break;
    case 3: rgb_at = 28; break;
    case 7: case 8: rgb_at = 30; break;
    default: throw ParseError(p, 0, "LAS point format " + std::to_string(format) + " is not supported");
  }
  LasHeader header;
  header.count = n;
  const bool compressed = (Get<std::uint8_t>(head, 104, p) & 0xC0) != 0;
  std::optional<laz::LaszipVlr> laszip;
  size_t off = header_size;
  for (std::uint32_t v = 0; v < num_vlrs; ++v) {
    const auto record_id = Get<std::uint16_t>(head, off + 18, p);
    const auto length = Get<std::uint16_t>(head, off + 20, p);
    if (off + 54 + length > head.size()) throw ParseError(p, 0, "VLR " + std::to_string(v) + " runs past the point data");
    if (record_id == 2112) header.crs_wkt = std::string(head.c_str() + off + 54);
    if (record_id == 22204 && head.compare(off + 2, 14, "laszip encoded") == 0) {
      laszip = laz::ParseLaszipVlr(reinterpret_cast<const std::uint8_t*>(head.data()) + off + 54, length, p.c_str());
    }
    off += 54 + length;
  }
  // Each batch of records becomes a cloud.
  const auto deliver = [&](const std::string& data, std::uint64_t m) {
    CrsCloud cloud;
    cloud.crs_wkt = header.crs_wkt;
    cloud.xyz.resize(m);
    cloud.classes.resize(m);
    if (rgb_at >= 0) cloud.rgb.resize(m);
    for (std::uint64_t i = 0; i < m; ++i) {
      const size_t r = i * record_length;
      for (int k = 0; k < 3; ++k) cloud.xyz[i][k] = Get<std::int32_t>(data, r + 4 * k, p) * scale[k] + offset[k];
      // Formats 0-5: 5 bits of byte 15; formats 6-10: byte 16.
      cloud.classes[i] = format >= 6 ? Get<std::uint8_t>(data, r + 16, p) : Get<std::uint8_t>(data, r + 15, p) & 0x1F;
      if (rgb_at >= 0) {
        for (int k = 0; k < 3; ++k) {
          cloud.rgb[i][k] = static_cast<std::uint8_t>(Get<std::uint16_t>(data, r + rgb_at + 2 * k, p) >> 8);
        }
      }
    }
    consume(std::move(cloud));
  };
  batch_points = std::max<std::size_t>(1, batch_points);
  if (compressed) {
    if (!laszip) throw ParseError(p, 0, "compressed point data (format byte " + std::to_string(Get<std::uint8_t>(head, 104, p)) + ") without a LASzip VLR");
    if (laszip->point_format != format || record_length != (format == 7 ? 36 : 30)) {
      throw ParseError(p, 0, "LAZ items (point format " + std::to_string(laszip->point_format) +
                                 ") do not match the header's point format " + std::to_string(format) +
                                 " of " + std::to_string(record_length) + " bytes");
    }
    const std::uint64_t evlrs = minor >= 4 && header_size >= 375 ? Get<std::uint64_t>(head, 235, p) : 0;
    ReadLazPoints(in, p, point_offset, evlrs ? evlrs : file_size, n, *laszip, record_length, batch_points, deliver);
    return header;
  }
  if (record_length == 0 || point_offset + n * record_length > file_size) {
    throw ParseError(p, 0, "truncated LAS point data");
  }
  std::string data;
  for (std::uint64_t first = 0; first < n; first += batch_points) {
    const std::uint64_t m = std::min<std::uint64_t>(batch_points, n - first);
    data.resize(m * record_length);
    if (!in.read(data.data(), static_cast<std::streamsize>(data.size()))) throw ParseError(p, 0, "truncated LAS point data");
    deliver(data, m);
  }
  return header;
}

CrsCloud ReadLas(const std::filesystem::path& path) {
  CrsCloud cloud;
  const LasHeader header = ReadLasInBatches(path, [&](CrsCloud&& batch) {
    cloud.xyz.insert(cloud.xyz.end(), batch.xyz.begin(), batch.xyz.end());
    cloud.classes.insert(cloud.classes.end(), batch.classes.begin(), batch.classes.end());
    cloud.rgb.insert(cloud.rgb.end(), batch.rgb.begin(), batch.rgb.end());
  });
  cloud.crs_wkt = header.crs_wkt;
  return cloud;
}

}  // namespace aerotri
