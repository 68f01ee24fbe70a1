// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The project's one work-sharing loop.
//
// ParallelFor runs body(k) for every k in [0, n) on `threads` threads, the
// calling thread included, handing indices out in increasing order. An
// exception thrown by body (an aerotri::Error, a cv::Exception, std::bad_alloc)
// stops the hand-out; once every thread has finished its current index, the
// first exception is rethrown in the caller. A failure in a worker thus
// reaches the command line as an error message and exit code 1, never as
// std::terminate.

#include <cstddef>
#include <functional>

namespace aerotri {

// Threads to use: `requested` when positive, else every core (at least 1).
unsigned ThreadCount(int requested);

void ParallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& body);

// As ParallelFor, and then in_order(k) for every k in increasing order, one
// at a time, each as soon as work(0..k) are done: parallel work feeding one
// sequential writer (a file written tile by tile, the same every run). No
// work(k) starts while in_order has not yet reached k - window + 1, so at
// most `window` results wait in the caller's hands. Exceptions from either
// function stop the loop and are rethrown in the caller, as ParallelFor's.
void ParallelForInOrder(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& work,
                        const std::function<void(std::size_t)>& in_order, std::size_t window);

}  // namespace aerotri
