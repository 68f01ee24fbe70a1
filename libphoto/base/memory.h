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
// Hands the heap's free pages back to the kernel (glibc malloc_trim; a
// no-op elsewhere): after a large structure built of many mid-sized blocks
// is freed, so that the next one does not stack on top of it.
void ReleaseFreedMemory();

}  // namespace aerotri
