// SPDX-License-Identifier: BSD-3-Clause
// The bundle adjuster's choices as data: which blocks take part and vary and
// what holds the gauge, decided from the model and the options before any
// problem is built.
#include "libphoto/adjust/bundle_config.h"

#include <gtest/gtest.h>

#include "libphoto/simulate/synthetic_survey.h"

namespace aerotri {
namespace {

SparseModel SmallBlock() {
  SyntheticSurveyOptions o;
  o.seed = 3;
  o.area_width_m = 120.0;
  o.area_height_m = 90.0;
  o.num_tie_points = 300;
  SparseModel model = MakeSyntheticSurvey(o).observed;
  for (Image& image : model.images) image.gps_prior.reset();
  for (Point& point : model.points) point.prior.reset();
  return model;
}

PositionPrior At(const Eigen::Vector3d& position) {
  PositionPrior prior;
  prior.position = position;
  return prior;
}

int FarthestFrom(const SparseModel& model, int a) {
  int best = -1;
  double longest = 0.0;
  for (size_t i = 0; i < model.images.size(); ++i) {
    const double d = (model.images[i].pose.centre_in_world - model.images[a].pose.centre_in_world).norm();
    if (d > longest) {
      longest = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

TEST(BundleConfig, WithoutPriorsTheFirstImageIsHeldAndTheLongestBaselineKeepsTheScale) {
  const SparseModel model = SmallBlock();
  const BundleConfig config = ConfigureBundle(model, BundleOptions());
  ASSERT_GT(model.images.size(), 10u);
  EXPECT_EQ(config.gauge, BundleGauge::kFixedImage);
  EXPECT_EQ(config.image_a, 0);
  EXPECT_EQ(config.image_b, FarthestFrom(model, 0));
  EXPECT_NEAR(config.baseline_m,
              (model.images[config.image_b].pose.centre_in_world - model.images[0].pose.centre_in_world).norm(),
              1e-9);
  EXPECT_TRUE(config.restore_scale);
  EXPECT_TRUE(config.HoldsRotationOf(0));
  EXPECT_TRUE(config.HoldsCentreOf(0));
  EXPECT_FALSE(config.HoldsRotationOf(1));
  EXPECT_FALSE(config.AnyMerged());  // one camera group shared by every image
  EXPECT_EQ(config.num_images, static_cast<int>(model.images.size()));
  EXPECT_NE(config.Describe(model, 0, 0, false).find("held fixed"), std::string::npos);
}

TEST(BundleConfig, PriorsThatSpanAPlaneHoldTheDatumAndNothingIsFixed) {
  SparseModel model = SmallBlock();
  for (Image& image : model.images) image.gps_prior = At(image.pose.centre_in_world);
  const BundleConfig config = ConfigureBundle(model, BundleOptions());
  EXPECT_EQ(config.gauge, BundleGauge::kPriors);
  EXPECT_EQ(config.prior_positions.size(), model.images.size());
  for (size_t i = 0; i < model.images.size(); ++i) {
    EXPECT_FALSE(config.HoldsRotationOf(static_cast<int>(i)));
    EXPECT_FALSE(config.HoldsCentreOf(static_cast<int>(i)));
  }
  EXPECT_EQ(config.Describe(model, 12, 0, false), "datum from priors (12 GPS, 0 GCP); no parameter held fixed");

  // The same priors, switched off, no longer count.
  BundleOptions no_gps;
  no_gps.use_gps_priors = false;
  EXPECT_EQ(ConfigureBundle(model, no_gps).gauge, BundleGauge::kFixedImage);
}

TEST(BundleConfig, FewOrCollinearPriorsHoldOneRotationAndGiveTheScaleOnlyWhenDistinct) {
  SparseModel model = SmallBlock();
  // Two distinct priors: they give the scale, the first image's rotation is held.
  model.images[2].gps_prior = At(model.images[2].pose.centre_in_world);
  model.images[7].gps_prior = At(model.images[7].pose.centre_in_world);
  BundleConfig config = ConfigureBundle(model, BundleOptions());
  EXPECT_EQ(config.gauge, BundleGauge::kHeldRotation);
  EXPECT_FALSE(config.restore_scale);
  EXPECT_TRUE(config.HoldsRotationOf(config.image_a));
  EXPECT_FALSE(config.HoldsCentreOf(config.image_a));

  // Two priors at one position say nothing about scale.
  model.images[7].gps_prior = At(model.images[2].pose.centre_in_world);
  config = ConfigureBundle(model, BundleOptions());
  EXPECT_EQ(config.gauge, BundleGauge::kHeldRotation);
  EXPECT_TRUE(config.restore_scale);

  // Three collinear priors do not fix the rotation about their line.
  const std::vector<Eigen::Vector3d> line = {{0, 0, 50}, {10, 0, 50}, {20, 0, 50}};
  EXPECT_FALSE(PriorsFixDatum(line));
  EXPECT_TRUE(PriorsFixDatum({{0, 0, 50}, {10, 0, 50}, {0, 10, 50}}));
}

TEST(BundleConfig, ImagesWithACameraGroupOfTheirOwnAreMergedAndTheNetworkIsFree) {
  SparseModel model = SmallBlock();
  const Camera shared = model.cameras[0];
  model.cameras.clear();
  for (size_t i = 0; i < model.images.size(); ++i) {
    model.cameras.push_back(shared);
    model.images[i].camera = static_cast<int>(i);
  }
  BundleConfig config = ConfigureBundle(model, BundleOptions());
  EXPECT_EQ(config.gauge, BundleGauge::kFreeNetwork);
  EXPECT_FALSE(config.HoldsRotationOf(config.image_a));
  for (size_t i = 0; i < model.images.size(); ++i) EXPECT_TRUE(config.merged[i]) << i;

  // Nothing to refine: no merged block (the intrinsics are held apart).
  BundleOptions held;
  held.refine_intrinsics = IntrinsicsRefinement::kNone;
  config = ConfigureBundle(model, held);
  EXPECT_FALSE(config.AnyMerged());

  // An image with a GPS prior keeps its centre in a block of its own.
  model.images[4].gps_prior = At(model.images[4].pose.centre_in_world);
  config = ConfigureBundle(model, BundleOptions());
  EXPECT_FALSE(config.merged[4]);
  EXPECT_EQ(config.gauge, BundleGauge::kHeldRotation);
  EXPECT_FALSE(config.merged[config.image_a]);  // its rotation is held
}

TEST(BundleConfig, PointsTakePartByRoleAndObservations) {
  SparseModel model = SmallBlock();
  // A tie point seen once is skipped; a control point with a prior seen once is kept.
  const auto per_point = model.ObservationsPerPoint();
  int tie = -1, control = -1, check = -1;
  for (size_t p = 0; p < model.points.size(); ++p) {
    if (per_point[p] < 2) continue;
    const PointRole role = model.points[p].role;
    if (role == PointRole::kTie && tie < 0) tie = static_cast<int>(p);
    if (role == PointRole::kControl && control < 0) control = static_cast<int>(p);
    if (role == PointRole::kCheck && check < 0) check = static_cast<int>(p);
  }
  ASSERT_GE(tie, 0);
  ASSERT_GE(control, 0);
  ASSERT_GE(check, 0);
  auto keep_first_observation_of = [&](int point) {
    bool kept = false;
    std::vector<Observation> observations;
    for (const Observation& obs : model.observations) {
      if (obs.point == point && kept) continue;
      kept |= obs.point == point;
      observations.push_back(obs);
    }
    model.observations = observations;
  };
  keep_first_observation_of(tie);
  keep_first_observation_of(control);
  model.points[control].prior = At(model.points[control].position);

  BundleConfig config = ConfigureBundle(model, BundleOptions());
  EXPECT_FALSE(config.point_used[tie]);
  EXPECT_TRUE(config.point_used[control]);
  EXPECT_FALSE(config.point_used[check]);  // independent by default
  EXPECT_GE(config.skipped_points, 1);

  BundleOptions in_bundle;
  in_bundle.check_points_in_bundle = true;
  EXPECT_TRUE(ConfigureBundle(model, in_bundle).point_used[check]);

  BundleOptions no_gcp;
  no_gcp.use_gcp_priors = false;
  EXPECT_FALSE(ConfigureBundle(model, no_gcp).point_used[control]);

  // An unregistered image takes no part, nor does its camera group if alone.
  model.images[3].registered = false;
  config = ConfigureBundle(model, BundleOptions());
  EXPECT_FALSE(config.image_used[3]);
  EXPECT_EQ(config.num_images, static_cast<int>(model.images.size()) - 1);
}

TEST(BundleConfig, IntrinsicsVaryAsTheOptionsAndTheBlockAllow) {
  const SparseModel model = SmallBlock();
  const CameraModelInfo& info = model.cameras[0].info();
  const auto index_of = [&](const std::string& name) {
    return static_cast<int>(std::find(info.param_names.begin(), info.param_names.end(), name) -
                            info.param_names.begin());
  };

  BundleConfig config = ConfigureBundle(model, BundleOptions());
  EXPECT_EQ(static_cast<int>(config.refined[0].size()), info.num_params());
  EXPECT_TRUE(config.ConstantParams(model, 0).empty());

  BundleOptions list;
  list.refine_intrinsics = IntrinsicsRefinement::kList;
  list.refine_params = {"K1", "f", "pp", "no_such_parameter"};
  config = ConfigureBundle(model, list);
  std::vector<int> expected = {index_of("f"), index_of("cx"), index_of("cy"), index_of("k1")};
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(config.refined[0], expected);
  EXPECT_EQ(static_cast<int>(config.ConstantParams(model, 0).size()), info.num_params() - 4);

  // Too few images to calibrate a lens: the focal length only.
  BundleOptions few;
  few.min_images_to_refine_intrinsics = static_cast<int>(model.images.size()) + 1;
  EXPECT_EQ(ConfigureBundle(model, few).refined[0], info.focal_params);

  // A certificate's fixed parameter is held whatever refine says.
  BundleOptions held;
  held.held_params = {{0, index_of("k2")}};
  config = ConfigureBundle(model, held);
  EXPECT_FALSE(std::binary_search(config.refined[0].begin(), config.refined[0].end(), index_of("k2")));
  EXPECT_EQ(config.ConstantParams(model, 0), std::vector<int>{index_of("k2")});
}

}  // namespace
}  // namespace aerotri
