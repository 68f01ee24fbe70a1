// SPDX-License-Identifier: BSD-3-Clause
// Progress lines: elapsed time and an ETA extrapolated from the fraction
// done; one line per update in a pipe, rewritten in place on a terminal.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>

#include <cpl_error.h>

#include <thread>
#include <vector>

#include "tools/commands.h"
#include "tools/tool_context.h"

namespace aerotri {
namespace {

TEST(Progress, DurationsReadAsAClock) {
  EXPECT_EQ(FormatDuration(0.2), "0 s");
  EXPECT_EQ(FormatDuration(42.4), "42 s");
  EXPECT_EQ(FormatDuration(187.0), "3:07");
  EXPECT_EQ(FormatDuration(3723.0), "1:02:03");
  EXPECT_EQ(FormatDuration(-5.0), "0 s");
}

TEST(Progress, EtaExtrapolatesTheElapsedTime) {
  // A quarter done in 30 s: 90 s to go.
  EXPECT_EQ(FormatProgressLine("match", 0.25, "pair 10 of 40", 30.0),
            "match:  25% pair 10 of 40 [elapsed 30 s, ETA 1:30]");
  // Too early to say, finished, or no fraction known: no ETA.
  EXPECT_EQ(FormatProgressLine("match", 0.01, "pair 1", 3.0), "match:   1% pair 1 [elapsed 3 s]");
  EXPECT_EQ(FormatProgressLine("match", 1.0, "done", 120.0), "match: 100% done [elapsed 2:00]");
  EXPECT_EQ(FormatProgressLine("dense", -1.0, "fusing", 5.0), "dense: fusing [elapsed 5 s]");
}

TEST(Progress, PipeGetsLinesTerminalGetsOneRewrittenLine) {
  std::ostringstream pipe;
  ToolContext ctx;
  ctx.err = &pipe;
  auto progress = ctx.Progress("features");
  progress(0.5, "image 1 of 2");
  progress(1.0, "image 2 of 2");
  const std::string lines = pipe.str();
  EXPECT_EQ(std::count(lines.begin(), lines.end(), '\n'), 2);
  EXPECT_EQ(lines.find('\r'), std::string::npos);

  std::ostringstream tty;
  ToolContext term;
  term.err = &tty;
  term.rewrite_progress = true;
  auto p = term.Progress("features");
  p(0.5, "image 1 of 2");
  term.Info("a message");  // ends the open progress line first
  p(1.0, "image 2 of 2");
  const std::string out = tty.str();
  EXPECT_NE(out.find("\r\033[Kfeatures:  50% image 1 of 2"), std::string::npos) << out;
  EXPECT_NE(out.find("ETA 0 s]\na message\n"), std::string::npos) << out;
  EXPECT_EQ(out.back(), '\n');

  ToolContext quiet;
  quiet.quiet = true;
  EXPECT_FALSE(quiet.Progress("features"));
}

TEST(GdalMessages, ComeOutAsTheToolsWarningsFromAnyThread) {
  std::ostringstream err;
  ToolContext ctx;
  ctx.err = &err;
  ctx.quiet = true;  // warnings are shown even so
  RouteGdalMessages(&ctx);
  CPLError(CE_Warning, CPLE_AppDefined, "the filename extension should be '%s'", "gpkg");
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) threads.emplace_back([t] { CPLError(CE_Failure, CPLE_FileIO, "thread %d failed", t); });
  for (auto& t : threads) t.join();
  CPLDebug("GDAL", "debug output stays out");
  RouteGdalMessages(nullptr);
  CPLErrorReset();
  const std::string text = err.str();
  EXPECT_NE(text.find("warning: GDAL: the filename extension should be 'gpkg'\n"), std::string::npos) << text;
  for (int t = 0; t < 4; ++t) {
    EXPECT_NE(text.find("warning: GDAL: thread " + std::to_string(t) + " failed\n"), std::string::npos) << text;
  }
  EXPECT_EQ(text.find("debug"), std::string::npos);
  EXPECT_EQ(text.find("Warning 1"), std::string::npos);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 5);  // whole lines, none interleaved
}

}  // namespace
}  // namespace aerotri
