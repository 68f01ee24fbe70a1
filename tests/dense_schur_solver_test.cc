// SPDX-License-Identifier: BSD-3-Clause
// aerotri's dense-Schur Levenberg–Marquardt against Ceres (the reference) on
// BAL-shaped problems with known truth: same optimum, residuals consistent
// with the injected noise (both bounds), held intrinsics held exactly, the
// engine used only where it applies; and the optimality-gap stopping rule on
// cost sequences whose optimum is known.
#include "libphoto/adjust/dense_schur_solver.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/adjust/schur_lm_solver.h"
#include "libphoto/base/error.h"

namespace aerotri {
namespace {

struct BalScene {
  SparseModel truth;
  SparseModel start;
  double noise_px = 0.0;
};

// A BAL-shaped block: every image its own SNAVELY camera (f, k1, k2), images
// on an arc looking at a cloud of points, Gaussian pixel noise, then every
// camera, focal length and point perturbed for the start.
BalScene MakeBalScene(std::uint32_t seed, int num_images, int num_points, double noise_px, CameraModelId model) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  BalScene scene;
  scene.noise_px = noise_px;
  SparseModel& m = scene.truth;
  for (int i = 0; i < num_images; ++i) {
    const double a = -0.6 + 1.2 * i / std::max(1, num_images - 1);
    const Eigen::Vector3d centre(12.0 * std::sin(a), 1.5 * unit(rng), -12.0 * std::cos(a));
    // Look at the origin: z axis towards it, y down.
    const Eigen::Vector3d z = (-centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d r;
    r.row(0) = x.transpose();
    r.row(1) = y.transpose();
    r.row(2) = z.transpose();
    Image image;
    image.id = i;
    image.name = "camera_" + std::to_string(i);
    image.camera = i;
    image.pose.cam_from_world = Eigen::Quaterniond(r).normalized();
    image.pose.centre_in_world = centre;
    m.images.push_back(image);
    Camera camera;
    camera.id = i;
    camera.model = model;
    if (model == CameraModelId::kSnavely) {
      camera.params = {800.0 + 40.0 * unit(rng), -0.05 + 0.01 * unit(rng), 0.004 * unit(rng)};
    } else {
      camera = Camera::Create(model, 800.0 + 40.0 * unit(rng), 1000, 800, i);
    }
    m.cameras.push_back(camera);
  }
  for (int p = 0; p < num_points; ++p) {
    Point point;
    point.id = p;
    point.position = Eigen::Vector3d(4.0 * unit(rng), 3.0 * unit(rng), 4.0 * unit(rng));
    m.points.push_back(point);
  }
  for (int p = 0; p < num_points; ++p) {
    for (int i = 0; i < num_images; ++i) {
      // Each point seen by about half the images, at least two.
      if ((p + i) % 2 == 1 && !(i < 2)) continue;
      const Eigen::Vector3d pc = m.images[i].pose.CamFromWorld(m.points[p].position);
      Observation obs;
      obs.image = i;
      obs.point = p;
      obs.xy = m.cameras[i].ImageFromCamera(pc) + noise_px * Eigen::Vector2d(gauss(rng), gauss(rng));
      m.observations.push_back(obs);
    }
  }
  scene.start = m;
  for (size_t i = 1; i < scene.start.images.size(); ++i) {
    Pose& pose = scene.start.images[i].pose;
    pose.centre_in_world += 0.05 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    pose.cam_from_world =
        (Eigen::Quaterniond(Eigen::AngleAxisd(0.005 * gauss(rng), Eigen::Vector3d::UnitZ())) * pose.cam_from_world)
            .normalized();
  }
  for (Camera& camera : scene.start.cameras) camera.params[0] *= 1.0 + 0.01 * gauss(rng);
  for (Point& point : scene.start.points) point.position += 0.03 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
  return scene;
}

BundleOptions Tight(BundleEngine engine) {
  BundleOptions o;
  o.engine = engine;
  o.function_tolerance = 1e-12;
  o.parameter_tolerance = 1e-12;
  o.gradient_tolerance = 1e-14;
  o.max_iterations = 200;
  return o;
}

TEST(DenseSchurSolver, ReachesCeresOptimumOnABalShapedBlock) {
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const BalScene scene = MakeBalScene(seed, 12, 400, 0.5, CameraModelId::kSnavely);
    SparseModel ours = scene.start;
    SparseModel ceres = scene.start;
    const BundleSummary a = AdjustBundle(&ours, Tight(BundleEngine::kAerotri));
    const BundleSummary b = AdjustBundle(&ceres, Tight(BundleEngine::kCeres));
    SCOPED_TRACE(a.BriefReport() + "\n" + b.BriefReport());
    EXPECT_EQ(a.linear_solver, "aerotri_dense_schur");
    EXPECT_EQ(b.linear_solver, "dense_schur");
    EXPECT_TRUE(a.converged);
    EXPECT_NEAR(a.initial_cost, b.initial_cost, 1e-9 * b.initial_cost);
    EXPECT_NEAR(a.final_cost, b.final_cost, 1e-7 * b.final_cost);
    // The residual matches the injected noise: 2 cost / redundancy = σ².
    const double variance = 2.0 * a.final_cost / a.redundancy;
    EXPECT_GT(variance, 0.85 * scene.noise_px * scene.noise_px);
    EXPECT_LT(variance, 1.15 * scene.noise_px * scene.noise_px);
    // Both restore the same datum, so the solutions agree coordinate by
    // coordinate, far inside what the noise moves them from the truth.
    double camera_diff = 0.0, camera_err = 0.0, focal_diff = 0.0;
    for (size_t i = 0; i < ours.images.size(); ++i) {
      camera_diff = std::max(camera_diff,
                             (ours.images[i].pose.centre_in_world - ceres.images[i].pose.centre_in_world).norm());
      camera_err = std::max(camera_err, (ours.images[i].pose.centre_in_world -
                                         scene.truth.images[i].pose.centre_in_world).norm());
      focal_diff = std::max(focal_diff, std::abs(ours.cameras[i].params[0] - ceres.cameras[i].params[0]));
    }
    EXPECT_LT(camera_diff, 1e-5);
    EXPECT_GT(camera_err, 1e-4);  // the noise moves them
    EXPECT_LT(focal_diff, 1e-3);
  }
}

TEST(DenseSchurSolver, HeldIntrinsicsStayExactlyAndOtherModelsWork) {
  const BalScene scene = MakeBalScene(7, 8, 300, 0.3, CameraModelId::kBrown);
  SparseModel ours = scene.start;
  SparseModel ceres = scene.start;
  BundleOptions options = Tight(BundleEngine::kAerotri);
  options.refine_intrinsics = IntrinsicsRefinement::kFocal;
  const BundleSummary a = AdjustBundle(&ours, options);
  options.engine = BundleEngine::kCeres;
  const BundleSummary b = AdjustBundle(&ceres, options);
  SCOPED_TRACE(a.BriefReport() + "\n" + b.BriefReport());
  EXPECT_EQ(a.linear_solver, "aerotri_dense_schur");
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-7 * b.final_cost);
  for (size_t c = 0; c < ours.cameras.size(); ++c) {
    for (size_t k = 1; k < ours.cameras[c].params.size(); ++k) {
      EXPECT_EQ(ours.cameras[c].params[k], scene.start.cameras[c].params[k]) << "camera " << c << " param " << k;
    }
    EXPECT_NE(ours.cameras[c].params[0], scene.start.cameras[c].params[0]);
    EXPECT_NEAR(ours.cameras[c].params[0], ceres.cameras[c].params[0], 1e-4);
  }
}

// The BAL engine takes free networks of merged blocks without a loss; the
// general Schur engine (schur_lm_solver.h) takes the rest, its reduced
// system dense or, beyond kMaxSchurLmDenseSize, sparse; Ceres where another
// linear solver is asked for.
TEST(DenseSchurSolver, UsedOnlyWhereItApplies) {
  BalScene scene = MakeBalScene(5, 6, 120, 0.5, CameraModelId::kSnavely);
  // A robust loss: the general engine; Ceres when asked for.
  {
    SparseModel m = scene.start;
    BundleOptions o;
    o.loss = LossType::kHuber;
    EXPECT_EQ(AdjustBundle(&m, o).linear_solver, "aerotri_schur_lm");
    o.engine = BundleEngine::kCeres;
    SparseModel m2 = scene.start;
    EXPECT_EQ(AdjustBundle(&m2, o).linear_solver, "dense_schur");
  }
  // GPS priors hold the datum: the general engine.
  {
    SparseModel m = scene.start;
    for (size_t i = 0; i < m.images.size(); ++i) {
      m.images[i].gps_prior = PositionPrior{scene.truth.images[i].pose.centre_in_world, 1.0, 1.0, std::nullopt};
    }
    EXPECT_EQ(AdjustBundle(&m, BundleOptions{}).linear_solver, "aerotri_schur_lm");
  }
  // A camera group shared by two images: the general engine.
  {
    SparseModel m = scene.start;
    m.images[1].camera = 0;
    EXPECT_EQ(AdjustBundle(&m, BundleOptions{}).linear_solver, "aerotri_schur_lm");
  }
  // A camera system too large to hold dense for the BAL engine: the general one.
  {
    const BalScene big = MakeBalScene(6, kMaxDenseSchurSize / 9 + 2, 60, 0.5, CameraModelId::kSnavely);
    SparseModel m = big.start;
    BundleOptions o;
    o.max_iterations = 1;
    EXPECT_EQ(AdjustBundle(&m, o).linear_solver, "aerotri_schur_lm");
  }
  // Beyond the dense size: the same engine, its reduced system held sparse.
  {
    const BalScene big = MakeBalScene(6, kMaxSchurLmDenseSize / 9 + 2, 60, 0.5, CameraModelId::kSnavely);
    SparseModel m = big.start;
    BundleOptions o;
    o.max_iterations = 1;
    EXPECT_EQ(AdjustBundle(&m, o).linear_solver, "aerotri_schur_lm_sparse");
  }
  // Another linear solver asked for: Ceres, and the aerotri engine asked for
  // with it says why not.
  {
    SparseModel m = scene.start;
    BundleOptions o;
    o.max_iterations = 1;
    o.linear_solver = LinearSolverChoice::kIterativeSchur;
    EXPECT_EQ(AdjustBundle(&m, o).linear_solver, "iterative_schur");
    o.engine = BundleEngine::kAerotri;
    SparseModel m2 = scene.start;
    try {
      AdjustBundle(&m2, o);
      ADD_FAILURE() << "the aerotri engine took a linear solver it does not have";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("linear solver"), std::string::npos) << e.what();
    }
  }
}

TEST(DenseSchurSolver, PointOnACameraPlaneAtTheStartIsAFailureNotACrash) {
  BalScene scene = MakeBalScene(9, 5, 80, 0.5, CameraModelId::kSnavely);
  SparseModel m = scene.start;
  const int p = m.observations[0].point;
  const Image& image = m.images[m.observations[0].image];
  // Put the point in the camera's z = 0 plane, beside the centre.
  m.points[p].position = image.pose.centre_in_world + image.pose.cam_from_world.conjugate() * Eigen::Vector3d(1, 0, 0);
  const BundleSummary s = AdjustBundle(&m, Tight(BundleEngine::kAerotri));
  EXPECT_NE(s.termination.find("FAILURE"), std::string::npos) << s.termination;
  EXPECT_FALSE(s.converged);
}

// Costs c* + A ρᵏ: the rule stops once the estimated gap is below the
// tolerance, and the true gap is then within a small factor of it.
TEST(BundleStopRule, StopsWithinTheGapOnGeometricConvergence) {
  for (double rho : {0.2, 0.5, 0.8, 0.9}) {
    const double optimum = 1000.0, tolerance = 1e-3;
    BundleStopRule rule(tolerance);
    int stopped_at = -1;
    for (int k = 0; k < 400 && stopped_at < 0; ++k) {
      if (rule.Accepted(optimum + 500.0 * std::pow(rho, k))) stopped_at = k;
    }
    ASSERT_GE(stopped_at, 0) << rho;
    const double true_gap = 500.0 * std::pow(rho, stopped_at) / optimum;
    EXPECT_LE(true_gap, tolerance) << "rho " << rho;
    // Not far past it either: one or two steps more than needed.
    EXPECT_GT(true_gap, tolerance * std::pow(rho, 3) * 0.5) << "rho " << rho;
  }
}

// A decrease that shrinks fast once in a slow tail (as on BAL's Ladybug):
// judged on that one ratio the gap would look tiny; the slower of the last
// two ratios keeps the rule going until the true gap is small.
TEST(BundleStopRule, OneFastStepDoesNotStopASlowTail) {
  const double optimum = 10000.0, tolerance = 5e-4;
  std::vector<double> gaps = {100.0};
  while (gaps.back() > 50.0) gaps.push_back(0.9 * gaps.back());
  const double last_decrease = gaps[gaps.size() - 2] - gaps.back();
  gaps.push_back(gaps.back() - 0.3 * last_decrease);
  for (int k = 0; k < 80; ++k) gaps.push_back(0.9 * gaps.back());
  BundleStopRule rule(tolerance);
  size_t stopped_at = gaps.size();
  for (size_t k = 0; k < gaps.size() && stopped_at == gaps.size(); ++k) {
    if (rule.Accepted(optimum + gaps[k])) stopped_at = k;
  }
  ASSERT_LT(stopped_at, gaps.size());
  EXPECT_LE(gaps[stopped_at] / optimum, 2 * tolerance) << "stopped at " << stopped_at;
  BundleStopRule off(0.0);
  for (double g : gaps) EXPECT_FALSE(off.Accepted(optimum + g));
}

}  // namespace
}  // namespace aerotri
