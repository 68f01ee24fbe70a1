// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/laz.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>

#include "libphoto/base/error.h"

namespace aerotri::laz {
namespace {

// ---------------------------------------------------------------------------
// Adaptive arithmetic coding (the coder LASzip uses: Amir Said's FastAC, 32-bit
// interval, periodic model updates). Encoder and decoder share the models.
// ---------------------------------------------------------------------------

constexpr std::uint32_t kMinLength = 0x01000000u;  // renormalise below this
constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;
constexpr std::uint32_t kBitShift = 13;  // bit models: length bits dropped before the product
constexpr std::uint32_t kBitMaxCount = 1u << kBitShift;
constexpr std::uint32_t kSymbolShift = 15;  // symbol models
constexpr std::uint32_t kSymbolMaxCount = 1u << kSymbolShift;

struct BitModel {
  std::uint32_t update_cycle = 4, until_update = 4;
  std::uint32_t bit_0_prob = 1u << (kBitShift - 1), bit_0_count = 1, bit_count = 2;

  void Update() {
    if ((bit_count += update_cycle) > kBitMaxCount) {  // halve the counts
      bit_count = (bit_count + 1) >> 1;
      bit_0_count = (bit_0_count + 1) >> 1;
      if (bit_0_count == bit_count) ++bit_count;
    }
    const std::uint32_t scale = 0x80000000u / bit_count;
    bit_0_prob = (bit_0_count * scale) >> (31 - kBitShift);
    update_cycle = std::min<std::uint32_t>((5 * update_cycle) >> 2, 64);
    until_update = update_cycle;
  }
};

struct SymbolModel {
  explicit SymbolModel(std::uint32_t n) : symbols(n), distribution(n), count(n, 1) {
    update_cycle = n;
    Update();
    until_update = update_cycle = (n + 6) >> 1;
  }
  void Update() {
    if ((total += update_cycle) > kSymbolMaxCount) {
      total = 0;
      for (std::uint32_t& c : count) total += (c = (c + 1) >> 1);
    }
    const std::uint32_t scale = 0x80000000u / total;
    std::uint32_t sum = 0;
    for (std::uint32_t k = 0; k < symbols; ++k) {
      distribution[k] = (scale * sum) >> (31 - kSymbolShift);
      sum += count[k];
    }
    update_cycle = std::min((5 * update_cycle) >> 2, (symbols + 6) << 3);
    until_update = update_cycle;
  }
  std::uint32_t symbols;
  std::vector<std::uint32_t> distribution, count;
  std::uint32_t total = 0, update_cycle = 0, until_update = 0;
};

class Encoder {
 public:
  void EncodeBit(BitModel& m, std::uint32_t bit) {
    const std::uint32_t x = m.bit_0_prob * (length_ >> kBitShift);
    if (bit == 0) {
      length_ = x;
      ++m.bit_0_count;
    } else {
      Advance(x);
      length_ -= x;
    }
    if (length_ < kMinLength) Renormalise();
    if (--m.until_update == 0) m.Update();
  }
  void EncodeSymbol(SymbolModel& m, std::uint32_t sym) {
    std::uint32_t x;
    if (sym == m.symbols - 1) {
      x = m.distribution[sym] * (length_ >> kSymbolShift);
      Advance(x);
      length_ -= x;
    } else {
      x = m.distribution[sym] * (length_ >>= kSymbolShift);
      Advance(x);
      length_ = m.distribution[sym + 1] * length_ - x;
    }
    if (length_ < kMinLength) Renormalise();
    ++m.count[sym];
    if (--m.until_update == 0) m.Update();
  }
  void WriteBits(std::uint32_t bits, std::uint32_t value) {
    if (bits > 19) {
      WriteShort(static_cast<std::uint16_t>(value & 0xFFFF));
      value >>= 16;
      bits -= 16;
    }
    Advance(value * (length_ >>= bits));
    if (length_ < kMinLength) Renormalise();
  }
  void WriteShort(std::uint16_t value) { WriteBits(16, value); }
  void WriteInt(std::uint32_t value) {
    WriteShort(static_cast<std::uint16_t>(value & 0xFFFF));
    WriteShort(static_cast<std::uint16_t>(value >> 16));
  }
  // Final bytes: enough for the decoder's four-byte window to settle.
  void Done() {
    const std::uint32_t before = base_;
    bool another_byte = true;
    if (length_ > 2 * kMinLength) {
      base_ += kMinLength;
      length_ = kMinLength >> 1;
    } else {
      base_ += kMinLength >> 1;
      length_ = kMinLength >> 9;
      another_byte = false;
    }
    if (before > base_) PropagateCarry();
    Renormalise();
    out_.push_back(0);
    out_.push_back(0);
    if (another_byte) out_.push_back(0);
  }
  std::vector<std::uint8_t>& bytes() { return out_; }

 private:
  void Advance(std::uint32_t x) {
    const std::uint32_t before = base_;
    base_ += x;
    if (before > base_) PropagateCarry();  // overflow: carry into the bytes out
  }
  void PropagateCarry() {
    for (std::size_t i = out_.size(); i-- > 0;) {
      if (out_[i] != 0xFF) {
        ++out_[i];
        return;
      }
      out_[i] = 0;
    }
  }
  void Renormalise() {
    do {
      out_.push_back(static_cast<std::uint8_t>(base_ >> 24));
      base_ <<= 8;
    } while ((length_ <<= 8) < kMinLength);
  }
  std::vector<std::uint8_t> out_;
  std::uint32_t base_ = 0, length_ = kMaxLength;
};

class Decoder {
 public:
  Decoder(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {
    for (int i = 0; i < 4; ++i) value_ = (value_ << 8) | NextByte();
  }
  std::uint32_t DecodeBit(BitModel& m) {
    const std::uint32_t x = m.bit_0_prob * (length_ >> kBitShift);
    const std::uint32_t bit = value_ >= x;
    if (bit == 0) {
      length_ = x;
      ++m.bit_0_count;
    } else {
      value_ -= x;
      length_ -= x;
    }
    if (length_ < kMinLength) Renormalise();
    if (--m.until_update == 0) m.Update();
    return bit;
  }
  std::uint32_t DecodeSymbol(SymbolModel& m) {
    // Bisection on the cumulative distribution (the encoder's own numbers).
    std::uint32_t n = m.symbols, sym = 0, x = 0, y = length_;
    length_ >>= kSymbolShift;
    std::uint32_t k = n >> 1;
    do {
      const std::uint32_t z = length_ * m.distribution[k];
      if (z > value_) {
        n = k;
        y = z;
      } else {
        sym = k;
        x = z;
      }
    } while ((k = (sym + n) >> 1) != sym);
    value_ -= x;
    length_ = y - x;
    if (length_ < kMinLength) Renormalise();
    ++m.count[sym];
    if (--m.until_update == 0) m.Update();
    return sym;
  }
  std::uint32_t ReadBits(std::uint32_t bits) {
    if (bits > 19) {
      const std::uint32_t low = ReadShort();
      return (ReadBits(bits - 16) << 16) | low;
    }
    const std::uint32_t sym = value_ / (length_ >>= bits);
    value_ -= length_ * sym;
    if (length_ < kMinLength) Renormalise();
    return sym;
  }
  std::uint32_t ReadShort() { return ReadBits(16); }
  std::uint32_t ReadInt() {
    const std::uint32_t low = ReadShort();
    return (ReadShort() << 16) | low;
  }
  bool overrun() const { return overrun_; }

 private:
  std::uint8_t NextByte() {
    if (pos_ < size_) return data_[pos_++];
    // The encoder's final bytes keep a whole stream inside; reading past
    // them means the layer was cut short.
    if (++past_ > 4) overrun_ = true;
    return 0;
  }
  void Renormalise() {
    do value_ = (value_ << 8) | NextByte();
    while ((length_ <<= 8) < kMinLength);
  }
  const std::uint8_t* data_;
  std::size_t size_, pos_ = 0;
  int past_ = 0;
  bool overrun_ = false;
  std::uint32_t value_ = 0, length_ = kMaxLength;
};

// Integers coded as a correction to a prediction: the correction's bit
// length k by context, then its value within the k-bit interval.
class IntegerCoder {
 public:
  IntegerCoder(std::uint32_t bits, std::uint32_t contexts, std::uint32_t bits_high = 8) : bits_high_(bits_high) {
    if (bits && bits < 32) {
      corr_bits_ = bits;
      corr_range_ = 1u << bits;
      corr_min_ = -static_cast<std::int32_t>(corr_range_ / 2);
      corr_max_ = corr_min_ + static_cast<std::int32_t>(corr_range_ - 1);
    }
    for (std::uint32_t i = 0; i < contexts; ++i) k_models_.emplace_back(corr_bits_ + 1);
    for (std::uint32_t i = 1; i <= corr_bits_; ++i) corrector_.emplace_back(1u << std::min(i, bits_high_));
  }
  void Compress(Encoder& enc, std::int32_t pred, std::int32_t real, std::uint32_t context) {
    std::int32_t corr = Wrap(static_cast<std::uint32_t>(real) - static_cast<std::uint32_t>(pred));
    if (corr_range_) {
      if (corr < corr_min_) corr += static_cast<std::int32_t>(corr_range_);
      else if (corr > corr_max_) corr -= static_cast<std::int32_t>(corr_range_);
    }
    WriteCorrector(enc, corr, k_models_[context]);
  }
  std::int32_t Decompress(Decoder& dec, std::int32_t pred, std::uint32_t context) {
    const std::int32_t corr = ReadCorrector(dec, k_models_[context]);
    std::int64_t real = static_cast<std::int64_t>(Wrap(static_cast<std::uint32_t>(pred) + static_cast<std::uint32_t>(corr)));
    if (corr_range_) {
      if (real < 0) real += corr_range_;
      else if (real >= static_cast<std::int64_t>(corr_range_)) real -= corr_range_;
    }
    return static_cast<std::int32_t>(real);
  }
  std::uint32_t k() const { return k_; }

 private:
  static std::int32_t Wrap(std::uint32_t v) {
    std::int32_t r;
    std::memcpy(&r, &v, 4);
    return r;
  }
  void WriteCorrector(Encoder& enc, std::int32_t c, SymbolModel& k_model) {
    // The tightest interval [-(2^k - 1), 2^k] holding c.
    std::uint32_t c1 = c <= 0 ? 0u - static_cast<std::uint32_t>(c) : static_cast<std::uint32_t>(c) - 1;
    k_ = 0;
    while (c1) {
      c1 >>= 1;
      ++k_;
    }
    enc.EncodeSymbol(k_model, k_);
    if (k_ == 0) {
      enc.EncodeBit(bit_model_, static_cast<std::uint32_t>(c));  // c is 0 or 1
      return;
    }
    if (k_ >= 32) return;  // only the interval's minimum lives there
    // Into [0, 2^k - 1]: negatives by adding 2^k - 1, positives by subtracting 1.
    std::uint32_t v = c < 0 ? static_cast<std::uint32_t>(static_cast<std::int64_t>(c) + ((std::int64_t{1} << k_) - 1))
                            : static_cast<std::uint32_t>(c - 1);
    if (k_ <= bits_high_) {
      enc.EncodeSymbol(corrector_[k_ - 1], v);
    } else {  // the high bits modelled, the low ones raw
      const std::uint32_t low_bits = k_ - bits_high_;
      enc.EncodeSymbol(corrector_[k_ - 1], v >> low_bits);
      enc.WriteBits(low_bits, v & ((1u << low_bits) - 1));
    }
  }
  std::int32_t ReadCorrector(Decoder& dec, SymbolModel& k_model) {
    k_ = dec.DecodeSymbol(k_model);
    if (k_ == 0) return static_cast<std::int32_t>(dec.DecodeBit(bit_model_));
    if (k_ >= 32) return corr_min_;
    std::uint32_t v;
    if (k_ <= bits_high_) {
      v = dec.DecodeSymbol(corrector_[k_ - 1]);
    } else {
      const std::uint32_t low_bits = k_ - bits_high_;
      v = dec.DecodeSymbol(corrector_[k_ - 1]) << low_bits;
      v |= dec.ReadBits(low_bits);
    }
    if (v >= (1u << (k_ - 1))) return static_cast<std::int32_t>(static_cast<std::int64_t>(v) + 1);
    return static_cast<std::int32_t>(static_cast<std::int64_t>(v) - ((std::int64_t{1} << k_) - 1));
  }
  std::uint32_t bits_high_, corr_bits_ = 32, corr_range_ = 0;
  std::int32_t corr_min_ = INT32_MIN, corr_max_ = INT32_MAX;
  std::vector<SymbolModel> k_models_, corrector_;
  BitModel bit_model_;
  std::uint32_t k_ = 0;
};

// ---------------------------------------------------------------------------
// The point record, as the POINT14 layers see it.
// ---------------------------------------------------------------------------

struct Point14 {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint32_t r = 0, n = 0;  // return number, number of returns (4 bits each)
  std::uint32_t class_flags = 0, channel = 0, scan_direction = 0, edge = 0;
  std::uint32_t classification = 0, user_data = 0;
  std::int16_t scan_angle = 0;
  std::uint16_t point_source = 0;
  std::uint64_t gps_bits = 0;
  bool gps_time_change = false;

  std::uint32_t Flags() const { return (edge << 5) | (scan_direction << 4) | class_flags; }
};

template <typename T>
T Load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}
template <typename T>
void Store(std::uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

Point14 Unpack(const std::uint8_t* b) {
  Point14 p;
  p.x = Load<std::int32_t>(b);
  p.y = Load<std::int32_t>(b + 4);
  p.z = Load<std::int32_t>(b + 8);
  p.intensity = Load<std::uint16_t>(b + 12);
  p.r = b[14] & 0xF;
  p.n = b[14] >> 4;
  p.class_flags = b[15] & 0xF;
  p.channel = (b[15] >> 4) & 3;
  p.scan_direction = (b[15] >> 6) & 1;
  p.edge = b[15] >> 7;
  p.classification = b[16];
  p.user_data = b[17];
  p.scan_angle = Load<std::int16_t>(b + 18);
  p.point_source = Load<std::uint16_t>(b + 20);
  p.gps_bits = Load<std::uint64_t>(b + 22);
  return p;
}

void Pack(const Point14& p, std::uint8_t* b) {
  Store(b, p.x);
  Store(b + 4, p.y);
  Store(b + 8, p.z);
  Store(b + 12, p.intensity);
  b[14] = static_cast<std::uint8_t>(p.r | (p.n << 4));
  b[15] = static_cast<std::uint8_t>(p.class_flags | (p.channel << 4) | (p.scan_direction << 6) | (p.edge << 7));
  b[16] = static_cast<std::uint8_t>(p.classification);
  b[17] = static_cast<std::uint8_t>(p.user_data);
  Store(b + 18, p.scan_angle);
  Store(b + 20, p.point_source);
  Store(b + 22, p.gps_bits);
}

// The median of the last five values, kept as LASzip's prediction of the
// next X or Y difference.
class StreamingMedian5 {
 public:
  std::int32_t Get() const { return v_[2]; }
  void Add(std::int32_t x) {
    if (high_) {
      if (x < v_[2]) {
        v_[4] = v_[3];
        v_[3] = v_[2];
        if (x < v_[0]) {
          v_[2] = v_[1];
          v_[1] = v_[0];
          v_[0] = x;
        } else if (x < v_[1]) {
          v_[2] = v_[1];
          v_[1] = x;
        } else {
          v_[2] = x;
        }
      } else {
        if (x < v_[3]) {
          v_[4] = v_[3];
          v_[3] = x;
        } else {
          v_[4] = x;
        }
        high_ = false;
      }
    } else {
      if (v_[2] < x) {
        v_[0] = v_[1];
        v_[1] = v_[2];
        if (v_[4] < x) {
          v_[2] = v_[3];
          v_[3] = v_[4];
          v_[4] = x;
        } else if (v_[3] < x) {
          v_[2] = v_[3];
          v_[3] = x;
        } else {
          v_[2] = x;
        }
      } else {
        if (v_[1] < x) {
          v_[0] = v_[1];
          v_[1] = x;
        } else {
          v_[0] = x;
        }
        high_ = true;
      }
    }
  }

 private:
  std::array<std::int32_t, 5> v_{};
  bool high_ = true;
};

// Contexts from (number of returns, return number): LASzip's tables.
constexpr std::uint8_t kReturnMap6[16][16] = {
    {0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5}, {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
    {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3}, {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
    {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};
// The level of penetration, |n - r|, stopped at 7.
std::uint32_t ReturnLevel8(std::uint32_t n, std::uint32_t r) { return std::min<std::uint32_t>(n > r ? n - r : r - n, 7); }
std::uint32_t ZeroBit0(std::uint32_t v) { return v & 0xFFFFFFFEu; }

// GPS time: differences of the doubles' bit patterns as integers,
// predicted from the last difference by a multiplier; up to four
// interleaved time sequences.
constexpr std::int32_t kGpsMulti = 500, kGpsMultiMinus = -10;
constexpr std::uint32_t kGpsCodeFull = kGpsMulti - kGpsMultiMinus + 1;  // 511
constexpr std::uint32_t kGpsSymbols = kGpsMulti - kGpsMultiMinus + 5;   // 515

std::int32_t Mul(std::int32_t a, std::int32_t b) {  // two's complement, as the format's C does it
  const std::uint32_t v = static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b);
  std::int32_t r;
  std::memcpy(&r, &v, 4);
  return r;
}
bool FitsInt32(std::int64_t v) { return v == static_cast<std::int32_t>(v); }
// Differences and sums of the times' bit patterns wrap, as the format's C does.
std::int64_t Sub64(std::int64_t a, std::int64_t b) {
  return static_cast<std::int64_t>(static_cast<std::uint64_t>(a) - static_cast<std::uint64_t>(b));
}
std::int64_t Add64(std::int64_t a, std::int64_t b) {
  return static_cast<std::int64_t>(static_cast<std::uint64_t>(a) + static_cast<std::uint64_t>(b));
}

std::int32_t Quantize(float f) {
  f = std::clamp(f, -1e6f, 1e6f);  // only comparisons with small multipliers follow
  return f >= 0 ? static_cast<std::int32_t>(f + 0.5f) : static_cast<std::int32_t>(f - 0.5f);
}

struct GpsTimeState {
  SymbolModel multi{kGpsSymbols}, zero_diff{5};
  IntegerCoder ic{32, 9};
  std::uint32_t last = 0, next = 0;
  std::array<std::int64_t, 4> last_time{};  // bit patterns, as signed integers
  std::array<std::int32_t, 4> last_diff{}, extreme{};

  void CountExtreme(std::int32_t diff) {
    if (++extreme[last] > 3) {
      last_diff[last] = diff;
      extreme[last] = 0;
    }
  }
  void StartSequence(Encoder& enc, std::int64_t t) {
    ic.Compress(enc, static_cast<std::int32_t>(static_cast<std::uint64_t>(last_time[last]) >> 32),
                static_cast<std::int32_t>(static_cast<std::uint64_t>(t) >> 32), 8);
    enc.WriteInt(static_cast<std::uint32_t>(static_cast<std::uint64_t>(t)));
    next = (next + 1) & 3;
    last = next;
    last_diff[last] = 0;
    extreme[last] = 0;
  }
  // Another of the four sequences within 32 bits of t, or 0.
  std::uint32_t OtherSequence(std::int64_t t) const {
    for (std::uint32_t i = 1; i < 4; ++i) {
      if (FitsInt32(Sub64(t, last_time[(last + i) & 3]))) return i;
    }
    return 0;
  }

  void Write(Encoder& enc, std::int64_t t) {
    const std::int64_t diff64 = Sub64(t, last_time[last]);
    const bool fits = FitsInt32(diff64);
    const std::int32_t diff = static_cast<std::int32_t>(diff64);
    if (last_diff[last] == 0) {
      if (fits) {
        enc.EncodeSymbol(zero_diff, 0);
        ic.Compress(enc, 0, diff, 0);
        last_diff[last] = diff;
        extreme[last] = 0;
      } else if (const std::uint32_t i = OtherSequence(t)) {
        enc.EncodeSymbol(zero_diff, i + 1);
        last = (last + i) & 3;
        return Write(enc, t);
      } else {
        enc.EncodeSymbol(zero_diff, 1);
        StartSequence(enc, t);
      }
      last_time[last] = t;
      return;
    }
    if (!fits) {
      if (const std::uint32_t i = OtherSequence(t)) {
        enc.EncodeSymbol(multi, kGpsCodeFull + i);
        last = (last + i) & 3;
        return Write(enc, t);
      }
      enc.EncodeSymbol(multi, kGpsCodeFull);
      StartSequence(enc, t);
      last_time[last] = t;
      return;
    }
    const std::int32_t m = Quantize(static_cast<float>(diff) / static_cast<float>(last_diff[last]));
    const std::int32_t ld = last_diff[last];
    if (m == 1) {
      enc.EncodeSymbol(multi, 1);
      ic.Compress(enc, ld, diff, 1);
      extreme[last] = 0;
    } else if (m > 0 && m < kGpsMulti) {
      enc.EncodeSymbol(multi, static_cast<std::uint32_t>(m));
      ic.Compress(enc, Mul(m, ld), diff, m < 10 ? 2 : 3);
    } else if (m >= kGpsMulti) {
      enc.EncodeSymbol(multi, kGpsMulti);
      ic.Compress(enc, Mul(kGpsMulti, ld), diff, 4);
      CountExtreme(diff);
    } else if (m < 0 && m > kGpsMultiMinus) {
      enc.EncodeSymbol(multi, static_cast<std::uint32_t>(kGpsMulti - m));
      ic.Compress(enc, Mul(m, ld), diff, 5);
    } else if (m < 0) {
      enc.EncodeSymbol(multi, static_cast<std::uint32_t>(kGpsMulti - kGpsMultiMinus));
      ic.Compress(enc, Mul(kGpsMultiMinus, ld), diff, 6);
      CountExtreme(diff);
    } else {
      enc.EncodeSymbol(multi, 0);
      ic.Compress(enc, 0, diff, 7);
      CountExtreme(diff);
    }
    last_time[last] = t;
  }

  void ReadNewSequence(Decoder& dec) {
    next = (next + 1) & 3;
    const std::uint64_t high = static_cast<std::uint32_t>(
        ic.Decompress(dec, static_cast<std::int32_t>(static_cast<std::uint64_t>(last_time[last]) >> 32), 8));
    last_time[next] = static_cast<std::int64_t>((high << 32) | dec.ReadInt());
    last = next;
    last_diff[last] = 0;
    extreme[last] = 0;
  }
  std::int64_t Read(Decoder& dec) {
    if (last_diff[last] == 0) {
      const std::uint32_t sym = dec.DecodeSymbol(zero_diff);
      if (sym == 0) {
        last_diff[last] = ic.Decompress(dec, 0, 0);
        last_time[last] = Add64(last_time[last], last_diff[last]);
        extreme[last] = 0;
      } else if (sym == 1) {
        ReadNewSequence(dec);
      } else {
        last = (last + sym - 1) & 3;
        return Read(dec);
      }
      return last_time[last];
    }
    const std::uint32_t sym = dec.DecodeSymbol(multi);
    const std::int32_t ld = last_diff[last];
    if (sym == 1) {
      last_time[last] = Add64(last_time[last], ic.Decompress(dec, ld, 1));
      extreme[last] = 0;
    } else if (sym < kGpsCodeFull) {
      std::int32_t diff;
      if (sym == 0) {
        diff = ic.Decompress(dec, 0, 7);
        CountExtreme(diff);
      } else if (sym < static_cast<std::uint32_t>(kGpsMulti)) {
        const auto m = static_cast<std::int32_t>(sym);
        diff = ic.Decompress(dec, Mul(m, ld), m < 10 ? 2 : 3);
      } else if (sym == static_cast<std::uint32_t>(kGpsMulti)) {
        diff = ic.Decompress(dec, Mul(kGpsMulti, ld), 4);
        CountExtreme(diff);
      } else {
        const std::int32_t m = kGpsMulti - static_cast<std::int32_t>(sym);
        if (m > kGpsMultiMinus) {
          diff = ic.Decompress(dec, Mul(m, ld), 5);
        } else {
          diff = ic.Decompress(dec, Mul(kGpsMultiMinus, ld), 6);
          CountExtreme(diff);
        }
      }
      last_time[last] = Add64(last_time[last], diff);
    } else if (sym == kGpsCodeFull) {
      ReadNewSequence(dec);
    } else {
      last = (last + sym - kGpsCodeFull) & 3;
      return Read(dec);
    }
    return last_time[last];
  }
};

// The models of the POINT14 layers (one scanner channel) and RGB14.
struct Models {
  explicit Models(const Point14& first) : last(first), changed_values(8, SymbolModel(128)), rgb_diff(6, SymbolModel(256)) {
    last_z.fill(first.z);
    last_intensity.fill(first.intensity);
    gps.last_time[0] = static_cast<std::int64_t>(first.gps_bits);
  }
  Point14 last;
  std::vector<SymbolModel> changed_values;
  SymbolModel scanner_channel{3}, return_number_gps_same{13};
  std::array<std::unique_ptr<SymbolModel>, 16> number_of_returns, return_number;
  IntegerCoder dx{32, 2}, dy{32, 22}, z{32, 20};
  std::array<StreamingMedian5, 12> median_dx, median_dy;
  std::array<std::int32_t, 8> last_z{};
  std::array<std::unique_ptr<SymbolModel>, 64> classification, flags, user_data;
  IntegerCoder intensity{16, 4};
  std::array<std::uint16_t, 8> last_intensity{};
  IntegerCoder scan_angle{16, 2}, point_source{16, 1};
  GpsTimeState gps;
  // RGB14
  std::array<std::uint16_t, 3> last_rgb{};
  SymbolModel byte_used{128};
  std::vector<SymbolModel> rgb_diff;

  static SymbolModel& Lazy(std::unique_ptr<SymbolModel>& m, std::uint32_t symbols) {
    if (!m) m = std::make_unique<SymbolModel>(symbols);
    return *m;
  }
  // Context of the last point's return: single (3), first (1), last (2), intermediate (0); +4 if its time changed.
  std::uint32_t LastReturnContext() const {
    return (last.r == 1 ? 1u : 0u) + (last.r >= last.n ? 2u : 0u) + (last.gps_time_change ? 4u : 0u);
  }
};

constexpr int kLayers = 10;  // nine of POINT14, one of RGB14
enum Layer { kXY, kZ, kClass, kFlags, kIntensity, kScanAngle, kUserData, kPointSource, kGpsTime, kRgb };

std::uint8_t Fold8(std::int32_t v) { return static_cast<std::uint8_t>(v & 0xFF); }
std::int32_t Clamp8(std::int32_t v) { return std::clamp(v, 0, 255); }

}  // namespace

// ---------------------------------------------------------------------------
// Encoding
// ---------------------------------------------------------------------------

namespace {

// The coders and models of one chunk being compressed.
struct EncoderState {
  explicit EncoderState(const Point14& first, const std::uint8_t* rgb) : models(first) {
    if (rgb) std::memcpy(models.last_rgb.data(), rgb, 6);
  }
  Models models;
  std::array<Encoder, kLayers> enc;
};

void EncodeReturnsAndXY(Models& m, Encoder& enc, const Point14& p, bool gps_change) {
  const Point14& l = m.last;
  const std::uint32_t changed = ((p.point_source != l.point_source) << 5) | (gps_change << 4) |
                                ((p.scan_angle != l.scan_angle) << 3) | ((p.n != l.n) << 2);
  std::uint32_t returns = 0;
  if (p.r != l.r) returns = p.r == ((l.r + 1) % 16) ? 1 : p.r == ((l.r + 15) % 16) ? 2 : 3;
  enc.EncodeSymbol(m.changed_values[m.LastReturnContext()], changed | returns);
  if (p.n != l.n) enc.EncodeSymbol(Models::Lazy(m.number_of_returns[l.n], 16), p.n);
  if (returns == 3) {
    if (gps_change) {
      enc.EncodeSymbol(Models::Lazy(m.return_number[l.r], 16), p.r);
    } else {
      const std::int32_t diff = static_cast<std::int32_t>(p.r) - static_cast<std::int32_t>(l.r);
      enc.EncodeSymbol(m.return_number_gps_same, static_cast<std::uint32_t>(diff > 1 ? diff - 2 : diff + 14));
    }
  }
  const std::uint32_t map = kReturnMap6[p.n][p.r], slot = (map << 1) | gps_change;
  const std::int32_t dx = static_cast<std::int32_t>(static_cast<std::uint32_t>(p.x) - static_cast<std::uint32_t>(l.x));
  m.dx.Compress(enc, m.median_dx[slot].Get(), dx, p.n == 1);
  m.median_dx[slot].Add(dx);
  const std::uint32_t kx = m.dx.k();
  const std::int32_t dy = static_cast<std::int32_t>(static_cast<std::uint32_t>(p.y) - static_cast<std::uint32_t>(l.y));
  m.dy.Compress(enc, m.median_dy[slot].Get(), dy, (p.n == 1) + (kx < 20 ? ZeroBit0(kx) : 20));
  m.median_dy[slot].Add(dy);
}

// RGB14: which bytes changed, then the low and high bytes of red as
// differences, green and blue predicted from red's change. Returns whether
// any byte changed.
bool EncodeRgb(Models& m, Encoder& e, const std::uint16_t* c) {
  const std::uint16_t* last = m.last_rgb.data();
  std::uint32_t sym = ((last[0] & 0xFF) != (c[0] & 0xFF)) | (((last[0] & 0xFF00) != (c[0] & 0xFF00)) << 1) |
                      (((last[1] & 0xFF) != (c[1] & 0xFF)) << 2) | (((last[1] & 0xFF00) != (c[1] & 0xFF00)) << 3) |
                      (((last[2] & 0xFF) != (c[2] & 0xFF)) << 4) | (((last[2] & 0xFF00) != (c[2] & 0xFF00)) << 5);
  const bool colour = (c[0] & 0xFF) != (c[1] & 0xFF) || (c[0] & 0xFF) != (c[2] & 0xFF) ||
                      (c[0] & 0xFF00) != (c[1] & 0xFF00) || (c[0] & 0xFF00) != (c[2] & 0xFF00);
  sym |= colour << 6;
  e.EncodeSymbol(m.byte_used, sym);
  std::int32_t diff_l = 0, diff_h = 0;
  if (sym & 1) {
    diff_l = (c[0] & 0xFF) - (last[0] & 0xFF);
    e.EncodeSymbol(m.rgb_diff[0], Fold8(diff_l));
  }
  if (sym & 2) {
    diff_h = (c[0] >> 8) - (last[0] >> 8);
    e.EncodeSymbol(m.rgb_diff[1], Fold8(diff_h));
  }
  if (sym & 64) {
    if (sym & 4) e.EncodeSymbol(m.rgb_diff[2], Fold8((c[1] & 0xFF) - Clamp8(diff_l + (last[1] & 0xFF))));
    if (sym & 16) {
      diff_l = (diff_l + (c[1] & 0xFF) - (last[1] & 0xFF)) / 2;
      e.EncodeSymbol(m.rgb_diff[4], Fold8((c[2] & 0xFF) - Clamp8(diff_l + (last[2] & 0xFF))));
    }
    if (sym & 8) e.EncodeSymbol(m.rgb_diff[3], Fold8((c[1] >> 8) - Clamp8(diff_h + (last[1] >> 8))));
    if (sym & 32) {
      diff_h = (diff_h + (c[1] >> 8) - (last[1] >> 8)) / 2;
      e.EncodeSymbol(m.rgb_diff[5], Fold8((c[2] >> 8) - Clamp8(diff_h + (last[2] >> 8))));
    }
  }
  return sym != 0;
}

}  // namespace

ChunkEncoder::ChunkEncoder(int point_format) : format_(point_format) {
  if (point_format != 6 && point_format != 7) {
    throw InvalidArgument("LAZ: point format " + std::to_string(point_format) + " (6 or 7 expected)");
  }
}
ChunkEncoder::~ChunkEncoder() = default;

void ChunkEncoder::Add(const std::uint8_t* record) {
  if (((record[15] >> 4) & 3) != 0) {
    throw InvalidArgument("LAZ: scanner channel " + std::to_string((record[15] >> 4) & 3) + " (0 expected)");
  }
  records_.insert(records_.end(), record, record + (format_ == 7 ? 36 : 30));
  ++points_;
}

ChunkEncoder ChunkEncoder::Release() {
  ChunkEncoder out(format_);
  out.records_.swap(records_);
  out.points_ = points_;
  points_ = 0;
  return out;
}

namespace {

// The layers whose field changes somewhere in the chunk: the others are
// left out, and not coded at all.
std::array<bool, kLayers> ChangedLayers(int format, const std::uint8_t* records, std::uint32_t n) {
  std::array<bool, kLayers> changed{};
  changed[kXY] = changed[kZ] = true;  // always written
  const std::size_t size = format == 7 ? 36 : 30;
  for (std::uint32_t i = 1; i < n; ++i) {
    const std::uint8_t* a = records + (i - 1) * size;
    const std::uint8_t* b = a + size;
    changed[kClass] = changed[kClass] || a[16] != b[16];
    changed[kFlags] = changed[kFlags] || (a[15] & 0xCF) != (b[15] & 0xCF);
    changed[kIntensity] = changed[kIntensity] || std::memcmp(a + 12, b + 12, 2) != 0;
    changed[kScanAngle] = changed[kScanAngle] || std::memcmp(a + 18, b + 18, 2) != 0;
    changed[kUserData] = changed[kUserData] || a[17] != b[17];
    changed[kPointSource] = changed[kPointSource] || std::memcmp(a + 20, b + 20, 2) != 0;
    changed[kGpsTime] = changed[kGpsTime] || std::memcmp(a + 22, b + 22, 8) != 0;
    changed[kRgb] = changed[kRgb] || (format == 7 && std::memcmp(a + 30, b + 30, 6) != 0);
  }
  return changed;
}

void EncodePoint(EncoderState& s, const std::uint8_t* record, bool rgb, const std::array<bool, kLayers>& on);

}  // namespace

std::vector<std::uint8_t> CompressChunk(int point_format, const std::uint8_t* records, std::uint32_t n) {
  std::vector<std::uint8_t> out;
  if (n == 0) return out;
  const std::size_t size = point_format == 7 ? 36 : 30;
  const int layers = point_format == 7 ? kLayers : kLayers - 1;
  const std::array<bool, kLayers> on = ChangedLayers(point_format, records, n);
  out.assign(records, records + size);  // the first point, raw
  EncoderState s(Unpack(records), point_format == 7 ? records + 30 : nullptr);
  for (std::uint32_t i = 1; i < n; ++i) EncodePoint(s, records + i * size, point_format == 7, on);
  std::array<std::uint32_t, kLayers> sizes{};
  for (int i = 0; i < layers; ++i) {
    if (!on[i]) continue;
    s.enc[i].Done();
    sizes[i] = static_cast<std::uint32_t>(s.enc[i].bytes().size());
  }
  auto put32 = [&](std::uint32_t v) {
    for (int b = 0; b < 4; ++b) out.push_back(static_cast<std::uint8_t>(v >> (8 * b)));
  };
  put32(n);
  for (int i = 0; i < layers; ++i) put32(sizes[i]);
  for (int i = 0; i < layers; ++i) out.insert(out.end(), s.enc[i].bytes().begin(), s.enc[i].bytes().end());
  return out;
}

namespace {

void EncodePoint(EncoderState& s, const std::uint8_t* record, bool rgb, const std::array<bool, kLayers>& on) {
  const Point14 p = Unpack(record);
  if (p.channel != 0) throw InvalidArgument("LAZ: scanner channel " + std::to_string(p.channel) + " (0 expected)");
  Models& m = s.models;
  const Point14& l = m.last;
  const bool gps_change = p.gps_bits != l.gps_bits;
  EncodeReturnsAndXY(m, s.enc[kXY], p, gps_change);
  // Z, predicted from the last point at the same return level.
  const std::uint32_t level = ReturnLevel8(p.n, p.r);
  const std::uint32_t kxy = (m.dx.k() + m.dy.k()) / 2;
  m.z.Compress(s.enc[kZ], m.last_z[level], p.z, (p.n == 1) + (kxy < 18 ? ZeroBit0(kxy) : 18));
  m.last_z[level] = p.z;
  const std::uint32_t cpr = (p.r == 1 ? 1u : 0u) + (p.r >= p.n ? 2u : 0u);
  if (on[kClass]) {
    s.enc[kClass].EncodeSymbol(Models::Lazy(m.classification[((l.classification & 0x1F) << 1) + (cpr == 3)], 256),
                               p.classification);
  }
  if (on[kFlags]) s.enc[kFlags].EncodeSymbol(Models::Lazy(m.flags[l.Flags()], 64), p.Flags());
  if (on[kIntensity]) {
    const std::uint32_t slot = (cpr << 1) | gps_change;
    m.intensity.Compress(s.enc[kIntensity], m.last_intensity[slot], p.intensity, cpr);
    m.last_intensity[slot] = p.intensity;
  }
  if (p.scan_angle != l.scan_angle) m.scan_angle.Compress(s.enc[kScanAngle], l.scan_angle, p.scan_angle, gps_change);
  if (on[kUserData]) s.enc[kUserData].EncodeSymbol(Models::Lazy(m.user_data[l.user_data / 4], 256), p.user_data);
  if (p.point_source != l.point_source) m.point_source.Compress(s.enc[kPointSource], l.point_source, p.point_source, 0);
  if (gps_change) m.gps.Write(s.enc[kGpsTime], static_cast<std::int64_t>(p.gps_bits));
  m.last = p;
  m.last.gps_time_change = gps_change;
  if (!rgb) return;
  std::uint16_t c[3];
  std::memcpy(c, record + 30, 6);
  if (on[kRgb]) EncodeRgb(m, s.enc[kRgb], c);
  std::memcpy(m.last_rgb.data(), c, 6);
}

}  // namespace

// ---------------------------------------------------------------------------
// Decoding
// ---------------------------------------------------------------------------

struct ChunkDecoder::State {
  State(const Point14& first, const std::uint8_t* rgb) : models(first) {
    if (rgb) std::memcpy(models.last_rgb.data(), rgb, 6);
  }
  Models models;
  std::vector<std::unique_ptr<Decoder>> dec;  // null: the layer is absent (unchanged)
};

ChunkDecoder::ChunkDecoder(int point_format, const std::uint8_t* data, std::size_t size, const char* path)
    : format_(point_format), path_(path) {
  const std::size_t record = point_format == 7 ? 36 : 30;
  const int layers = point_format == 7 ? kLayers : kLayers - 1;
  const std::size_t head = record + 4 + 4 * static_cast<std::size_t>(layers);
  if (size < head) throw ParseError(path, 0, "LAZ chunk of " + std::to_string(size) + " bytes: truncated");
  first_.assign(data, data + record);
  points_ = Load<std::uint32_t>(data + record);
  const Point14 p = Unpack(data);
  if (p.channel != 0) {
    throw ParseError(path, 0, "LAZ point with scanner channel " + std::to_string(p.channel) +
                                  ": this reader reads one channel (0)");
  }
  state_ = std::make_unique<State>(p, point_format == 7 ? data + 30 : nullptr);
  std::size_t offset = head;
  for (int i = 0; i < layers; ++i) {
    const std::uint32_t bytes = Load<std::uint32_t>(data + record + 4 + 4 * i);
    if (offset + bytes > size) {
      throw ParseError(path, 0, "LAZ chunk layer " + std::to_string(i) + " of " + std::to_string(bytes) +
                                    " bytes runs past the chunk's " + std::to_string(size));
    }
    state_->dec.push_back(bytes ? std::make_unique<Decoder>(data + offset, bytes) : nullptr);
    offset += bytes;
  }
  if (points_ > 1 && (!state_->dec[kXY] || !state_->dec[kZ])) {
    throw ParseError(path, 0, "LAZ chunk without its XY or Z layer");
  }
}
ChunkDecoder::~ChunkDecoder() = default;

namespace {

// Returns the mask of what changed (bit 5 point source, 4 GPS time, 3 scan angle).
std::uint32_t DecodeReturnsAndXY(Models& m, Decoder& dec, Point14* p) {
  const Point14& l = m.last;
  const std::uint32_t changed = dec.DecodeSymbol(m.changed_values[m.LastReturnContext()]);
  if (changed & (1 << 6)) return changed;  // another scanner channel: refused by the caller
  const std::uint32_t gps_change = (changed >> 4) & 1;
  p->n = (changed & 4) ? dec.DecodeSymbol(Models::Lazy(m.number_of_returns[l.n], 16)) : l.n;
  switch (changed & 3) {
    case 0: p->r = l.r; break;
    case 1: p->r = (l.r + 1) % 16; break;
    case 2: p->r = (l.r + 15) % 16; break;
    default:
      if (gps_change) {
        p->r = dec.DecodeSymbol(Models::Lazy(m.return_number[l.r], 16));
      } else {
        p->r = (l.r + dec.DecodeSymbol(m.return_number_gps_same) + 2) % 16;
      }
  }
  const std::uint32_t map = kReturnMap6[p->n][p->r], slot = (map << 1) | gps_change;
  const std::int32_t dx = m.dx.Decompress(dec, m.median_dx[slot].Get(), p->n == 1);
  p->x = static_cast<std::int32_t>(static_cast<std::uint32_t>(l.x) + static_cast<std::uint32_t>(dx));
  m.median_dx[slot].Add(dx);
  const std::uint32_t kx = m.dx.k();
  const std::int32_t dy = m.dy.Decompress(dec, m.median_dy[slot].Get(), (p->n == 1) + (kx < 20 ? ZeroBit0(kx) : 20));
  p->y = static_cast<std::int32_t>(static_cast<std::uint32_t>(l.y) + static_cast<std::uint32_t>(dy));
  m.median_dy[slot].Add(dy);
  return changed;
}

void DecodeRgb(Models& m, Decoder& dec, std::uint16_t* c) {
  const std::uint16_t* last = m.last_rgb.data();
  const std::uint32_t sym = dec.DecodeSymbol(m.byte_used);
  c[0] = (sym & 1) ? Fold8(dec.DecodeSymbol(m.rgb_diff[0]) + (last[0] & 0xFF)) : (last[0] & 0xFF);
  c[0] |= (sym & 2) ? Fold8(dec.DecodeSymbol(m.rgb_diff[1]) + (last[0] >> 8)) << 8 : (last[0] & 0xFF00);
  if (sym & 64) {
    std::int32_t diff = (c[0] & 0xFF) - (last[0] & 0xFF);
    c[1] = (sym & 4) ? Fold8(dec.DecodeSymbol(m.rgb_diff[2]) + Clamp8(diff + (last[1] & 0xFF))) : (last[1] & 0xFF);
    diff = (diff + (c[1] & 0xFF) - (last[1] & 0xFF)) / 2;
    c[2] = (sym & 16) ? Fold8(dec.DecodeSymbol(m.rgb_diff[4]) + Clamp8(diff + (last[2] & 0xFF))) : (last[2] & 0xFF);
    diff = (c[0] >> 8) - (last[0] >> 8);
    c[1] |= (sym & 8) ? Fold8(dec.DecodeSymbol(m.rgb_diff[3]) + Clamp8(diff + (last[1] >> 8))) << 8
                      : (last[1] & 0xFF00);
    diff = (diff + (c[1] >> 8) - (last[1] >> 8)) / 2;
    c[2] |= (sym & 32) ? Fold8(dec.DecodeSymbol(m.rgb_diff[5]) + Clamp8(diff + (last[2] >> 8))) << 8
                       : (last[2] & 0xFF00);
  } else {
    c[1] = c[2] = c[0];
  }
}

}  // namespace

void ChunkDecoder::Next(std::uint8_t* record) {
  if (read_ >= points_) throw ParseError(path_, 0, "LAZ chunk read past its " + std::to_string(points_) + " points");
  const std::size_t size = format_ == 7 ? 36 : 30;
  if (read_++ == 0) {
    std::memcpy(record, first_.data(), size);
    return;
  }
  State& s = *state_;
  Models& m = s.models;
  const Point14 l = m.last;
  Point14 p = l;
  const std::uint32_t changed = DecodeReturnsAndXY(m, *s.dec[kXY], &p);
  if (changed & (1 << 6)) {
    throw ParseError(path_, 0, "LAZ point changes scanner channel: this reader reads one channel (0)");
  }
  const bool source_change = changed & (1 << 5), gps_change = changed & (1 << 4), angle_change = changed & (1 << 3);
  const std::uint32_t level = ReturnLevel8(p.n, p.r);
  const std::uint32_t kxy = (m.dx.k() + m.dy.k()) / 2;
  p.z = m.z.Decompress(*s.dec[kZ], m.last_z[level], (p.n == 1) + (kxy < 18 ? ZeroBit0(kxy) : 18));
  m.last_z[level] = p.z;
  const std::uint32_t cpr = (p.r == 1 ? 1u : 0u) + (p.r >= p.n ? 2u : 0u);
  if (s.dec[kClass]) {
    p.classification = s.dec[kClass]->DecodeSymbol(
        Models::Lazy(m.classification[((l.classification & 0x1F) << 1) + (cpr == 3)], 256));
  }
  if (s.dec[kFlags]) {
    const std::uint32_t f = s.dec[kFlags]->DecodeSymbol(Models::Lazy(m.flags[l.Flags()], 64));
    p.edge = (f >> 5) & 1;
    p.scan_direction = (f >> 4) & 1;
    p.class_flags = f & 0xF;
  }
  const std::uint32_t islot = (cpr << 1) | gps_change;
  if (s.dec[kIntensity]) {
    p.intensity = static_cast<std::uint16_t>(m.intensity.Decompress(*s.dec[kIntensity], m.last_intensity[islot], cpr));
    m.last_intensity[islot] = p.intensity;
  }
  if (angle_change && s.dec[kScanAngle]) {
    p.scan_angle = static_cast<std::int16_t>(
        static_cast<std::uint16_t>(m.scan_angle.Decompress(*s.dec[kScanAngle], l.scan_angle, gps_change)));
  }
  if (s.dec[kUserData]) p.user_data = s.dec[kUserData]->DecodeSymbol(Models::Lazy(m.user_data[l.user_data / 4], 256));
  if (source_change && s.dec[kPointSource]) {
    p.point_source = static_cast<std::uint16_t>(m.point_source.Decompress(*s.dec[kPointSource], l.point_source, 0));
  }
  if (gps_change && s.dec[kGpsTime]) p.gps_bits = static_cast<std::uint64_t>(m.gps.Read(*s.dec[kGpsTime]));
  p.gps_time_change = gps_change;
  m.last = p;
  Pack(p, record);
  if (format_ == 7) {
    std::uint16_t c[3];
    if (s.dec[kRgb]) {
      DecodeRgb(m, *s.dec[kRgb], c);
    } else {
      std::memcpy(c, m.last_rgb.data(), 6);
    }
    std::memcpy(m.last_rgb.data(), c, 6);
    std::memcpy(record + 30, c, 6);
  }
  for (const auto& d : s.dec) {
    if (d && d->overrun()) throw ParseError(path_, 0, "LAZ chunk layer ends early (a truncated or damaged file)");
  }
}

// ---------------------------------------------------------------------------
// The LASzip VLR and the chunk table
// ---------------------------------------------------------------------------

std::vector<std::uint8_t> LaszipVlrPayload(int point_format, std::uint32_t chunk_size) {
  std::vector<std::uint8_t> out;
  auto put = [&](auto v) {
    for (std::size_t b = 0; b < sizeof(v); ++b) out.push_back(static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> (8 * b)));
  };
  put(std::uint16_t{3});   // compressor: layered chunked
  put(std::uint16_t{0});   // coder: arithmetic
  put(std::uint8_t{3});    // LASzip version 3.4 r3, the first to write these items
  put(std::uint8_t{4});
  put(std::uint16_t{3});
  put(std::uint32_t{0});   // options
  put(chunk_size);
  put(std::int64_t{-1});   // number of special EVLRs: none
  put(std::int64_t{-1});   // their offset
  const bool rgb = point_format == 7;
  put(static_cast<std::uint16_t>(rgb ? 2 : 1));
  put(std::uint16_t{10});  // POINT14
  put(std::uint16_t{30});
  put(std::uint16_t{3});
  if (rgb) {
    put(std::uint16_t{11});  // RGB14
    put(std::uint16_t{6});
    put(std::uint16_t{3});
  }
  return out;
}

LaszipVlr ParseLaszipVlr(const std::uint8_t* d, std::size_t size, const char* path) {
  if (size < 34) throw ParseError(path, 0, "LASzip VLR of " + std::to_string(size) + " bytes (34 or more expected)");
  LaszipVlr v;
  v.compressor = Load<std::uint16_t>(d);
  v.chunk_size = Load<std::uint32_t>(d + 12);
  const std::uint16_t items = Load<std::uint16_t>(d + 32);
  if (v.compressor != 3) {
    throw ParseError(path, 0, "LAZ compressor " + std::to_string(v.compressor) +
                                  ": this reader reads LAS 1.4 layered compression (3), as LASzip 3 writes it");
  }
  if (size < 34 + 6u * items) throw ParseError(path, 0, "LASzip VLR shorter than its " + std::to_string(items) + " items");
  bool point = false, rgb = false;
  for (std::uint16_t i = 0; i < items; ++i) {
    const std::uint16_t type = Load<std::uint16_t>(d + 34 + 6 * i), version = Load<std::uint16_t>(d + 38 + 6 * i);
    if (type == 10 && version == 3) point = true;
    else if (type == 11 && version == 3) rgb = true;
    else throw ParseError(path, 0, "LAZ item type " + std::to_string(type) + " version " + std::to_string(version) +
                                       ": this reader reads POINT14 and RGB14 (version 3)");
  }
  if (!point) throw ParseError(path, 0, "LAZ without a POINT14 item");
  v.point_format = rgb ? 7 : 6;
  return v;
}

std::vector<std::uint8_t> EncodeChunkTable(const std::vector<Chunk>& chunks, bool variable_size) {
  std::vector<std::uint8_t> out(8, 0);
  const auto n = static_cast<std::uint32_t>(chunks.size());
  std::memcpy(out.data() + 4, &n, 4);  // version 0, then the count
  if (chunks.empty()) return out;
  Encoder enc;
  IntegerCoder ic(32, 2);
  for (std::size_t i = 0; i < chunks.size(); ++i) {
    if (variable_size) {
      ic.Compress(enc, i ? static_cast<std::int32_t>(chunks[i - 1].points) : 0, static_cast<std::int32_t>(chunks[i].points), 0);
    }
    ic.Compress(enc, i ? static_cast<std::int32_t>(chunks[i - 1].bytes) : 0, static_cast<std::int32_t>(chunks[i].bytes), 1);
  }
  enc.Done();
  out.insert(out.end(), enc.bytes().begin(), enc.bytes().end());
  return out;
}

std::vector<Chunk> DecodeChunkTable(const std::uint8_t* data, std::size_t size, std::uint32_t fixed_size,
                                    std::uint64_t total_points, const char* path) {
  if (size < 8) throw ParseError(path, 0, "LAZ chunk table missing or truncated");
  const std::uint32_t version = Load<std::uint32_t>(data), n = Load<std::uint32_t>(data + 4);
  if (version != 0) throw ParseError(path, 0, "LAZ chunk table version " + std::to_string(version) + " (0 expected)");
  if (n > size * 8 + 1) throw ParseError(path, 0, "LAZ chunk table of " + std::to_string(n) + " chunks in " + std::to_string(size) + " bytes");
  std::vector<Chunk> chunks(n);
  if (n == 0) return chunks;
  Decoder dec(data + 8, size - 8);
  IntegerCoder ic(32, 2);
  const bool variable = fixed_size == kVariableChunkSize;
  std::uint64_t left = total_points;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (variable) {
      chunks[i].points = static_cast<std::uint32_t>(ic.Decompress(dec, i ? static_cast<std::int32_t>(chunks[i - 1].points) : 0, 0));
    } else {
      chunks[i].points = static_cast<std::uint32_t>(std::min<std::uint64_t>(left, fixed_size));
      left -= chunks[i].points;
    }
    chunks[i].bytes = static_cast<std::uint32_t>(ic.Decompress(dec, i ? static_cast<std::int32_t>(chunks[i - 1].bytes) : 0, 1));
  }
  if (dec.overrun()) throw ParseError(path, 0, "LAZ chunk table truncated");
  return chunks;
}

}  // namespace aerotri::laz
