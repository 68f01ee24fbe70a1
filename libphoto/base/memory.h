// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The process's memory, as the kernel counts it (Linux /proc; elsewhere the
// process-wide peak from getrusage).
//
// A pipeline run is one process through every stage, so the process's peak
// (ru_maxrss) only ever grows: the dense stage's peak would be reported as
// every later stage's too. ResetPeakRss() asks the kernel to restart the
// resident high-water mark (/proc/self/clear_refs, "5", Linux 4.0+), so that
// PeakRssMb() after it is the peak of the work since: one stage's own.
//
// The kernel's reset also restarts what getrusage (and so wait4, and
// /usr/bin/time) reports as the maximum resident set: after a reset those
// give the peak since it, not the process's. ProcessPeakRssMb() keeps the
// true figure by remembering the mark before each reset.

namespace aerotri {

// The resident set now (VmRSS), in MiB; 0 where unknown.
double CurrentRssMb();
// The resident high-water mark since the last successful ResetPeakRss()
// (VmHWM), or since the process started; the process's peak where /proc
// is unavailable.
double PeakRssMb();
// The process's peak since it started: the largest mark seen before any
// ResetPeakRss() and the mark since the last.
double ProcessPeakRssMb();
// Restarts the high-water mark at the current resident set. False where the
// kernel refuses (no /proc, a restricted container): PeakRssMb() then stays
// the process's peak, and callers should say so.
bool ResetPeakRss();
// The resident peak of one span of work that may hold spans of its own (a
// stage and its phases): each span starts with ResetPeakRss(), and every
// reset inside it hands the span the mark it discards, so PeakMb() is the
// span's own peak however many spans nested in it reset the mark since.
// Spans are opened and closed on one thread; they may nest, not overlap.
class PeakRssSpan {
 public:
  PeakRssSpan();
  ~PeakRssSpan();
  PeakRssSpan(const PeakRssSpan&) = delete;
  PeakRssSpan& operator=(const PeakRssSpan&) = delete;
  double PeakMb() const;
  // Whether the kernel restarted the mark at the span's start: false, and
  // PeakMb() is the process's peak.
  bool Own() const { return own_; }

 private:
  friend bool ResetPeakRss();
  bool own_ = false;
  double discarded_mb_ = 0.0;  // the largest mark a reset inside the span discarded
};
// Hands the heap's free pages back to the kernel (glibc malloc_trim; a
// no-op elsewhere): after a large structure built of many mid-sized blocks
// is freed, so that the next one does not stack on top of it.
void ReleaseFreedMemory();

}  // namespace aerotri
