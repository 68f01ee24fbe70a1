// SPDX-License-Identifier: BSD-3-Clause
// A coordinate list placed on the targets found in photos without GPS
// (PlaceListOnTargets): a scattered layout with missing and spurious
// targets is placed, and the similarity recovered; a symmetric layout is
// refused as ambiguous, never guessed; too few targets are refused.
#include <gtest/gtest.h>

#include <random>

#include "libphoto/targets/marking.h"

namespace aerotri {
namespace {

// A model frame: turned, scaled, moved from ENU.
Similarity ModelFromEnu() {
  Similarity s;
  s.scale = 0.23;
  s.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(1.3, Eigen::Vector3d(0.2, 0.9, -0.4).normalized()));
  s.translation = Eigen::Vector3d(4.0, -2.0, 11.0);
  return s;
}

TEST(ListPlacement, ScatteredLayoutIsPlacedDespiteMissingAndSpuriousTargets) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-60.0, 60.0), h(-2.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.01);  // 1 cm: triangulated targets
  std::vector<Eigen::Vector3d> surveyed;
  for (int k = 0; k < 9; ++k) surveyed.emplace_back(u(rng), u(rng), h(rng));
  const Similarity to_model = ModelFromEnu();
  std::vector<Eigen::Vector3d> targets;
  for (int k = 0; k < 9; ++k) {
    if (k == 4 || k == 7) continue;  // two targets not found in the photos
    targets.push_back(to_model.Apply(surveyed[k] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))));
  }
  for (int k = 0; k < 4; ++k) targets.push_back(to_model.Apply(Eigen::Vector3d(u(rng), u(rng), h(rng))));  // not control
  std::string why;
  const auto placed = PlaceListOnTargets(targets, surveyed, &why);
  ASSERT_TRUE(placed) << why;
  EXPECT_EQ(placed->placed, 7);
  // RMS of 3D noise 1 cm per axis, less what 7 parameters absorb: 0.3 to 3 cm.
  EXPECT_GT(placed->rms_m, 0.003);
  EXPECT_LT(placed->rms_m, 0.03);
  EXPECT_NEAR(placed->model_to_enu.scale * to_model.scale, 1.0, 1e-3);
  for (int k : {4, 7}) {  // the points whose targets were not found are predicted to a few cm
    EXPECT_LT((placed->model_to_enu.Apply(to_model.Apply(surveyed[k])) - surveyed[k]).norm(), 0.05) << k;
  }
}

TEST(ListPlacement, SymmetricLayoutIsRefusedAsAmbiguous) {
  // Four points on the corners of a level square: a quarter turn maps the
  // layout onto itself.
  const std::vector<Eigen::Vector3d> surveyed = {{0, 0, 0}, {40, 0, 0}, {40, 40, 0}, {0, 40, 0}};
  const Similarity to_model = ModelFromEnu();
  std::vector<Eigen::Vector3d> targets;
  for (const Eigen::Vector3d& p : surveyed) targets.push_back(to_model.Apply(p));
  std::string why;
  EXPECT_FALSE(PlaceListOnTargets(targets, surveyed, &why));
  EXPECT_NE(why.find("two ways"), std::string::npos) << why;
  // One corner moved off the square breaks the symmetry: placed.
  std::vector<Eigen::Vector3d> broken = surveyed;
  broken[2] = Eigen::Vector3d(47, 52, 1.5);
  targets[2] = to_model.Apply(broken[2]);
  const auto placed = PlaceListOnTargets(targets, broken, &why);
  ASSERT_TRUE(placed) << why;
  EXPECT_EQ(placed->placed, 4);
}

TEST(ListPlacement, TooFewTargetsAreRefused) {
  const std::vector<Eigen::Vector3d> surveyed = {{0, 0, 0}, {40, 0, 0}, {40, 40, 0}, {5, 30, 0}};
  std::string why;
  EXPECT_FALSE(PlaceListOnTargets({{0, 0, 0}, {1, 0, 0}}, surveyed, &why));
  EXPECT_NE(why.find("2 targets found"), std::string::npos) << why;
}

}  // namespace
}  // namespace aerotri
