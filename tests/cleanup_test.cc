// SPDX-License-Identifier: BSD-3-Clause
// The depth maps go once fused (unless kept); everything a resume or a rerun
// needs stays.
#include <gtest/gtest.h>

#include <fstream>

#include "libphoto/pipeline/pipeline.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

TEST(Cleanup, RemovesTheDepthMapsAndNothingElseUnlessKept) {
  testing::TempDir dir;
  PipelineOptions o;
  o.workspace = dir.path();
  std::string log;
  o.log = [&](const std::string& line) { log += line + "\n"; };
  std::filesystem::create_directories(dir / "depth");
  std::ofstream(dir / "depth" / "IMG_0001.JPG+IMG_0002.JPG.pts") << std::string(3 << 20, 'x');
  std::filesystem::create_directories(dir / "features");
  const std::vector<std::string> kept = {"features/IMG_0001.JPG.sift", "matches.bin", "report.json", "report.html",
                                         "cloud.laz", "dsm.tif", "dense.json"};
  for (const auto& f : kept) std::ofstream(dir / f) << "data";
  // Asked to keep them: kept, silently.
  o.keep_depth_maps = true;
  RemoveDepthMaps(o);
  EXPECT_TRUE(std::filesystem::exists(dir / "depth" / "IMG_0001.JPG+IMG_0002.JPG.pts"));
  EXPECT_TRUE(log.empty()) << log;
  o.keep_depth_maps = false;
  RemoveDepthMaps(o);
  EXPECT_FALSE(std::filesystem::exists(dir / "depth"));
  for (const auto& f : kept) EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  EXPECT_NE(log.find("depth maps, 3 MB"), std::string::npos) << log;
  // Nothing to remove: silent.
  log.clear();
  RemoveDepthMaps(o);
  EXPECT_TRUE(log.empty()) << log;
}

}  // namespace
}  // namespace aerotri
