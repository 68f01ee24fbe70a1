// SPDX-License-Identifier: BSD-3-Clause
// Calibration certificates: parsing with file:line errors, millimetres and
// pixels giving the same camera, fixed values held and priors weighed in
// the georeferenced adjustment of a synthetic block with known intrinsics.
#include "libphoto/adjust/camera_file.h"

#include <gtest/gtest.h>

#include <fstream>

#include "libphoto/survey/georeferencing.h"
#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

void Write(const std::filesystem::path& path, const std::string& text) { std::ofstream(path) << text; }

TEST(CameraFile, BadLinesNameFileLineAndExpectation) {
  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"f 3000\nq 1\n", 2, "unknown parameter 'q'"},
      {"f three\n", 1, "expected a number after 'f'"},
      {"f 3000 sigma -1\n", 1, "expected a positive sigma, got '-1'"},
      {"f 3000 loose\n", 1, "expected 'f VALUE', 'f VALUE sigma S' or 'f VALUE fixed'"},
      {"f 3000\n# again\nf 3001\n", 3, "'f' is given twice (also on line 1)"},
      {"units mm\npixel_size_mm 0.006\ncx 10\n", 3, "with 'units mm' give x0 / y0"},
      {"x0 0.1\n", 1, "'x0' is in millimetres"},
      {"units mm\nf 18\n", 0, "'units mm' needs pixel_size_mm"},
      {"units inch\n", 1, "expected 'units mm' or 'units px'"},
  };
  testing::TempDir dir;
  for (const Case& c : cases) {
    Write(dir / "camera.txt", c.text);
    try {
      ReadCameraFile(dir / "camera.txt");
      ADD_FAILURE() << "accepted: " << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("camera.txt"), std::string::npos);
    }
  }
  EXPECT_THROW(ReadCameraFile(dir / "absent.txt"), IoError);
}

// The same certificate in millimetres and in pixels sets the same camera;
// a model at half resolution gets half the focal length, its principal point
// on the same pixel centres.
TEST(CameraFile, MillimetresAndPixelsAgree) {
  testing::TempDir dir;
  Write(dir / "px.txt", "f 3000 sigma 0.5\ncx 2010.5\ncy 1490.5 fixed\nk1 -0.05 sigma 0.001\np2 1e-4\n");
  // 6 um pixels, 4000 x 3000 image: centre (1999.5, 1499.5).
  Write(dir / "mm.txt",
        "units mm  # certificate\npixel_size_mm 0.006\nf 18.0 sigma 0.003\nx0 0.066\ny0 0.054 fixed\nk1 -0.05 sigma "
        "0.001\np2 1e-4\n");
  auto camera_model = [] {
    SparseModel m;
    m.cameras.push_back(Camera::Create(CameraModelId::kBrown, 2900.0, 4000, 3000));
    return m;
  };
  SparseModel a = camera_model(), b = camera_model();
  BundleOptions oa, ob;
  ApplyCameraFile(ReadCameraFile(dir / "px.txt"), &a, &oa);
  ApplyCameraFile(ReadCameraFile(dir / "mm.txt"), &b, &ob);
  for (int k = 0; k < a.cameras[0].info().num_params(); ++k) {
    EXPECT_NEAR(a.cameras[0].params[k], b.cameras[0].params[k], 1e-9) << a.cameras[0].info().param_names[k];
  }
  EXPECT_DOUBLE_EQ(a.cameras[0].params[0], 3000.0);
  ASSERT_EQ(oa.intrinsics_priors.size(), 2u);
  ASSERT_EQ(ob.intrinsics_priors.size(), 2u);
  EXPECT_NEAR(oa.intrinsics_priors[0].sigma, ob.intrinsics_priors[0].sigma, 1e-12);  // 0.5 px = 0.003 mm
  EXPECT_EQ(oa.held_params, (std::vector<std::pair<int, int>>{{0, 2}}));
  EXPECT_EQ(ob.held_params, oa.held_params);

  SparseModel half;
  half.cameras.push_back(Camera::Create(CameraModelId::kBrown, 1450.0, 2000, 1500));
  BundleOptions oh;
  ApplyCameraFile(ReadCameraFile(dir / "px.txt"), &half, &oh, {2.0});
  EXPECT_DOUBLE_EQ(half.cameras[0].params[0], 1500.0);
  EXPECT_DOUBLE_EQ(half.cameras[0].params[1], (2010.5 + 0.5) / 2.0 - 0.5);
  EXPECT_DOUBLE_EQ(oh.intrinsics_priors[0].sigma, 0.25);
}

// In the adjustment: fixed values stay where the certificate puts them,
// priors hold what the block cannot determine, and a parameter the camera
// model lacks is refused naming the file and line.
TEST(CameraFile, HoldsAndWeighsTheIntrinsicsInTheAdjustment) {
  SyntheticSurveyOptions so;
  so.seed = 7;
  so.num_tie_points = 800;
  so.num_control_points = 6;
  so.num_check_points = 3;
  const SyntheticGeoref scene = MakeSyntheticGeoref(so, {});
  const Camera& truth = scene.survey.truth.cameras.at(0);
  testing::TempDir dir;
  std::ostringstream text;
  text.precision(17);
  for (int k = 0; k < truth.info().num_params(); ++k) {
    text << truth.info().param_names[k] << " " << truth.params[k] << (k < 3 ? " fixed\n" : " sigma 1e-6\n");
  }
  Write(dir / "certificate.txt", text.str());
  GeoreferenceOptions options;
  options.output_crs = "EPSG:32632";
  SparseModel model = scene.tie_model;
  for (int k = 0; k < model.cameras[0].info().num_params(); ++k) model.cameras[0].params[k] *= 1.01;
  ApplyCameraFile(ReadCameraFile(dir / "certificate.txt"), &model, &options.bundle);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(model.cameras[0].params[k], truth.params[k]) << k;  // held exactly
  for (int k = 3; k < truth.info().num_params(); ++k) {
    EXPECT_NEAR(model.cameras[0].params[k], truth.params[k], 1e-5) << truth.info().param_names[k];
  }
  EXPECT_LT(r.check_stats.rmse_3d_m, 0.05);

  Write(dir / "snavely.txt", "f 3000\n\n# a Brown term\nk3 0.1\n");
  SparseModel snavely;
  snavely.cameras.push_back(Camera::Create(CameraModelId::kSnavely, 80.0, 100, 100));
  BundleOptions o;
  try {
    ApplyCameraFile(ReadCameraFile(dir / "snavely.txt"), &snavely, &o);
    ADD_FAILURE() << "k3 accepted for a Snavely camera";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("snavely.txt:4: camera"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("has no parameter 'k3'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace aerotri
