// SPDX-License-Identifier: BSD-3-Clause
// The memory figures every stage records: a stage's peak is its own, not the
// process's peak so far.
#include "libphoto/base/memory.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <vector>

namespace aerotri {
namespace {

constexpr std::size_t kBlockMb = 256;

// Touches every page of a block the size of kBlockMb, then frees it (glibc
// returns a block this large to the kernel at once: it is mmapped).
void TouchAndFree() {
  std::vector<char> block(kBlockMb << 20);
  std::memset(block.data(), 1, block.size());
  volatile char sink = block[block.size() / 2];
  (void)sink;
}

TEST(Memory, AStagesPeakIsItsOwnOnceTheMarkIsRestarted) {
  const double before = CurrentRssMb();
  ASSERT_GT(before, 0.0) << "no /proc/self/status";
  TouchAndFree();
  // The block was resident: the process's peak and the mark both hold it.
  EXPECT_GE(ProcessPeakRssMb(), before + 0.9 * kBlockMb);
  EXPECT_GE(PeakRssMb(), before + 0.9 * kBlockMb);
  if (!ResetPeakRss()) GTEST_SKIP() << "the kernel would not restart the high-water mark here";
  // Restarted: the freed block is not in the mark, the process peak keeps it.
  EXPECT_LT(PeakRssMb(), before + 0.25 * kBlockMb);
  EXPECT_GE(ProcessPeakRssMb(), before + 0.9 * kBlockMb);
  // A second stage that uses the block again has it in its own peak.
  TouchAndFree();
  EXPECT_GE(PeakRssMb(), before + 0.9 * kBlockMb);
  EXPECT_LT(PeakRssMb(), before + 1.25 * kBlockMb);
}

// A stage that times its phases: each phase's peak is its own, and the
// stage's holds the largest of them though every phase restarted the mark.
TEST(Memory, AStagesPeakHoldsItsPhasesPeaks) {
  const double before = CurrentRssMb();
  ASSERT_GT(before, 0.0) << "no /proc/self/status";
  const PeakRssSpan stage;
  if (!stage.Own()) GTEST_SKIP() << "the kernel would not restart the high-water mark here";
  double big = 0.0, small = 0.0;
  {
    const PeakRssSpan phase;
    TouchAndFree();
    big = phase.PeakMb();
  }
  {
    const PeakRssSpan phase;
    std::vector<char> little(16 << 20);
    std::memset(little.data(), 1, little.size());
    small = phase.PeakMb();
  }
  EXPECT_GE(big, before + 0.9 * kBlockMb);
  EXPECT_LT(small, before + 0.25 * kBlockMb);
  EXPECT_GE(small, before + 15.0);
  // The second phase restarted the mark below the first's block: the stage
  // still has it.
  EXPECT_LT(PeakRssMb(), before + 0.25 * kBlockMb);
  EXPECT_GE(stage.PeakMb(), before + 0.9 * kBlockMb);
  EXPECT_LT(stage.PeakMb(), before + 1.25 * kBlockMb);
}

}  // namespace
}  // namespace aerotri
