// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/base/memory.h"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

namespace aerotri {
namespace {

// A "Name:   1234 kB" line of /proc/self/status, in MiB; negative when absent.
double StatusFieldMb(const char* name) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(name) + ":";
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    std::istringstream fields(line.substr(key.size()));
    double kb = -1.0;
    fields >> kb;
    return kb >= 0.0 ? kb / 1024.0 : -1.0;
  }
  return -1.0;
}

std::atomic<double> peak_before_reset{0.0};  // the largest mark a reset discarded

std::mutex spans_mutex;
// Never destroyed: a span held by a static (the pipeline's stage span) is
// destroyed at exit after any function-local static made later, and must
// still find the list.
std::vector<PeakRssSpan*>& OpenSpans() {
  static auto* spans = new std::vector<PeakRssSpan*>();
  return *spans;
}

double RusageMaxRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux reports kB
}

}  // namespace

double CurrentRssMb() {
  const double mb = StatusFieldMb("VmRSS");
  return mb >= 0.0 ? mb : 0.0;
}

double PeakRssMb() {
  const double mb = StatusFieldMb("VmHWM");
  return mb >= 0.0 ? mb : RusageMaxRssMb();
}

double ProcessPeakRssMb() { return std::max({peak_before_reset.load(), PeakRssMb(), RusageMaxRssMb()}); }

bool ResetPeakRss() {
  const double before = PeakRssMb();
  double seen = peak_before_reset.load();
  while (before > seen && !peak_before_reset.compare_exchange_weak(seen, before)) {
  }
  {
    std::lock_guard<std::mutex> lock(spans_mutex);
    for (PeakRssSpan* span : OpenSpans()) span->discarded_mb_ = std::max(span->discarded_mb_, before);
  }
  std::ofstream out("/proc/self/clear_refs");
  if (!out) return false;
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

PeakRssSpan::PeakRssSpan() {
  own_ = ResetPeakRss();
  std::lock_guard<std::mutex> lock(spans_mutex);
  OpenSpans().push_back(this);
}

PeakRssSpan::~PeakRssSpan() {
  std::lock_guard<std::mutex> lock(spans_mutex);
  auto& spans = OpenSpans();
  spans.erase(std::remove(spans.begin(), spans.end(), this), spans.end());
}

double PeakRssSpan::PeakMb() const {
  std::lock_guard<std::mutex> lock(spans_mutex);
  return std::max(discarded_mb_, PeakRssMb());
}

void ReleaseFreedMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace aerotri
