// SPDX-License-Identifier: BSD-3-Clause
// ParallelForInOrder: parallel work, then one sequential consumer in order.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "libphoto/base/parallel.h"

namespace aerotri {
namespace {

TEST(ParallelForInOrder, ConsumesEveryResultOnceInOrderWithABoundedBacklog) {
  const size_t n = 200, window = 3;
  std::vector<int> results(n, -1);
  std::vector<size_t> consumed;
  std::atomic<size_t> waiting{0};  // done, not yet consumed
  size_t most_waiting = 0;
  ParallelForInOrder(
      n, 4,
      [&](size_t k) {
        // Uneven work, so that later items finish before earlier ones.
        std::this_thread::sleep_for(std::chrono::microseconds((k * 7919) % 500));
        results[k] = static_cast<int>(k * k);
        ++waiting;
      },
      [&](size_t k) {
        most_waiting = std::max(most_waiting, waiting.load());
        --waiting;
        EXPECT_EQ(results[k], static_cast<int>(k * k));
        consumed.push_back(k);
      },
      window);
  ASSERT_EQ(consumed.size(), n);
  for (size_t k = 0; k < n; ++k) EXPECT_EQ(consumed[k], k);
  EXPECT_LE(most_waiting, window);
}

TEST(ParallelForInOrder, AnExceptionInEitherStepReachesTheCaller) {
  std::vector<size_t> consumed;
  EXPECT_THROW(ParallelForInOrder(
                   50, 2, [](size_t k) { if (k == 20) throw std::runtime_error("work"); },
                   [&](size_t k) { consumed.push_back(k); }, 4),
               std::runtime_error);
  for (size_t k = 0; k < consumed.size(); ++k) EXPECT_EQ(consumed[k], k);
  EXPECT_LT(consumed.size(), 20u + 1);
  EXPECT_THROW(ParallelForInOrder(
                   50, 2, [](size_t) {},
                   [](size_t k) { if (k == 10) throw std::runtime_error("consumer"); }, 4),
               std::runtime_error);
}

}  // namespace
}  // namespace aerotri
