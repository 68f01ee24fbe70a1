// SPDX-License-Identifier: BSD-3-Clause
// Every stage's options check themselves: a library caller gets the same
// refusal, naming the option, its value and what was expected, as a user of
// the command line, before any stage runs.
#include <gtest/gtest.h>

#include <functional>

#include "libphoto/base/error.h"
#include "libphoto/pipeline/pipeline.h"

namespace aerotri {
namespace {

// The message of the InvalidArgument that check throws, or "" when none.
std::string Refusal(const std::function<void()>& check) {
  try {
    check();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

TEST(OptionsCheck, TheDefaultsPass) {
  EXPECT_NO_THROW(FeatureOptions().Check());
  EXPECT_NO_THROW(MatchOptions().Check());
  EXPECT_NO_THROW(MapperOptions().Check());
  EXPECT_NO_THROW(GeoreferenceOptions().Check());
  EXPECT_NO_THROW(PipelineOptions().Check());
}

TEST(OptionsCheck, EachStageNamesItsOptionValueAndRange) {
  FeatureOptions features;
  features.max_features = 0;
  EXPECT_EQ(Refusal([&] { features.Check(); }), "--max-features: expected a positive number of features, got 0");

  MatchOptions matching;
  matching.ratio = 1.5;
  EXPECT_EQ(Refusal([&] { matching.Check(); }), "matching ratio: expected Lowe's ratio in (0, 1], got 1.5");

  MapperOptions mapper;
  mapper.min_pnp_inliers = 3;
  EXPECT_EQ(Refusal([&] { mapper.Check(); }),
            "mapper min_pnp_inliers: expected at least 4 (P3P and one to check), got 3");

  GeoreferenceOptions georef;
  georef.gcp_sigma_v_m = -0.01;
  EXPECT_EQ(Refusal([&] { georef.Check(); }), "--gcp-sigma-v: expected a positive number of metres, got -0.01");

  // The bundle's own validation is part of the georeference stage's.
  georef = GeoreferenceOptions();
  georef.bundle.observation_sigma_px = 0.0;
  EXPECT_NE(Refusal([&] { georef.Check(); }).find("observation sigma must be > 0 px"), std::string::npos);

  // A CRS PROJ cannot create is a CrsError, naming it.
  georef = GeoreferenceOptions();
  georef.output_crs = "EPSG:999999";
  EXPECT_THROW(georef.Check(), CrsError);
}

TEST(OptionsCheck, ThePipelineChecksEveryStageAndItsOwnFields) {
  const auto refusal = [](const std::function<void(PipelineOptions*)>& set) {
    PipelineOptions o;
    set(&o);
    return Refusal([&] { o.Check(); });
  };
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->features.max_dimension = 10; }),
            "--max-dimension: expected 0 (full size) or at least 32 pixels, got 10");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->matching.gps_neighbours = 0; }),
            "--gps-neighbours: expected at least 1 image, got 0");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->dense_min_views = 0; }),
            "--dense-min-views: expected at least 1 depth map, got 0");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->dense_image_scale = 2.0; }),
            "dense image scale: expected a fraction of the working images in (0, 1], got 2");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->heights = "geoid"; }),
            "--heights: expected egm96 or ellipsoidal, got 'geoid'");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->ortho_surface = "dem"; }),
            "--ortho-surface: expected dsm or dtm, got 'dem'");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->dsm_fill_m = std::nan(""); }),
            "--dsm-fill: expected 0 (no filling) or a positive number of metres, got nan");
  EXPECT_EQ(refusal([](PipelineOptions* o) { o->gps_sigma_h_m = 0.0; }),
            "--gps-sigma-h: expected a positive number of metres, got 0");
}

TEST(OptionsCheck, BadOptionsAreRefusedBeforeAnyStageWritesAnything) {
  PipelineOptions o;
  o.workspace = std::filesystem::temp_directory_path() / ("aerotri_options_check_" + std::to_string(::getpid()));
  std::filesystem::remove_all(o.workspace);
  o.ground_cell_m = 0.0;
  EXPECT_EQ(Refusal([&] { ValidateInputs(o); }), "--ground-cell: expected a positive number of metres, got 0");
  EXPECT_FALSE(std::filesystem::exists(o.workspace));
}

}  // namespace
}  // namespace aerotri
