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

}  // namespace aerotri
