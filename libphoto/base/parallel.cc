// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace aerotri {

unsigned ThreadCount(int requested) {
  if (requested > 0) return static_cast<unsigned>(requested);
  return std::max(1u, std::thread::hardware_concurrency());
}

namespace {

// worker() on min(threads, n) threads, the calling thread one of them; returns
// once all have finished.
void RunWorkers(unsigned threads, std::size_t n, const std::function<void()>& worker) {
  const unsigned count = static_cast<unsigned>(std::min<std::size_t>(std::max(1u, threads), std::max<std::size_t>(n, 1)));
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < count; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
}

}  // namespace

void ParallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& body) {
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr first;
  std::mutex mutex;
  auto worker = [&] {
    for (std::size_t k = next++; k < n && !failed; k = next++) {
      try {
        body(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!first) first = std::current_exception();
        failed = true;
      }
    }
  };
  RunWorkers(threads, n, worker);
  if (first) std::rethrow_exception(first);
}

void ParallelForInOrder(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& work,
                        const std::function<void(std::size_t)>& in_order, std::size_t window) {
  window = std::max<std::size_t>(1, window);
  std::mutex mutex;
  std::condition_variable changed;
  std::size_t next_work = 0, next_emit = 0;
  std::vector<char> done(n, 0);
  bool failed = false, emitting = false;
  std::exception_ptr first;
  auto fail = [&] {  // with the mutex held
    if (!first) first = std::current_exception();
    failed = true;
    changed.notify_all();
  };
  auto worker = [&] {
    for (;;) {
      std::size_t k = 0;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return failed || next_work >= n || next_work < next_emit + window; });
        if (failed || next_work >= n) return;
        k = next_work++;
      }
      try {
        work(k);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        fail();
        return;
      }
      std::unique_lock<std::mutex> lock(mutex);
      done[k] = 1;
      if (emitting) continue;  // the thread emitting will reach k
      emitting = true;
      while (!failed && next_emit < n && done[next_emit]) {
        const std::size_t e = next_emit;
        lock.unlock();
        try {
          in_order(e);
        } catch (...) {
          lock.lock();
          emitting = false;
          fail();
          return;
        }
        lock.lock();
        ++next_emit;
        changed.notify_all();
      }
      emitting = false;
    }
  };
  RunWorkers(threads, n, worker);
  if (first) std::rethrow_exception(first);
}

}  // namespace aerotri
