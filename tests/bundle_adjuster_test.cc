// SPDX-License-Identifier: BSD-3-Clause
// The bundle adjuster on synthetic surveys with known truth: errors must be
// consistent with the injected noise (both bounds), the gauge must be what the
// summary says, outliers must be found, options must validate.
#include "libphoto/adjust/bundle_adjuster.h"

#include <gtest/gtest.h>

#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

SyntheticSurveyOptions SmallSurvey(std::uint32_t seed) {
  SyntheticSurveyOptions o;
  o.seed = seed;
  o.area_width_m = 160.0;
  o.area_height_m = 110.0;
  o.num_tie_points = 1200;
  o.pixel_noise_px = 0.5;
  return o;
}

std::vector<Eigen::Vector3d> Centres(const SparseModel& m) {
  std::vector<Eigen::Vector3d> c;
  for (const Image& image : m.images) c.push_back(image.pose.centre_in_world);
  return c;
}

std::vector<Eigen::Vector3d> Positions(const SparseModel& m) {
  std::vector<Eigen::Vector3d> c;
  for (const Point& p : m.points) {
    if (p.role != PointRole::kCheck) c.push_back(p.position);
  }
  return c;
}

TEST(BundleAdjuster, RecoversASyntheticSurveyToTheNoiseLevel) {
  const SyntheticSurveyOptions o = SmallSurvey(11);
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SparseModel model = survey.observed;
  std::mt19937 rng(11);
  testing::Perturb(&model, rng, 0.5, 0.3, 0.3, 0.01);
  for (Camera& c : model.cameras) {
    for (int i = 3; i < 8; ++i) c.params[i] = 0.0;  // distortion unknown at start
  }
  const Pose initial_a = model.images[0].pose;

  BundleOptions options;
  const BundleSummary summary = AdjustBundle(&model, options);
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_TRUE(summary.converged);
  EXPECT_EQ(summary.num_images, static_cast<int>(model.images.size()));

  // Each observation's error is 2D Gaussian with sigma per axis: the RMS of
  // its norm is sigma * sqrt(2) (less the few degrees of freedom fitted).
  const double expected_rms = o.pixel_noise_px * std::sqrt(2.0);
  EXPECT_GT(summary.final_rms_px, 0.9 * expected_rms);
  EXPECT_LT(summary.final_rms_px, 1.05 * expected_rms);
  EXPECT_GT(summary.initial_rms_px, 10.0 * expected_rms);

  // Gauge: no priors, so image 0's pose is back at its initial value exactly.
  EXPECT_NE(summary.gauge.find("no priors"), std::string::npos);
  EXPECT_LT((model.images[0].pose.centre_in_world - initial_a.centre_in_world).norm(), 1e-9);
  EXPECT_LT(model.images[0].pose.cam_from_world.angularDistance(initial_a.cam_from_world), 1e-9);

  // Shape: up to a similarity, cameras and points land where truth has them.
  // 0.5 px at a GSD of ~2.7 cm is ~1.3 cm per ray; cameras, seen by hundreds
  // of rays, do better; points, seen by few, about that.
  const double camera_rms = testing::AlignedRms(Centres(model), Centres(survey.truth));
  const double point_rms = testing::AlignedRms(Positions(model), Positions(survey.truth));
  EXPECT_GT(camera_rms, 1e-4);
  EXPECT_LT(camera_rms, 0.05);
  EXPECT_GT(point_rms, 0.002);
  EXPECT_LT(point_rms, 0.08);
  // Self-calibration recovers k1 close to the truth (-0.08).
  EXPECT_NEAR(model.cameras[0].params[3], o.brown_params[3], 0.01);
}

TEST(BundleAdjuster, GpsPriorsAnchorTheDatum) {
  const SyntheticSurveyOptions o = SmallSurvey(12);
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SparseModel model = survey.observed;
  std::mt19937 rng(12);
  testing::AddGpsPriors(&model, survey.truth, rng, 0.05, 0.1);
  testing::Perturb(&model, rng, 1.0, 0.3, 0.5, 0.0);
  BundleOptions options;
  options.refine_intrinsics = IntrinsicsRefinement::kNone;
  const BundleSummary summary = AdjustBundle(&model, options);
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_NE(summary.gauge.find("datum from priors"), std::string::npos);
  EXPECT_EQ(summary.num_gps_priors, static_cast<int>(model.images.size()));
  // Absolute (not aligned) camera error is at the GPS noise level averaged
  // over many images, not metres.
  double sum = 0.0;
  for (size_t i = 0; i < model.images.size(); ++i) {
    sum += (model.images[i].pose.centre_in_world - survey.truth.images[i].pose.centre_in_world)
               .squaredNorm();
  }
  const double rms = std::sqrt(sum / model.images.size());
  EXPECT_GT(rms, 0.002);
  EXPECT_LT(rms, 0.12);
}

// A local adjustment (the mapper's, after each registration): one image
// displaced from the truth varies, every other is held. The held poses must
// not move at all (they hold the datum: no gauge is restored), and the
// displaced image must come back to the truth within what its few hundred
// 0.5 px rays allow.
TEST(BundleAdjuster, HeldPosesStayPutAndHoldTheDatumOfALocalAdjustment) {
  const SyntheticSurveyOptions o = SmallSurvey(15);
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SparseModel model = survey.observed;
  for (size_t i = 0; i < model.images.size(); ++i) model.images[i].pose = survey.truth.images[i].pose;
  const int moved = static_cast<int>(model.images.size()) / 2;
  Pose& pose = model.images[moved].pose;
  pose.centre_in_world += Eigen::Vector3d(0.6, -0.4, 0.5);
  pose.cam_from_world = (pose.cam_from_world * Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX())).normalized();
  const SparseModel before = model;

  BundleOptions options;
  options.refine_intrinsics = IntrinsicsRefinement::kNone;
  options.loss = LossType::kHuber;
  options.held_poses.assign(model.images.size(), 1);
  options.held_poses[moved] = 0;
  const BundleSummary summary = AdjustBundle(&model, options);
  SCOPED_TRACE(summary.BriefReport());
  EXPECT_NE(summary.gauge.find("held fixed (a local adjustment)"), std::string::npos);
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (static_cast<int>(i) == moved) continue;
    EXPECT_EQ(model.images[i].pose.centre_in_world, before.images[i].pose.centre_in_world) << i;
    EXPECT_EQ(model.images[i].pose.cam_from_world.coeffs(), before.images[i].pose.cam_from_world.coeffs()) << i;
  }
  const double error = (model.images[moved].pose.centre_in_world -
                        survey.truth.images[moved].pose.centre_in_world).norm();
  EXPECT_GT(error, 1e-5);  // the pixel noise leaves some
  EXPECT_LT(error, 0.05);  // of the 0.88 m displacement
  EXPECT_LT(model.images[moved].pose.cam_from_world.angularDistance(survey.truth.images[moved].pose.cam_from_world),
            0.1 * 0.01);
  EXPECT_LT(summary.final_rms_px, 1.1 * o.pixel_noise_px * std::sqrt(2.0));

  // One held image cannot hold scale: the usual gauge is chosen instead.
  SparseModel single = before;
  options.held_poses.assign(single.images.size(), 0);
  options.held_poses[0] = 1;
  const BundleSummary one = AdjustBundle(&single, options);
  EXPECT_EQ(one.gauge.find("held fixed (a local adjustment)"), std::string::npos) << one.gauge;
}

TEST(BundleAdjuster, RejectsGrossOutliersAndSolvesAgain) {
  const SyntheticSurveyOptions o = SmallSurvey(13);
  SparseModel model = MakeSyntheticSurvey(o).observed;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int injected = 0;
  for (Observation& obs : model.observations) {
    if (u(rng) < 0.01) {
      obs.xy += Eigen::Vector2d(40.0 + 40.0 * u(rng), -30.0 - 30.0 * u(rng));
      ++injected;
    }
  }
  BundleOptions options;
  options.loss = LossType::kCauchy;
  options.loss_scale_px = 2.0;
  options.outlier_threshold_px = 4.0;
  options.refine_intrinsics = IntrinsicsRefinement::kFocal;
  const BundleSummary summary = AdjustBundle(&model, options);
  SCOPED_TRACE(summary.BriefReport());
  ASSERT_GT(injected, 50);
  // Every injected outlier (> 50 px) goes, and almost nothing else does
  // (a 0.5 px Gaussian exceeds 4 px with probability ~1e-14).
  EXPECT_GE(summary.outliers_removed, injected - injected / 50);
  EXPECT_LE(summary.outliers_removed, injected + 2);
  EXPECT_GE(summary.outlier_rounds, 1);
  EXPECT_LT(summary.final_rms_px, 1.05 * o.pixel_noise_px * std::sqrt(2.0));
}

// The robust loss screens and least squares estimates: with blunders among
// 0.5 px noise (half the residuals' Huber weight below one), the result is
// the least-squares estimate of the observations without the blunders, not
// the Huber estimate, and every solve after the screening converges.
TEST(BundleAdjuster, ScreeningThenLeastSquaresGivesTheCleanLeastSquaresEstimate) {
  const SyntheticSurveyOptions o = SmallSurvey(16);
  const SparseModel clean = MakeSyntheticSurvey(o).observed;
  SparseModel blundered = clean;
  std::mt19937 rng(16);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Observation> kept;
  int injected = 0;
  for (Observation& obs : blundered.observations) {
    if (blundered.points[obs.point].role == PointRole::kTie && u(rng) < 0.01) {
      obs.xy += Eigen::Vector2d(40.0 + 40.0 * u(rng), 30.0 * u(rng));
      ++injected;
    } else {
      kept.push_back(obs);
    }
  }
  ASSERT_GT(injected, 50);
  SparseModel screened_truth = clean;
  screened_truth.observations = kept;  // what a perfect screening keeps

  BundleOptions options;
  options.loss = LossType::kHuber;
  options.loss_scale_px = 1.0;
  options.outlier_threshold_px = 4.0;
  options.refine_intrinsics = IntrinsicsRefinement::kFocal;
  options.function_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  options.max_iterations = 200;

  BundleOptions screen = options;
  screen.least_squares_after_screening = true;
  SparseModel a = blundered;
  const BundleSummary sa = AdjustBundle(&a, screen);
  SCOPED_TRACE(sa.BriefReport());

  BundleOptions plain = options;
  plain.loss = LossType::kNone;
  SparseModel b = screened_truth;
  const BundleSummary sb = AdjustBundle(&b, plain);

  SparseModel c = blundered;
  const BundleSummary sc = AdjustBundle(&c, options);  // Huber throughout

  ASSERT_GE(sa.solves.size(), 2u);
  EXPECT_EQ(sa.solves.front().kind, "robust screening (huber)");
  const std::string& last = sa.solves.back().kind;
  EXPECT_TRUE(last == "least squares" || last.rfind("outlier round", 0) == 0) << last;
  EXPECT_TRUE(sa.converged) << sa.termination;
  EXPECT_EQ(sa.outliers_removed, injected);
  EXPECT_EQ(sc.outliers_removed, injected);

  double to_ls = 0.0, huber_to_ls = 0.0;
  const std::vector<Eigen::Vector3d> ca = Centres(a), cb = Centres(b), cc = Centres(c);
  for (size_t i = 0; i < ca.size(); ++i) {
    to_ls = std::max(to_ls, (ca[i] - cb[i]).norm());
    huber_to_ls = std::max(huber_to_ls, (cc[i] - cb[i]).norm());
  }
  std::printf("screened vs clean least squares %.3g m; Huber vs clean least squares %.3g m\n", to_ls,
              huber_to_ls);
  // The Huber estimate differs from least squares by a fraction of the
  // cameras' precision; the screened one by the solver's tolerance.
  EXPECT_GT(huber_to_ls, 1e-4);
  EXPECT_LT(to_ls, 0.01 * huber_to_ls);
  EXPECT_NEAR(sa.final_cost, sb.final_cost, 1e-6 * sb.final_cost);
}

TEST(BundleAdjuster, IntrinsicsRefinementChoiceIsRespected) {
  const SyntheticSurveyOptions o = SmallSurvey(14);
  for (IntrinsicsRefinement r : {IntrinsicsRefinement::kNone, IntrinsicsRefinement::kFocal,
                                 IntrinsicsRefinement::kList}) {
    SparseModel model = MakeSyntheticSurvey(o).observed;
    std::mt19937 rng(14);
    testing::Perturb(&model, rng, 0.2, 0.1, 0.1, 0.005);
    const std::vector<double> before = model.cameras[0].params;
    BundleOptions options;
    options.refine_intrinsics = r;
    options.refine_params = {"k1", "p2"};
    options.max_iterations = 10;
    AdjustBundle(&model, options);
    const std::vector<double>& after = model.cameras[0].params;
    for (int i = 0; i < 8; ++i) {
      const bool refined = (r == IntrinsicsRefinement::kFocal && i == 0) ||
                           (r == IntrinsicsRefinement::kList && (i == 3 || i == 7));
      if (refined) {
        EXPECT_NE(after[i], before[i]) << "parameter " << i << " should move";
      } else {
        EXPECT_EQ(after[i], before[i]) << "parameter " << i << " should stay";
      }
    }
  }
}

TEST(BundleAdjuster, RobustLossesAllConvergeOnCleanData) {
  const SyntheticSurveyOptions o = SmallSurvey(15);
  for (LossType loss : {LossType::kNone, LossType::kHuber, LossType::kCauchy, LossType::kTukey}) {
    SparseModel model = MakeSyntheticSurvey(o).observed;
    std::mt19937 rng(15);
    testing::Perturb(&model, rng, 0.05, 0.02, 0.03, 0.0);
    BundleOptions options;
    options.loss = loss;
    options.loss_scale_px = 3.0;
    options.refine_intrinsics = IntrinsicsRefinement::kNone;
    const BundleSummary summary = AdjustBundle(&model, options);
    EXPECT_LT(summary.final_rms_px, 1.05 * o.pixel_noise_px * std::sqrt(2.0)) << ToString(loss);
    EXPECT_GT(summary.final_rms_px, 0.9 * o.pixel_noise_px * std::sqrt(2.0)) << ToString(loss);
  }
}

TEST(BundleAdjuster, ReportsWeakImagesAndBehindCameraObservations) {
  const SyntheticSurveyOptions o = SmallSurvey(16);
  SparseModel model = MakeSyntheticSurvey(o).observed;
  // Keep only 5 observations of the last image.
  const int last = static_cast<int>(model.images.size()) - 1;
  std::vector<Observation> kept;
  int seen = 0;
  for (const Observation& obs : model.observations) {
    if (obs.image == last && ++seen > 5) continue;
    kept.push_back(obs);
  }
  model.observations.swap(kept);
  // Move one point behind the camera that sees it.
  const Observation& first = model.observations.front();
  const Pose& pose = model.images[first.image].pose;
  model.points[first.point].position =
      pose.centre_in_world + pose.cam_from_world.conjugate() * Eigen::Vector3d(0.0, 0.0, -20.0);
  BundleOptions options;
  options.max_iterations = 0;
  const BundleSummary summary = AdjustBundle(&model, options);
  EXPECT_GE(summary.num_behind_camera_initial, 1);
  ASSERT_FALSE(summary.weak_images.empty());
  EXPECT_EQ(summary.weak_images.back().name, model.images[last].name);
  EXPECT_EQ(summary.weak_images.back().observations, 5);
  EXPECT_NE(summary.BriefReport().find("behind their camera"), std::string::npos);
}

TEST(BundleAdjuster, FocalPriorHoldsFocalLengthOverFlatGround) {
  // Nadir photos of flat ground with GPS observe focal length over depth
  // only: started 15 % off, the focal length stays off without a prior and
  // comes back with the EXIF prior.
  SyntheticSurveyOptions o = SmallSurvey(17);
  o.attitude_sigma_deg = 0.0;
  // No lens distortion: distortion, seen at other radii when the focal length
  // changes, would otherwise tell focal length and depth apart.
  for (int i = 3; i < 8; ++i) o.brown_params[i] = 0.0;
  SyntheticSurvey survey = MakeSyntheticSurvey(o);
  // Level ground (every point at height 0) under a level flight (every
  // camera at 80 m), observations re-projected exactly.
  for (Point& p : survey.truth.points) p.position.z() = 0.0;
  for (Image& image : survey.truth.images) image.pose.centre_in_world.z() = 80.0;
  for (Observation& obs : survey.truth.observations) {
    const Image& image = survey.truth.images[obs.image];
    obs.xy = survey.truth.cameras[0].ImageFromCamera(image.pose.CamFromWorld(survey.truth.points[obs.point].position));
  }
  auto run = [&](bool prior) {
    SparseModel model = survey.truth;
    for (size_t i = 0; i < model.images.size(); ++i) {
      model.images[i].gps_prior = PositionPrior{survey.truth.images[i].pose.centre_in_world, 0.5, 0.5};
    }
    // Start in the other solution of the ambiguity: focal length and depth
    // both 15 % larger (the ground lower, the same images).
    model.cameras[0].params[0] *= 1.15;
    const double camera_height = survey.truth.images[0].pose.centre_in_world.z();
    for (Point& p : model.points) {
      p.position.z() = camera_height - 1.15 * (camera_height - p.position.z());
    }
    BundleOptions options;
    options.refine_intrinsics = IntrinsicsRefinement::kFocal;
    if (prior) options.focal_prior_px = {o.brown_params[0]};
    AdjustBundle(&model, options);
    return model.cameras[0].params[0] / o.brown_params[0] - 1.0;
  };
  EXPECT_GT(std::abs(run(false)), 0.05);
  EXPECT_LT(std::abs(run(true)), 0.01);
}

// A point seen along one ray only (twice from the same photo: its depth is
// anything) tells the cameras nothing. The posterior precision is still
// computed, the cameras' covariance is the same as without the point, and
// the point is counted as undetermined, not given a covariance. (On a real
// block one such point used to void the precision of the whole survey and,
// with it, the check that the block determines its focal length.)
TEST(BundleAdjuster, APointAlongOneRayLeavesTheCamerasPrecisionAsItWas) {
  const SyntheticSurveyOptions o = SmallSurvey(21);
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SparseModel model = survey.observed;
  for (size_t i = 0; i < model.images.size(); ++i) {
    model.images[i].gps_prior = PositionPrior{survey.truth.images[i].pose.centre_in_world, 0.05, 0.1};
  }
  BundleOptions options;
  options.refine_intrinsics = IntrinsicsRefinement::kNone;
  AdjustBundle(&model, options);  // to the optimum, then the precision there
  options.compute_precision = true;
  SparseModel plain = model;
  const BundleSummary without = AdjustBundle(&plain, options);
  ASSERT_TRUE(without.precision.computed) << without.precision.note;
  EXPECT_EQ(without.precision.undetermined_points, 0);

  SparseModel with = model;
  const Image& image = with.images[0];
  const Eigen::Vector3d ray = image.pose.cam_from_world.conjugate() * Eigen::Vector3d(0.05, -0.02, 1.0);
  Point lone;
  lone.id = 999999;
  lone.position = image.pose.centre_in_world + 60.0 * ray;
  with.points.push_back(lone);
  const int p = static_cast<int>(with.points.size()) - 1;
  const Eigen::Vector2d xy = with.cameras[image.camera].ImageFromCamera(image.pose.CamFromWorld(lone.position));
  with.observations.push_back({0, p, xy});
  with.observations.push_back({0, p, xy});
  const BundleSummary summary = AdjustBundle(&with, options);
  ASSERT_TRUE(summary.precision.computed) << summary.precision.note;
  EXPECT_EQ(summary.precision.undetermined_points, 1);
  EXPECT_EQ(summary.precision.points.size(), without.precision.points.size());
  EXPECT_EQ(summary.precision.ForPoint(p), nullptr);
  ASSERT_EQ(summary.precision.images.size(), without.precision.images.size());
  double worst = 0.0;
  for (size_t k = 0; k < summary.precision.images.size(); ++k) {
    const ImagePrecision& a = summary.precision.images[k];
    const ImagePrecision& b = *without.precision.ForImage(a.image);
    worst = std::max(worst, (a.centre_cov - b.centre_cov).norm() / b.centre_cov.norm());
    worst = std::max(worst, (a.rotation_cov - b.rotation_cov).norm() / b.rotation_cov.norm());
  }
  // Both are scaled by their sigma0²: the two zero residuals the point adds
  // beyond its two determined coordinates change the redundancy by 1 in
  // thousands; nothing else may differ.
  const double redundancy_share = 2.0 / (2.0 * static_cast<double>(with.observations.size()));
  EXPECT_LT(worst, 2.0 * redundancy_share) << worst;
  EXPECT_GT(without.precision.images[0].centre_cov(0, 0), 0.0);
}

// The intrinsics' covariance: taken from the posterior precision pass where
// it runs, computed by a pass of its own where it does not. Both are
// (JᵀJ)⁻¹ at the same optimum and weights: the same sigmas and
// correlations; and the focal length's sigma is what 0.5 px over a block
// this size allows, not zero and not metres.
TEST(BundleAdjuster, IntrinsicsCovarianceFromThePrecisionPassEqualsItsOwnPass) {
  const SyntheticSurveyOptions o = SmallSurvey(23);
  const SyntheticSurvey survey = MakeSyntheticSurvey(o);
  SparseModel model = survey.observed;
  std::mt19937 rng(23);
  testing::AddGpsPriors(&model, survey.truth, rng, 0.05, 0.1);
  BundleOptions options;
  options.compute_intrinsics_covariance = true;
  AdjustBundle(&model, options);  // to the optimum, then both from there
  SparseModel a = model, b = model;
  options.compute_precision = true;
  const BundleSummary with_pass = AdjustBundle(&a, options);
  options.compute_precision = false;
  const BundleSummary own_pass = AdjustBundle(&b, options);
  ASSERT_TRUE(with_pass.precision.computed) << with_pass.precision.note;
  ASSERT_EQ(with_pass.intrinsics_precision.size(), 1u) << with_pass.covariance_note;
  ASSERT_EQ(own_pass.intrinsics_precision.size(), 1u) << own_pass.covariance_note;
  const IntrinsicsPrecision &p = with_pass.intrinsics_precision[0], &q = own_pass.intrinsics_precision[0];
  ASSERT_EQ(p.names, q.names);
  for (size_t k = 0; k < p.sigmas.size(); ++k) {
    EXPECT_NEAR(p.sigmas[k], q.sigmas[k], 1e-7 * q.sigmas[k]) << p.names[k];
    for (size_t l = 0; l < p.sigmas.size(); ++l) EXPECT_NEAR(p.correlation[k][l], q.correlation[k][l], 1e-7);
  }
  EXPECT_NEAR(p.focal_height_correlation_max, q.focal_height_correlation_max, 1e-7);
  ASSERT_EQ(p.names[0], "f");
  EXPECT_GT(p.sigmas[0], 0.01);
  EXPECT_LT(p.sigmas[0], 10.0);
}

TEST(BundleOptions, ValidateNamesTheOption) {
  BundleOptions options;
  std::string error;
  EXPECT_TRUE(options.Validate(&error));
  options.loss_scale_px = -1.0;
  EXPECT_FALSE(options.Validate(&error));
  EXPECT_NE(error.find("loss scale"), std::string::npos);
  options = BundleOptions();
  options.refine_intrinsics = IntrinsicsRefinement::kList;
  EXPECT_FALSE(options.Validate(&error));
  SparseModel empty;
  options = BundleOptions();
  options.observation_sigma_px = 0.0;
  EXPECT_THROW(AdjustBundle(&empty, options), InvalidArgument);
}

TEST(BundleOptions, ParsersAcceptDocumentedNames) {
  std::vector<std::string> params;
  EXPECT_EQ(ParseIntrinsicsRefinement("focal,pp", &params),
            IntrinsicsRefinement::kFocalPrincipalPoint);
  EXPECT_EQ(ParseIntrinsicsRefinement("f,k1,k2", &params), IntrinsicsRefinement::kList);
  EXPECT_EQ(params.size(), 3u);
  EXPECT_FALSE(ParseIntrinsicsRefinement("f,k9", &params).has_value());
  EXPECT_EQ(ParseLossType("Huber"), LossType::kHuber);
  EXPECT_FALSE(ParseLossType("l1").has_value());
  EXPECT_EQ(ParseLinearSolver("iterative_schur"), LinearSolverChoice::kIterativeSchur);
}

}  // namespace
}  // namespace aerotri
