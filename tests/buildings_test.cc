// SPDX-License-Identifier: BSD-3-Clause
// A rendered survey with box buildings through the whole pipeline: the
// ground classification against the scene's truth, the DTM against the bare
// terrain (buildings removed), the true orthomosaic against the true
// colours of ground and roofs.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include <opencv2/imgproc.hpp>

#include "georef/crs.h"
#include "georef/local_frame.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/point_cloud.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/simulate/survey_writer.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;

struct Footprint {  // in the output CRS (axis-aligned: the grid convergence here is under 1 degree)
  double x, y, half_w, half_h, height;
  bool Inside(double px, double py, double grow) const {
    return std::abs(px - x) <= half_w + grow && std::abs(py - y) <= half_h + grow;
  }
};

TEST(Buildings, ClassifiedCloudDtmAndTrueOrthoMatchTheScene) {
  testing::TempDir dir;
  SimulationOptions sim;
  sim.survey.seed = 7;
  sim.survey.width = 640;
  sim.survey.height = 480;
  sim.survey.brown_params = {520.0, 322.0, 238.0, -0.08, 0.05, -0.01, 0.0005, -0.0003};
  sim.survey.area_width_m = 60.0;
  sim.survey.area_height_m = 44.0;
  sim.survey.flight_height_m = 40.0;
  sim.survey.relief_m = 3.0;
  sim.survey.num_tie_points = 300;
  sim.survey.num_control_points = 6;
  sim.survey.num_check_points = 4;
  sim.georef.seed = 7;
  sim.num_buildings = 3;
  WriteSyntheticSurvey(sim, dir.path() / "survey");
  const fs::path survey = dir.path() / "survey";

  PipelineOptions o;
  o.images_dir = survey / "images";
  o.workspace = dir.path() / "ws";
  o.gcp = survey / "gcp_list.txt";
  o.checkpoints = survey / "checkpoints.txt";
  o.georef.leave_one_out = false;
  o.log = [](const std::string&) {};
  ASSERT_NE(RunPipeline(o), "failed");
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const auto truth = nlohmann::json::parse(ReadTextFile(survey / "truth" / "truth.json"));
  const double gsd = report["gsd_m"];

  // Footprints and heights in the output CRS (ellipsoidal, as truth/dem.tif).
  const Crs crs = Crs::FromString("EPSG:32632");
  const LocalFrame frame({truth["origin"]["lat_deg"], truth["origin"]["lon_deg"], truth["origin"]["h_m"]});
  std::vector<Footprint> buildings;
  for (const auto& b : truth["buildings"]) {
    const Eigen::Vector3d c = crs.FromGeodetic(frame.GeodeticFromEnu({b["centre_enu_m"][0], b["centre_enu_m"][1], 0.0}));
    buildings.push_back({c.x(), c.y(), b["half_size_m"][0], b["half_size_m"][1], b["height_m"]});
  }
  ASSERT_EQ(buildings.size(), 3u);
  const Raster terrain = ReadRaster(survey / "truth" / "dem.tif");
  const double n = Egm96Undulation(46.5, 7.5);  // deliverables: EGM96 heights

  // Classes: points well inside a footprint are roofs, points 1.5 m clear of
  // every footprint ground; the band along the walls is left out.
  const CrsCloud cloud = ReadLas(o.workspace / "cloud.laz");
  ASSERT_EQ(cloud.classes.size(), cloud.xyz.size());
  long long truth_ground = 0, truth_ground_found = 0, said_ground = 0, said_ground_right = 0, roofs = 0, roofs_found = 0;
  for (size_t i = 0; i < cloud.xyz.size(); ++i) {
    const Eigen::Vector3d& p = cloud.xyz[i];
    bool roof = false, clear = true;
    for (const Footprint& b : buildings) {
      roof = roof || b.Inside(p.x(), p.y(), -0.75);
      clear = clear && !b.Inside(p.x(), p.y(), 1.5);
    }
    const bool ground = cloud.classes[i] == 2;
    if (clear) {
      ++truth_ground;
      truth_ground_found += ground;
    }
    if (roof) {
      ++roofs;
      roofs_found += !ground;
    }
    if (ground && (clear || roof)) {
      ++said_ground;
      said_ground_right += clear;
    }
  }
  const double recall = static_cast<double>(truth_ground_found) / truth_ground;
  const double precision = static_cast<double>(said_ground_right) / said_ground;
  std::printf("ground recall %.4f, precision %.4f; roof points not ground %.4f (%lld)\n", recall, precision,
              static_cast<double>(roofs_found) / roofs, roofs);
  EXPECT_GT(recall, 0.95);
  EXPECT_GT(precision, 0.95);
  ASSERT_GT(roofs, 1000);
  EXPECT_GT(static_cast<double>(roofs_found) / roofs, 0.95);

  // The DTM against the bare terrain; the DSM keeps the roofs.
  const Raster dtm = ReadRaster(o.workspace / "dtm.tif"), dsm = ReadRaster(o.workspace / "dsm.tif");
  std::vector<double> open_err, under_err, roof_rise;
  const double margin = 14.0;  // truth's 10 m margin, and 4 m more
  for (int y = 0; y < terrain.height; ++y) {
    for (int x = 0; x < terrain.width; ++x) {
      const double px = terrain.X(x), py = terrain.Y(y);
      if (px < terrain.X(0) + margin || px > terrain.X(terrain.width - 1) - margin || py > terrain.Y(0) - margin ||
          py < terrain.Y(terrain.height - 1) + margin) {
        continue;
      }
      const auto z = SampleRaster(dtm, px, py);
      const auto s = SampleRaster(dsm, px, py);
      if (!z || !s) continue;
      bool under = false, near = false;
      for (const Footprint& b : buildings) {
        under = under || b.Inside(px, py, -1.0);
        near = near || b.Inside(px, py, 1.0);
      }
      const double dz = std::abs(*z + n - terrain.at(x, y));
      if (under) {
        under_err.push_back(dz);
        roof_rise.push_back(*s - *z);
      } else if (!near) {
        open_err.push_back(dz);
      }
    }
  }
  ASSERT_GT(open_err.size(), 1000u);
  ASSERT_GT(under_err.size(), 50u);
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::vector<double> all = open_err;
  all.insert(all.end(), under_err.begin(), under_err.end());
  std::printf("DTM |dz| median %.3f m (open %.3f, under roofs %.3f); DSM - DTM under roofs %.2f m; GSD %.3f m\n",
              median(all), median(open_err), median(under_err), median(roof_rise), gsd);
  EXPECT_LT(median(all), gsd);               // the bar: one GSD
  EXPECT_GT(median(all), 0.001);             // not the truth copied
  EXPECT_LT(median(under_err), 0.5);         // the buildings (4-8 m) are gone
  EXPECT_GT(median(roof_rise), 3.0);         // and the DSM kept them

  // True ortho: the roofs where they are, at the check targets within a GSD.
  EXPECT_EQ(report["ortho"]["check_points"]["count"], 4);
  // Located to a fraction of a cell (the truth ortho itself gives 0.3 GSD).
  EXPECT_LT(report["ortho"]["check_points"]["rmse_h_m"].get<double>(), 0.6 * gsd);
}

}  // namespace
}  // namespace aerotri
