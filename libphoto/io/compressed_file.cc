// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/compressed_file.h"

#include <bzlib.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"

namespace aerotri {
namespace {

constexpr std::uint64_t kBlockMagic = 0x314159265359ULL;  // pi
constexpr std::uint64_t kEndMagic = 0x177245385090ULL;    // sqrt(pi)
constexpr std::uint64_t kMask48 = (1ULL << 48) - 1;

// Decompresses one or more concatenated bzip2 streams. Returns false with a
// message on corrupt or truncated input.
bool DecompressStreams(const char* data, size_t size, std::string* out, std::string* error) {
  out->clear();
  size_t produced = 0;
  size_t consumed = 0;
  out->resize(size * 5 + (1 << 16));
  while (consumed < size) {
    bz_stream stream{};
    if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) {
      *error = "cannot initialise bzip2 decompression";
      return false;
    }
    stream.next_in = const_cast<char*>(data + consumed);
    stream.avail_in = static_cast<unsigned int>(size - consumed);
    while (true) {
      if (produced == out->size()) out->resize(out->size() * 2);
      stream.next_out = out->data() + produced;
      stream.avail_out = static_cast<unsigned int>(out->size() - produced);
      const int rc = BZ2_bzDecompress(&stream);
      produced = out->size() - stream.avail_out;
      if (rc == BZ_STREAM_END) break;
      if (rc != BZ_OK) {
        BZ2_bzDecompressEnd(&stream);
        *error = "corrupt bzip2 data (libbz2 error " + std::to_string(rc) + ")";
        return false;
      }
      if (stream.avail_in == 0 && stream.avail_out != 0) {
        BZ2_bzDecompressEnd(&stream);
        *error = "truncated bzip2 file: the stream ends before its end marker";
        return false;
      }
    }
    consumed = size - stream.avail_in;
    BZ2_bzDecompressEnd(&stream);
    // Another stream may follow (pbzip2 / lbzip2 output); anything else ends it.
    if (size - consumed < 4 || data[consumed] != 'B' || data[consumed + 1] != 'Z' ||
        data[consumed + 2] != 'h') {
      break;
    }
  }
  out->resize(produced);
  return true;
}

class BitWriter {
 public:
  void Put(std::uint64_t value, int bits) {
    for (int i = bits - 1; i >= 0; --i) PutBit((value >> i) & 1U);
  }
  void PutBit(unsigned bit) {
    current_ = static_cast<unsigned char>((current_ << 1) | bit);
    if (++filled_ == 8) {
      bytes_.push_back(static_cast<char>(current_));
      current_ = 0;
      filled_ = 0;
    }
  }
  // Copies bits [from, to) of data.
  void CopyBits(const std::string& data, std::uint64_t from, std::uint64_t to) {
    std::uint64_t b = from;
    while (b < to && (b % 8) != 0) PutBit(Bit(data, b++));
    if (filled_ == 0) {
      while (b + 8 <= to) {
        bytes_.push_back(data[b / 8]);
        b += 8;
      }
    } else {
      while (b + 8 <= to) {
        Put(static_cast<unsigned char>(data[b / 8]), 8);
        b += 8;
      }
    }
    while (b < to) PutBit(Bit(data, b++));
  }
  std::string Finish() {
    while (filled_ != 0) PutBit(0);
    return std::move(bytes_);
  }
  static unsigned Bit(const std::string& data, std::uint64_t b) {
    return (static_cast<unsigned char>(data[b / 8]) >> (7 - b % 8)) & 1U;
  }

 private:
  std::string bytes_;
  unsigned char current_ = 0;
  int filled_ = 0;
};

// Bit offsets of every block magic and end-of-stream magic in [begin, end).
void FindMagics(const std::string& raw, size_t begin, size_t end,
                std::vector<std::pair<std::uint64_t, bool>>* found) {
  std::uint64_t window = 0;
  const size_t warm = begin >= 6 ? begin - 6 : 0;
  for (size_t i = warm; i < end; ++i) {
    const unsigned byte = static_cast<unsigned char>(raw[i]);
    for (int k = 7; k >= 0; --k) {
      window = (window << 1) | ((byte >> k) & 1U);
      const std::uint64_t w = window & kMask48;
      if ((w == kBlockMagic || w == kEndMagic) && i >= begin) {
        const std::uint64_t bit_end = i * 8 + (8 - k);
        if (bit_end >= 48) found->emplace_back(bit_end - 48, w == kBlockMagic);
      }
    }
  }
}

// bzip2 compresses in independent blocks of up to 900 kB: decompress them on
// all cores (the lbzip2 approach). Each block is re-wrapped as a one-block
// stream whose stream CRC equals the block CRC, so libbz2 still verifies every
// byte. Returns false when the layout is not as expected (the caller then
// decompresses serially and reports any corruption).
bool DecompressBlocksInParallel(const std::string& raw, std::string* out) {
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  if (threads < 2 || raw.size() < (1u << 20)) return false;
  std::vector<std::pair<std::uint64_t, bool>> magics;
  {
    std::vector<std::pair<std::uint64_t, bool>> second;
    const size_t mid = raw.size() / 2;
    std::thread helper([&] { FindMagics(raw, mid, raw.size(), &second); });
    FindMagics(raw, 4, mid, &magics);
    helper.join();
    magics.insert(magics.end(), second.begin(), second.end());
  }
  std::vector<std::pair<std::uint64_t, std::uint64_t>> blocks;  // [start, end) bits
  for (size_t i = 0; i + 1 < magics.size(); ++i) {
    if (magics[i].second) blocks.emplace_back(magics[i].first, magics[i + 1].first);
  }
  if (blocks.size() < 2 || magics.back().second) return false;

  std::vector<std::string> parts(blocks.size());
  std::atomic<bool> ok{true};
  ParallelFor(blocks.size(), threads, [&](size_t b) {
    if (!ok) return;
    std::string error;
    const auto [start, stop] = blocks[b];
    if (stop - start < 48 + 32) {
      ok = false;
      return;
    }
    BitWriter writer;
    writer.Put('B', 8);
    writer.Put('Z', 8);
    writer.Put('h', 8);
    writer.Put('9', 8);
    writer.CopyBits(raw, start, stop);
    writer.Put(kEndMagic, 48);
    std::uint64_t crc = 0;
    for (std::uint64_t i = start + 48; i < start + 80; ++i) crc = (crc << 1) | BitWriter::Bit(raw, i);
    writer.Put(crc, 32);
    const std::string stream = writer.Finish();
    if (!DecompressStreams(stream.data(), stream.size(), &parts[b], &error)) ok = false;
  });
  if (!ok) return false;
  size_t total = 0;
  for (const auto& p : parts) total += p.size();
  out->clear();
  out->reserve(total);
  for (const auto& p : parts) out->append(p);
  return true;
}

}  // namespace

std::string ReadMaybeCompressedFile(const std::filesystem::path& path) {
  std::string raw = ReadTextFile(path);
  if (raw.size() < 4 || raw.compare(0, 3, "BZh") != 0) return raw;
  std::string out;
  if (DecompressBlocksInParallel(raw, &out)) return out;
  std::string error;
  if (!DecompressStreams(raw.data(), raw.size(), &out, &error)) {
    throw IoError(path.string(), error);
  }
  return out;
}

}  // namespace aerotri
