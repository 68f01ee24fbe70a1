// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Heights grouped by raster cell, for a per-cell median or percentile over a
// whole cloud: two passes over the points (count, then place) into one array,
// 4 bytes per cell and per point. A vector per cell costs 24 bytes per cell
// and a heap block per cell with data, which on a 1,000-photo survey's DSM
// grid (tens of millions of cells) was a gigabyte before any height.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "libphoto/base/error.h"

namespace aerotri {

class CellHeights {
 public:
  explicit CellHeights(std::size_t cells) : start_(cells + 1, 0) {}

  // Pass 1: one call per height the cell will hold.
  void Count(std::size_t cell) { ++start_[cell + 1]; }
  // Between the passes.
  void Allocate() {
    std::uint64_t total = 0;
    for (std::size_t c = 1; c < start_.size(); ++c) {
      total += start_[c];
      if (total > std::numeric_limits<std::uint32_t>::max()) {
        throw InvalidArgument("more than 4,294,967,295 points in one raster: tile the cloud");
      }
      start_[c] = static_cast<std::uint32_t>(total);
    }
    next_.assign(start_.begin(), start_.end() - 1);
    values_.resize(total);
  }
  // Pass 2: the heights, in any order, exactly as counted.
  void Add(std::size_t cell, float z) { values_[next_[cell]++] = z; }
  // After pass 2: the cell's heights, reorderable (for nth_element).
  float* begin(std::size_t cell) { return values_.data() + start_[cell]; }
  float* end(std::size_t cell) { return values_.data() + start_[cell + 1]; }
  bool empty(std::size_t cell) const { return start_[cell] == start_[cell + 1]; }
  std::size_t size(std::size_t cell) const { return start_[cell + 1] - start_[cell]; }

 private:
  std::vector<std::uint32_t> start_;
  std::vector<std::uint32_t> next_;
  std::vector<float> values_;
};

}  // namespace aerotri
