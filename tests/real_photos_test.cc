// SPDX-License-Identifier: BSD-3-Clause
// The photo pipeline on the shared real photo sets (../shared/data; each
// test skips when its set is absent): every photo registered at sub-pixel
// RMS, a georeferenced survey in the expected UTM zone, and the deliverables
// the geometry allows. Figures and timings: bench/photo_bench.sh.
#include <gtest/gtest.h>

#include <cstdio>

#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "libphoto/base/atomic_file.h"
#include "libphoto/pipeline/pipeline.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;

nlohmann::json RunOn(const fs::path& images, const fs::path& workspace) {
  PipelineOptions o;
  o.images_dir = images;
  o.workspace = workspace;
  o.log = [](const std::string&) {};  // quiet: no progress or notes
  RunPipeline(o);
  return nlohmann::json::parse(ReadTextFile(workspace / "report.json"));
}

std::map<std::string, nlohmann::json> PerImage(const nlohmann::json& report) {
  std::map<std::string, nlohmann::json> out;
  for (const auto& im : report["images"]["per_image"]) out[im["name"]] = im;
  return out;
}

// A real survey that works is never reported failed; its status and the
// codes of its warnings are printed for the record.
void ExpectNotFailed(const nlohmann::json& r) {
  const std::string status = r.value("status", std::string("missing"));
  EXPECT_TRUE(status == "ok" || status == "warnings") << status << " " << r.value("errors", nlohmann::json()).dump(1);
  std::string codes;
  for (const auto& w : r.value("warnings", nlohmann::json::array())) codes += " " + w.value("code", std::string());
  std::printf("status %s; warnings:%s\n", status.c_str(), codes.c_str());
}

TEST(RealPhotos, BeachDroneSetRegistersEveryPhotoAndGivesADsm) {
  const fs::path set = testing::SharedData("drone_brighton_beach/images");
  if (set.empty()) GTEST_SKIP() << "../shared/data/drone_brighton_beach is absent";
  testing::TempDir dir;
  const nlohmann::json r = RunOn(set, dir.path());
  EXPECT_EQ(r["images"]["total"], 18);
  EXPECT_EQ(r["images"]["registered"], 18);
  EXPECT_LT(r["adjustment"]["final_rms_px"].get<double>(), 1.0);
  EXPECT_EQ(r["crs"], "EPSG:32615");  // UTM 15N (Lake Superior shore at 46.8 N), from the photos' GPS
  ExpectNotFailed(r);
  // Rectified stereo over the whole beach: millions of points, a DSM.
  ASSERT_TRUE(r.contains("dense")) << r.dump(1);
  EXPECT_GT(r["dense"]["points"].get<long long>(), 1000000);
  EXPECT_TRUE(fs::exists(dir.path() / "dsm.tif"));
  EXPECT_TRUE(fs::exists(dir.path() / "cloud.laz"));
  // The DSM against the ground the photos cover: 95.3 % measured (83.2 %
  // while rectified frames cut the strips' rims, flown here at 45 deg yaw);
  // what is left is water and the forest's edge.
  const double coverage = r["dsm"]["footprint_coverage"]["fraction"];
  std::printf("DSM coverage of the ground seen by 2 or more photos: %.1f %%\n", 100.0 * coverage);
  EXPECT_GT(coverage, 0.90);
  // A nadir flight, level: the adjusted cameras look down.
  EXPECT_TRUE(r["adjustment"]["attitude"]["nadir_block"].get<bool>());
  EXPECT_LT(r["adjustment"]["attitude"]["mean_axis_tilt_deg"].get<double>(), 5.0);
}

TEST(RealPhotos, GroundLevelSetRegistersEveryPhotoAndSaysWhyThereIsNoDsm) {
  const fs::path set = testing::SharedData("groundlevel_lund/images");
  if (set.empty()) GTEST_SKIP() << "../shared/data/groundlevel_lund is absent";
  testing::TempDir dir;
  const nlohmann::json r = RunOn(set, dir.path());
  EXPECT_EQ(r["images"]["total"], 29);
  EXPECT_EQ(r["images"]["registered"], 29);
  EXPECT_LT(r["adjustment"]["final_rms_px"].get<double>(), 1.0);
  ExpectNotFailed(r);
  // Walking forward along a street: no pair is side by side, so there is no
  // dense cloud, and the report says so instead of the run failing.
  ASSERT_TRUE(r.contains("dense")) << r.dump(1);
  EXPECT_EQ(r["dense"]["points"], 0);
  EXPECT_NE(r["dense"]["skipped"].get<std::string>().find("side by side"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir.path() / "dsm.tif"));
  EXPECT_TRUE(fs::exists(dir.path() / "report.html"));
}

TEST(RealPhotos, FixedWingSetRegistersAllButTheBareFieldAtAStripEnd) {
  const fs::path set = testing::SharedData("fixedwing_seneca/images");
  if (set.empty()) GTEST_SKIP() << "../shared/data/fixedwing_seneca is absent";
  testing::TempDir dir;
  const nlohmann::json r = RunOn(set, dir.path());
  EXPECT_EQ(r["images"]["total"], 40);
  EXPECT_GE(r["images"]["registered"].get<int>(), 39);
  EXPECT_LT(r["adjustment"]["final_rms_px"].get<double>(), 1.0);
  EXPECT_EQ(r["crs"], "EPSG:32617");  // Ohio
  ExpectNotFailed(r);
  // IMG_0482 (bare soil and crop rows, see bench/README.md) shares no
  // verifiable tie points; when it stays out, the report says why.
  auto per_image = PerImage(r);
  for (const auto& [name, im] : per_image) {
    if (!im["registered"].get<bool>()) {
      EXPECT_EQ(name, "IMG_0482.jpg");
      EXPECT_FALSE(im["why_not"].get<std::string>().empty());
    }
  }
  EXPECT_GT(r["dense"]["points"].get<long long>(), 1000000);
  // 92.9 % of the ground seen by 2 or more photos measured (71.2 % before
  // whole rectified frames, wide pairs for the sparse return strips and
  // SGBM's search started at the pair's disparities).
  const double coverage = r["dsm"]["footprint_coverage"]["fraction"];
  std::printf("DSM coverage of the ground seen by 2 or more photos: %.1f %%\n", 100.0 * coverage);
  EXPECT_GT(coverage, 0.90);
  EXPECT_TRUE(r["adjustment"]["attitude"]["nadir_block"].get<bool>());
  EXPECT_LT(r["adjustment"]["attitude"]["mean_axis_tilt_deg"].get<double>(), 5.0);
}

}  // namespace
}  // namespace aerotri
