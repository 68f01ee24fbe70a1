// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/colmap_text.h"

#include <gtest/gtest.h>

#include <fstream>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

void Write(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(ColmapText, WriteThenReadKeepsEveryResidual) {
  SyntheticSurveyOptions o;
  o.area_width_m = 120;
  o.area_height_m = 90;
  o.num_tie_points = 300;
  const SparseModel model = MakeSyntheticSurvey(o).observed;
  testing::TempDir dir;
  WriteColmapText(model, dir / "m");
  const SparseModel back = ReadColmapText(dir / "m");
  ASSERT_EQ(back.images.size(), model.images.size());
  ASSERT_EQ(back.points.size(), model.points.size());
  ASSERT_EQ(back.observations.size(), model.observations.size());
  EXPECT_EQ(back.cameras[0].model, CameraModelId::kBrown);
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(back.cameras[0].params[i], model.cameras[0].params[i], 1e-9);
  const auto e1 = ReprojectionErrors(model), e2 = ReprojectionErrors(back);
  double worst = 0.0;
  for (size_t i = 0; i < e1.size(); ++i) worst = std::max(worst, std::abs(e1[i] - e2[i]));
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT((back.images[3].pose.centre_in_world - model.images[3].pose.centre_in_world).norm(), 1e-9);
  EXPECT_EQ(back.images[3].name, model.images[3].name);
}

// Each rolling-shutter photo's motion goes beside the model
// (rolling_shutter.txt) and comes back exactly; a model without one leaves
// no file, and writing it over an earlier model's removes that model's.
TEST(ColmapText, RollingShuttersKeptBesideTheModel) {
  SyntheticSurveyOptions o;
  o.num_tie_points = 50;
  o.readout_time_s = 0.0473;
  o.flight_speed_mps = 12.3;
  SparseModel model = MakeSyntheticSurvey(o).observed;
  ASSERT_GT(model.images.size(), 3u);
  model.images[2].rolling_shutter.reset();  // a global shutter among them
  model.images[1].rolling_shutter->velocity = Eigen::Vector3d(-0.1, 1.0 / 3.0, 2e-7);
  testing::TempDir dir;
  WriteColmapText(model, dir / "m");
  ASSERT_TRUE(std::filesystem::exists(dir / "m" / "rolling_shutter.txt"));
  const SparseModel back = ReadColmapText(dir / "m");
  for (size_t i = 0; i < model.images.size(); ++i) {
    const auto& want = model.images[i].rolling_shutter;
    const auto& got = back.images[i].rolling_shutter;
    ASSERT_EQ(got.has_value(), want.has_value()) << model.images[i].name;
    if (!want) continue;
    EXPECT_EQ(got->readout_time_s, want->readout_time_s);
    EXPECT_EQ(got->velocity, want->velocity);
  }
  EXPECT_FALSE(back.images[2].rolling_shutter);
  EXPECT_EQ(back.images[0].rolling_shutter->readout_time_s, 0.0473);

  for (Image& image : model.images) image.rolling_shutter.reset();
  WriteColmapText(model, dir / "m");
  EXPECT_FALSE(std::filesystem::exists(dir / "m" / "rolling_shutter.txt"));
  for (const Image& image : ReadColmapText(dir / "m").images) EXPECT_FALSE(image.rolling_shutter) << image.name;
}

TEST(ColmapText, ReadsColmapConventionsAndModels) {
  // A hand-written COLMAP model: the 2D point (100.5, 50.5) is the centre of
  // pixel (100, 50) in aerotri's convention; cx 320 becomes 319.5.
  testing::TempDir dir;
  Write(dir / "cameras.txt",
        "# comment\n1 SIMPLE_RADIAL 640 480 500 320 240 -0.1\n2 PINHOLE 640 480 500 500.2 320 240\n"
        "3 OPENCV 640 480 500 500 320 240 -0.1 0.01 0.001 0.002\n");
  Write(dir / "images.txt",
        "1 1 0 0 0 0 0 5 1 a.jpg\n100.5 50.5 7 10 10 -1\n"
        "2 1 0 0 0 -1 0 5 3 b.jpg\n\n");
  Write(dir / "points3D.txt", "7 0.1 0.2 0.3 255 128 0 0.5 1 0\n");
  const SparseModel m = ReadColmapText(dir.path());
  ASSERT_EQ(m.cameras.size(), 3u);
  EXPECT_EQ(m.cameras[0].model, CameraModelId::kBrown);
  EXPECT_DOUBLE_EQ(m.cameras[0].params[1], 319.5);
  EXPECT_DOUBLE_EQ(m.cameras[0].params[3], -0.1);
  EXPECT_EQ(m.cameras[1].model, CameraModelId::kPinhole);
  EXPECT_NEAR(m.cameras[1].params[0], 500.1, 1e-12);
  EXPECT_DOUBLE_EQ(m.cameras[2].params[6], 0.001);  // p1
  ASSERT_EQ(m.observations.size(), 1u);
  EXPECT_DOUBLE_EQ(m.observations[0].xy.x(), 100.0);
  EXPECT_DOUBLE_EQ(m.observations[0].xy.y(), 50.0);
  // t = (0, 0, 5), R = I: the centre is (0, 0, -5).
  EXPECT_LT((m.images[0].pose.centre_in_world - Eigen::Vector3d(0, 0, -5)).norm(), 1e-12);
  EXPECT_EQ(m.points[0].color[1], 128);
}

TEST(ColmapText, RefusesWhatItCannotRepresentWithTheLine) {
  struct Case {
    std::string file, text;
    int line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"cameras.txt", "1 FISHEYE 640 480 1 2 3 4\n", 1, "camera model 'FISHEYE' is not supported"},
      {"cameras.txt", "1 PINHOLE 640 480 500 600 320 240\n", 1, "differ"},
      {"cameras.txt", "1 SIMPLE_PINHOLE 640 480 500 320\n", 1, "expects 3 parameters, got 2"},
      {"images.txt", "1 1 0 0 0 0 0 5 9 a.jpg\n\n", 1, "refers to camera 9"},
      {"images.txt", "1 1 0 0 0 0 0 5 1 a.jpg\n1 2\n", 2, "triples"},
      {"images.txt", "1 2 0 0 0 0 0 5 1 a.jpg\n\n", 1, "unit quaternion"},
      {"points3D.txt", "7 0.1 0.2 0.3 255 128 0 0.5 1\n", 1, "odd count"},
      {"points3D.txt", "7 0.1 x 0.3 255 128 0 0.5\n", 1, "expected a number for X Y Z, got 'x'"},
      // Found by tests/fuzz/fuzz_colmap.cc: an id beyond int was converted with undefined behaviour.
      {"cameras.txt", "1e20 PINHOLE 640 480 500 500 320 240\n", 1,
       "expected an integer (at most 2147483647 in magnitude) for CAMERA_ID, got '1e20'"},
      {"cameras.txt", "1 PINHOLE 4294967296 480 500 500 320 240\n", 1, "for WIDTH, got '4294967296'"},
      {"rolling_shutter.txt", "1 0.04 12 0\n", 1, "expected 'IMAGE_ID READOUT_TIME_S VX VY VZ NAME', got 4"},
      {"rolling_shutter.txt", "# header\n2 0.04 12 0 0 b.jpg\n", 2, "refers to image 2, not in images.txt"},
      {"rolling_shutter.txt", "1 -0.04 12 0 0 a.jpg\n", 1, "expected a readout time from 0 to 1 s, got -0.04"},
      {"rolling_shutter.txt", "1 0.04 12 nan 0 a.jpg\n", 1, "for VX VY VZ, got 'nan'"},
      {"rolling_shutter.txt", "1 0.04 12 0 0 a.jpg\n1 0.04 12 0 0 a.jpg\n", 2, "appears twice"},
  };
  for (const Case& c : cases) {
    testing::TempDir dir;
    Write(dir / "cameras.txt", "1 SIMPLE_PINHOLE 640 480 500 320 240\n");
    Write(dir / "images.txt", "1 1 0 0 0 0 0 5 1 a.jpg\n\n");
    Write(dir / "points3D.txt", "");
    Write(dir / c.file, c.text);
    try {
      ReadColmapText(dir.path());
      ADD_FAILURE() << "accepted " << c.file << ": " << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.file), std::string::npos) << e.what();
    }
  }
  testing::TempDir empty;
  EXPECT_THROW(ReadColmapText(empty.path()), IoError);
}

}  // namespace
}  // namespace aerotri
