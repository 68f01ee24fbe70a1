// SPDX-License-Identifier: BSD-3-Clause
// A survey split into 4 parts, each reconstructed on its own, merged and
// adjusted once, run end to end by Snakemake's local executor: every photo
// registered once, the seams invisible (check-point RMSE within 1.2x of the
// unsplit run's, no step between the parts' areas in the DSM above a GSD);
// the dense stage in shares (4 jobs of depth maps, 4 of fusion) gives the
// DSM the dense stage gives in one process; the orthomosaic is drawn in 4
// bands and joined.
// Skipped (visibly) where snakemake is not installed.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <set>

#include "libphoto/base/atomic_file.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/raster.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/survey_split.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

TEST(SplitWorkflow, FourPartsUnderSnakemakeMatchTheUnsplitSurvey) {
  if (std::system("snakemake --version > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "snakemake is not installed (apt-get install snakemake): the split workflow cannot run";
  }
  const fs::path sample = fs::path(AEROTRI_SOURCE_DIR) / "sample_surveys" / "synthetic_meadow";
  testing::TempDir dir;
  PipelineOptions o;
  o.images_dir = sample / "images";
  o.gcp = sample / "gcp_list.txt";
  o.checkpoints = sample / "checkpoints.txt";
  o.georef.leave_one_out = false;
  o.ortho = false;
  o.workspace = dir.path() / "whole";
  RunPipeline(o);
  const json whole = json::parse(ReadTextFile(o.workspace / "report.json"));

  PipelineOptions s = o;
  s.workspace = dir.path() / "split";
  RunIngestStage(s);
  const std::vector<SurveyPart> parts = SplitSurvey(s, SplitOptions{4, 0.0});
  ASSERT_EQ(parts.size(), 4u);
  std::set<std::string> in_a_part;
  int own = 0;
  for (const SurveyPart& p : parts) {
    EXPECT_LT(p.images.size(), 30u) << p.name;  // a part, not the survey
    in_a_part.insert(p.images.begin(), p.images.end());
    own += p.core;
  }
  EXPECT_EQ(in_a_part.size(), 35u);
  EXPECT_EQ(own, 35);
  // The global adjustment's options as `aerotri split` passes them on: the
  // whole survey's (the leave-one-out off; the library's stated sigmas,
  // where the command line's default is auto).
  WriteSplitWorkflow(s, parts, fs::path(AEROTRI_BINARY_DIR) / "tools" / "aerotri",
                     {"--gcp", o.gcp.string(), "--checkpoints", o.checkpoints.string(), "--leave-one-out", "off",
                      "--variance-components", "stated"});
  const std::string command = "cd '" + s.workspace.string() + "' && snakemake --cores 2 --quiet > snakemake.log 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << ReadTextFile(s.workspace / "snakemake.log");

  // Every photo once in the merged model, all registered.
  const SparseModel merged = ReadColmapText(s.workspace / "reconstruction");
  std::set<std::string> names;
  for (const Image& im : merged.images) EXPECT_TRUE(names.insert(im.name).second) << im.name;
  EXPECT_EQ(names.size(), 35u);
  const json split = json::parse(ReadTextFile(s.workspace / "report.json"));
  EXPECT_EQ(split["images"]["registered"], 35);
  EXPECT_EQ(split["reconstruction"].value("initial_pair", ""), "merged from 4 parts") << split["reconstruction"];
  EXPECT_NE(split["status"], "failed") << split["errors"];
  // The global adjustment ran with the whole survey's options.
  json split_options = split["georeference_options"], whole_options = whole["georeference_options"];
  split_options.erase("ingest");
  whole_options.erase("ingest");
  EXPECT_EQ(split_options, whole_options);
  // The seams are invisible at the check points ...
  const double whole_rmse = whole["check_points"]["rmse_3d_m"].get<double>();
  const double split_rmse = split["check_points"]["rmse_3d_m"].get<double>();
  EXPECT_LE(split_rmse, 1.2 * whole_rmse) << "split " << split_rmse << " m, whole " << whole_rmse << " m";
  // ... and in the DSM: the split survey's surface against the whole one's,
  // per quadrant (the parts' areas) and overall, within a GSD.
  const double gsd = whole["gsd_m"].get<double>();
  const Raster a = ReadRaster(s.workspace / "dsm.tif");
  const Raster b = ReadRaster(o.workspace / "dsm.tif");
  std::vector<std::vector<double>> quadrant(4);
  std::vector<double> all;
  for (int y = 0; y < a.height; y += 2) {
    for (int x = 0; x < a.width; x += 2) {
      const float v = a.values[static_cast<size_t>(y) * a.width + x];
      if (v == static_cast<float>(a.nodata)) continue;
      const double e = a.geotransform[0] + (x + 0.5) * a.geotransform[1];
      const double n = a.geotransform[3] + (y + 0.5) * a.geotransform[5];
      const auto w = SampleRaster(b, e, n);
      if (!w) continue;
      const double d = v - *w;
      quadrant[(2 * y >= a.height ? 2 : 0) + (2 * x >= a.width ? 1 : 0)].push_back(d);
      all.push_back(d);
    }
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  ASSERT_GT(all.size(), 10000u);
  std::printf("check RMSE 3D: split %.4f m, whole %.4f m; DSM split - whole: median %.4f m, GSD %.4f m\n",
              split_rmse, whole_rmse, median(all), gsd);
  EXPECT_LT(std::abs(median(all)), 0.5 * gsd);
  for (const auto& q : quadrant) {
    std::printf("  quadrant: %zu cells, median %.4f m\n", q.size(), q.empty() ? 0.0 : median(q));
    ASSERT_GT(q.size(), 1000u);
    EXPECT_LT(std::abs(median(q)), gsd) << "median split - whole " << median(q) << " m, GSD " << gsd << " m";
  }

  // The dense stage ran as 4 jobs of depth maps, then 4 of fusion, then one
  // of deliverables; its scratch is gone, and a second snakemake has
  // nothing to do (the records were temp files).
  const json dense = json::parse(ReadTextFile(s.workspace / "dense.json"));
  EXPECT_GT(dense["points"].get<long long>(), 100000) << dense;
  EXPECT_FALSE(fs::exists(s.workspace / "depth"));
  for (int k = 1; k <= 4; ++k) {
    const std::string share = std::to_string(k) + "_of_4";
    EXPECT_FALSE(fs::exists(s.workspace / "dense_parts" / ("fused_" + share + ".pts"))) << share;
    EXPECT_FALSE(fs::exists(s.workspace / "dense_parts" / ("fused_" + share + ".json"))) << share;
    // The orthomosaic was drawn in 4 bands, joined, and they are gone.
    EXPECT_FALSE(fs::exists(s.workspace / "ortho_parts" / ("band_" + share + ".tif"))) << share;
  }
  const json ortho = json::parse(ReadTextFile(s.workspace / "ortho.json"));
  EXPECT_EQ(ortho["ortho"]["images_used"], 35) << ortho;
  EXPECT_GT(ortho["ortho"]["filled_fraction"].get<double>(), 0.99) << ortho;
  const std::string again = "cd '" + s.workspace.string() + "' && snakemake --cores 2 -n > again.log 2>&1";
  ASSERT_EQ(std::system(again.c_str()), 0) << ReadTextFile(s.workspace / "again.log");
  EXPECT_NE(ReadTextFile(s.workspace / "again.log").find("Nothing to be done"), std::string::npos)
      << ReadTextFile(s.workspace / "again.log");
  // The shares' DSM is the one dense stage in one process makes from the
  // same model, cell for cell.
  const Raster shared = ReadRaster(s.workspace / "dsm.tif");
  PipelineOptions one = s;
  one.force = true;
  ASSERT_TRUE(RunDenseStage(one));
  const Raster whole_stage = ReadRaster(s.workspace / "dsm.tif");
  EXPECT_EQ(json::parse(ReadTextFile(s.workspace / "dense.json"))["points"], dense["points"]);
  ASSERT_EQ(shared.width, whole_stage.width);
  ASSERT_EQ(shared.height, whole_stage.height);
  for (int k = 0; k < 6; ++k) EXPECT_EQ(shared.geotransform[k], whole_stage.geotransform[k]) << k;
  size_t differ = 0;
  for (size_t k = 0; k < shared.values.size(); ++k) differ += shared.values[k] != whole_stage.values[k] ? 1 : 0;
  EXPECT_EQ(differ, 0u) << "of " << shared.values.size() << " cells";
}

}  // namespace
}  // namespace aerotri
