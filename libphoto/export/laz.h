// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// LAZ: LAS 1.4 point records compressed as LASzip does it, written and read
// from the published format (LASzip's "layered chunked" compressor 3, the
// point items POINT14 v3 and RGB14 v3; the format of LASzip 3.x, LAZ 1.4, and
// of COPC's point chunks). Debian packages no LAZ library (LASzip, LAZperf,
// PDAL), so this is aerotri's own, small and self-contained, tested against
// an independent decoder (laz-perf, tests/las/check_laz.mjs).
//
// A chunk holds its first point raw, then the point count, then per layer
// its byte count, then the layers: each field group (returns and XY, Z,
// classification, flags, intensity, scan angle, user data, point source,
// GPS time; RGB) coded by its own adaptive arithmetic coder, so that a reader
// can skip what it does not need. A layer whose field never changes in the
// chunk is left out (byte count 0). The chunk table at the end of the point
// data gives each chunk's byte size (and point count for chunks of varying
// size), arithmetic-coded as well.
//
// Scope: point formats 6 (30 bytes) and 7 (36 bytes, RGB), every field of
// them, one scanner channel (channel 0: photogrammetric clouds have no
// scanner channels); a record with another channel is refused when written
// and reported when read.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace aerotri::laz {

constexpr std::uint32_t kDefaultChunkSize = 50000;
constexpr std::uint32_t kVariableChunkSize = 0xFFFFFFFFu;  // COPC: one chunk per octree node

// The payload of the LASzip VLR (user "laszip encoded", record 22204) for
// point format 6 or 7.
std::vector<std::uint8_t> LaszipVlrPayload(int point_format, std::uint32_t chunk_size);

struct LaszipVlr {
  std::uint16_t compressor = 0;
  std::uint32_t chunk_size = 0;
  int point_format = 0;  // 6 or 7, from the items
};
// Throws ParseError (naming `path`) for a LASzip VLR this reader cannot read.
LaszipVlr ParseLaszipVlr(const std::uint8_t* data, std::size_t size, const char* path);

struct Chunk {
  std::uint32_t points = 0;
  std::uint32_t bytes = 0;
};

// One chunk's bytes from its n records (30 or 36 bytes each, LAS 1.4
// layout): the first point raw, the count, the layer sizes, the layers.
std::vector<std::uint8_t> CompressChunk(int point_format, const std::uint8_t* records, std::uint32_t n);

// Collects the records of one chunk, to be compressed where the caller
// likes (Release, then Compress on a thread of its own).
class ChunkEncoder {
 public:
  explicit ChunkEncoder(int point_format);
  ~ChunkEncoder();
  ChunkEncoder(const ChunkEncoder&) = delete;
  ChunkEncoder& operator=(const ChunkEncoder&) = delete;
  void Add(const std::uint8_t* record);  // 30 or 36 bytes, LAS 1.4 layout
  std::uint32_t points() const { return points_; }
  // The collected records as a chunk of their own (to compress elsewhere);
  // this one starts empty.
  ChunkEncoder Release();
  std::vector<std::uint8_t> Compress() const { return CompressChunk(format_, records_.data(), points_); }
  ChunkEncoder(ChunkEncoder&&) = default;

 private:
  int format_;
  std::uint32_t points_ = 0;
  std::vector<std::uint8_t> records_;
};

// Decompresses one chunk, record by record. Throws ParseError on a chunk
// that ends early or is not what the format allows.
class ChunkDecoder {
 public:
  ChunkDecoder(int point_format, const std::uint8_t* data, std::size_t size, const char* path);
  ~ChunkDecoder();
  ChunkDecoder(const ChunkDecoder&) = delete;
  ChunkDecoder& operator=(const ChunkDecoder&) = delete;
  std::uint32_t points() const { return points_; }  // as the chunk states it
  void Next(std::uint8_t* record);

 private:
  struct State;
  int format_;
  std::uint32_t points_ = 0, read_ = 0;
  std::vector<std::uint8_t> first_;
  std::unique_ptr<State> state_;
  const char* path_;
};

// The chunk table: version 0, the number of chunks, then the sizes coded.
std::vector<std::uint8_t> EncodeChunkTable(const std::vector<Chunk>& chunks, bool variable_size);
// `fixed_size`: the VLR's chunk size (points of every chunk but the last),
// or kVariableChunkSize; `total_points` completes a fixed-size table.
std::vector<Chunk> DecodeChunkTable(const std::uint8_t* data, std::size_t size, std::uint32_t fixed_size,
                                    std::uint64_t total_points, const char* path);

}  // namespace aerotri::laz
