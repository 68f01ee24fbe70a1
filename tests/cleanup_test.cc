// SPDX-License-Identifier: BSD-3-Clause
// run --cleanup: the depth maps go, everything a resume or a rerun needs stays.
#include <gtest/gtest.h>

#include <fstream>

#include "libphoto/pipeline/pipeline.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

TEST(Cleanup, RemovesTheDepthMapsAndNothingElse) {
  testing::TempDir dir;
  PipelineOptions o;
  o.workspace = dir.path();
  std::string log;
  o.log = [&](const std::string& line) { log += line + "\n"; };
  std::filesystem::create_directories(dir / "depth" / "pair_0001");
  std::ofstream(dir / "depth" / "pair_0001" / "depth.bin") << std::string(3 << 20, 'x');
  std::filesystem::create_directories(dir / "features");
  const std::vector<std::string> kept = {"features/IMG_0001.JPG.feat", "matches.bin", "report.json", "report.html",
                                         "cloud.las", "dsm.tif", "dense.json"};
  for (const auto& f : kept) std::ofstream(dir / f) << "data";
  CleanUpIntermediates(o);
  EXPECT_FALSE(std::filesystem::exists(dir / "depth"));
  for (const auto& f : kept) EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  EXPECT_NE(log.find("depth maps, 3 MB"), std::string::npos) << log;
  // Nothing to clean: silent.
  log.clear();
  CleanUpIntermediates(o);
  EXPECT_TRUE(log.empty()) << log;
}

}  // namespace
}  // namespace aerotri
