// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// LAS 1.4 point records of format 7 with every field in use, as a lidar
// survey's would be (returns of pulses sharing a GPS time, GPS time in
// interleaved sequences with jumps, scan angles, point sources changing by
// flight line, intensities, flags, user data, colour and grey), for the LAZ
// tests: what aerotri's own clouds leave constant must still be coded right.

#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

namespace aerotri::test {

inline std::vector<std::uint8_t> LidarLikeRecords(std::uint32_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  std::vector<std::uint8_t> out(std::size_t{n} * 36, 0);
  std::int32_t x = 100000, y = -50000, z = 2000;
  double t = 381234.5;
  std::uint16_t source = 7, intensity = 900;
  int returns = 1, r = 1;
  std::uint16_t rgb[3] = {30000, 31000, 29000};
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint8_t* b = out.data() + std::size_t{i} * 36;
    if (r > returns) {  // a new pulse
      returns = uniform(0, 9) < 7 ? 1 : uniform(1, 15);
      r = 1;
      t += uniform(0, 50) == 0 ? 1e4 * uniform(1, 100) : 1e-5 * uniform(1, 3);  // jumps and steps
    }
    if (uniform(0, 20000) == 0) source = static_cast<std::uint16_t>(uniform(0, 65535));
    x += uniform(-300, 300);
    y += uniform(-200, 250);
    z += uniform(-40, 40) + (uniform(0, 1000) == 0 ? 1000000 : 0);
    intensity = static_cast<std::uint16_t>(intensity + uniform(-80, 80));
    std::memcpy(b, &x, 4);
    std::memcpy(b + 4, &y, 4);
    std::memcpy(b + 8, &z, 4);
    std::memcpy(b + 12, &intensity, 2);
    // Now and then a record as some files have them: return 0, or beyond its count.
    const int rr = uniform(0, 500) == 0 ? uniform(0, 15) : r;
    b[14] = static_cast<std::uint8_t>(rr | (returns << 4));
    b[15] = static_cast<std::uint8_t>(uniform(0, 30) == 0 ? uniform(0, 15) : 0) |
            static_cast<std::uint8_t>((i / 5000 % 2) << 6) | static_cast<std::uint8_t>((uniform(0, 100) == 0) << 7);
    b[16] = static_cast<std::uint8_t>(uniform(0, 3) == 0 ? uniform(0, 255) : (r == returns ? 2 : 1));
    b[17] = static_cast<std::uint8_t>(uniform(0, 10) == 0 ? uniform(0, 255) : 0);
    const auto angle = static_cast<std::int16_t>(uniform(-30000, 30000) / (uniform(0, 3) == 0 ? 1 : 1000) * 1);
    std::memcpy(b + 18, &angle, 2);
    std::memcpy(b + 20, &source, 2);
    const double gps = uniform(0, 200) == 0 ? -t : t;  // a second, interleaved sequence
    std::memcpy(b + 22, &gps, 8);
    if (uniform(0, 3) == 0) {
      for (std::uint16_t& c : rgb) c = static_cast<std::uint16_t>(c + uniform(-2000, 2000));
    }
    if (uniform(0, 10) == 0) rgb[1] = rgb[2] = rgb[0];  // grey
    std::memcpy(b + 30, rgb, 6);
    ++r;
  }
  return out;
}

}  // namespace aerotri::test
