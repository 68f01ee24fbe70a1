// SPDX-License-Identifier: BSD-3-Clause
// The reprojection cost's analytic Jacobians against Ceres Jets (autodiff of
// the same residual) and against central differences (ceres::GradientChecker
// on the quaternion manifold), with a negative control the checker must catch.
#include <ceres/autodiff_cost_function.h>
#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <random>

#include "libphoto/adjust/position_prior_cost.h"
#include "libphoto/adjust/reprojection_cost.h"
#include "camera_models/camera.h"
#include "tests/jacobian_checks.h"

namespace aerotri {
namespace {

// Autodiff and analytic Jacobians are both exact: only rounding separates them.
constexpr double kJetTolerance = 1e-9;
// GradientChecker's central differences (relative step 1e-6) agree to ~1e-7.
constexpr double kNumericTolerance = 1e-6;

template <typename Model>
std::vector<double> Intrinsics();
template <>
std::vector<double> Intrinsics<PinholeModel>() { return {2900.0, 2000.0, 1500.0}; }
template <>
std::vector<double> Intrinsics<BrownModel>() {
  return {2900.0, 2000.0, 1500.0, -0.1, 0.07, -0.02, 0.001, -0.0008};
}
template <>
std::vector<double> Intrinsics<SnavelyModel>() { return {2900.0, -0.1, 0.07}; }

struct Scene {
  std::array<double, 4> q;
  Eigen::Vector3d centre;
  Eigen::Vector3d point;
};

Scene RandomScene(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Scene s;
  const Eigen::Quaterniond q = Eigen::Quaterniond(
      Eigen::AngleAxisd(0.3 * g(rng), Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized()));
  s.q = {q.w(), q.x(), q.y(), q.z()};
  s.centre = Eigen::Vector3d(g(rng), g(rng), g(rng));
  // A point 20-40 m in front of the camera, within the field of view.
  const Eigen::Vector3d in_cam(4.0 * g(rng), 3.0 * g(rng), 30.0 + 5.0 * g(rng));
  s.point = q.conjugate() * in_cam + s.centre;
  return s;
}

template <typename Model>
class ReprojectionCostTest : public ::testing::Test {
 protected:
  void SetUp() override { rng_.seed(42); }
  std::mt19937 rng_;
};
using ModelTypes = ::testing::Types<PinholeModel, BrownModel, SnavelyModel>;
TYPED_TEST_SUITE(ReprojectionCostTest, ModelTypes);

TYPED_TEST(ReprojectionCostTest, AnalyticJacobiansMatchAutodiff) {
  using Model = TypeParam;
  constexpr int N = Model::kNumParams;
  auto k = Intrinsics<Model>();
  for (int trial = 0; trial < 50; ++trial) {
    Scene s = RandomScene(this->rng_);
    const Eigen::Vector2d observed(1234.5, 876.5);
    ReprojectionCost<Model> analytic(observed, 0.7);
    ceres::AutoDiffCostFunction<ReprojectionResidualFunctor<Model>, 2, 4, 3, 3, N> autodiff(
        new ReprojectionResidualFunctor<Model>{observed, 0.7});
    const double* params[] = {s.q.data(), s.centre.data(), s.point.data(), k.data()};
    Eigen::Matrix<double, 2, 4, Eigen::RowMajor> a0, b0;
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> a1, b1, a2, b2;
    Eigen::Matrix<double, 2, N, Eigen::RowMajor> a3, b3;
    double* ja[] = {a0.data(), a1.data(), a2.data(), a3.data()};
    double* jb[] = {b0.data(), b1.data(), b2.data(), b3.data()};
    Eigen::Vector2d ra, rb;
    ASSERT_TRUE(analytic.Evaluate(params, ra.data(), ja));
    ASSERT_TRUE(autodiff.Evaluate(params, rb.data(), jb));
    EXPECT_LT((ra - rb).norm(), 1e-9);
    EXPECT_LT(testing::WorstRelativeError(a0, b0), kJetTolerance) << "rotation";
    EXPECT_LT(testing::WorstRelativeError(a1, b1), kJetTolerance) << "centre";
    EXPECT_LT(testing::WorstRelativeError(a2, b2), kJetTolerance) << "point";
    EXPECT_LT(testing::WorstRelativeError(a3, b3), kJetTolerance) << "intrinsics";
  }
}

TYPED_TEST(ReprojectionCostTest, MergedCameraBlockMatchesSeparateBlocks) {
  using Model = TypeParam;
  constexpr int N = Model::kNumParams;
  auto k = Intrinsics<Model>();
  Scene s = RandomScene(this->rng_);
  const Eigen::Vector2d observed(100.0, -50.0);
  std::vector<double> camera(s.q.begin(), s.q.end());
  camera.insert(camera.end(), s.centre.data(), s.centre.data() + 3);
  camera.insert(camera.end(), k.begin(), k.end());
  ReprojectionCost<Model> separate(observed);
  ReprojectionCostMergedCamera<Model> merged(observed);
  const double* sp[] = {s.q.data(), s.centre.data(), s.point.data(), k.data()};
  const double* mp[] = {camera.data(), s.point.data()};
  Eigen::Matrix<double, 2, 4, Eigen::RowMajor> j0;
  Eigen::Matrix<double, 2, 3, Eigen::RowMajor> j1, j2, m1;
  Eigen::Matrix<double, 2, N, Eigen::RowMajor> j3;
  Eigen::Matrix<double, 2, 7 + N, Eigen::RowMajor> m0;
  double* js[] = {j0.data(), j1.data(), j2.data(), j3.data()};
  double* jm[] = {m0.data(), m1.data()};
  Eigen::Vector2d rs, rm;
  ASSERT_TRUE(separate.Evaluate(sp, rs.data(), js));
  ASSERT_TRUE(merged.Evaluate(mp, rm.data(), jm));
  EXPECT_EQ(rs, rm);
  EXPECT_EQ(Eigen::MatrixXd(m0.template leftCols<4>()), Eigen::MatrixXd(j0));
  EXPECT_EQ(Eigen::MatrixXd(m0.template middleCols<3>(4)), Eigen::MatrixXd(j1));
  EXPECT_EQ(Eigen::MatrixXd(m0.rightCols(N)), Eigen::MatrixXd(j3));
  EXPECT_EQ(Eigen::MatrixXd(m1), Eigen::MatrixXd(j2));
}

// Wraps a cost function and corrupts one Jacobian entry: the negative control.
class WrongJacobian final : public ceres::CostFunction {
 public:
  explicit WrongJacobian(ceres::CostFunction* inner) : inner_(inner) {
    set_num_residuals(inner->num_residuals());
    *mutable_parameter_block_sizes() = inner->parameter_block_sizes();
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    if (!inner_->Evaluate(parameters, residuals, jacobians)) return false;
    if (jacobians && jacobians[2]) jacobians[2][4] *= 1.02;  // d r_y / d point_y off by 2 %
    return true;
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
};

TYPED_TEST(ReprojectionCostTest, GradientCheckerPassesAndCatchesAWrongJacobian) {
  using Model = TypeParam;
  auto k = Intrinsics<Model>();
  Scene s = RandomScene(this->rng_);
  const double* params[] = {s.q.data(), s.centre.data(), s.point.data(), k.data()};
  ceres::QuaternionManifold quaternion;
  std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, nullptr, nullptr};
  ceres::NumericDiffOptions numeric;
  ceres::GradientChecker::ProbeResults results;

  ReprojectionCost<Model> good(Eigen::Vector2d(10.0, 20.0));
  ceres::GradientChecker good_checker(&good, &manifolds, numeric);
  EXPECT_TRUE(good_checker.Probe(params, kNumericTolerance, &results)) << results.error_log;

  WrongJacobian bad(new ReprojectionCost<Model>(Eigen::Vector2d(10.0, 20.0)));
  ceres::GradientChecker bad_checker(&bad, &manifolds, numeric);
  EXPECT_FALSE(bad_checker.Probe(params, kNumericTolerance, &results));
}

TEST(ReprojectionCost, PointOnTheCameraPlaneIsRejected) {
  ReprojectionCost<PinholeModel> cost(Eigen::Vector2d(0.0, 0.0));
  std::array<double, 4> q = {1.0, 0.0, 0.0, 0.0};
  Eigen::Vector3d centre(0, 0, 0), point(1.0, 2.0, 0.0);
  std::vector<double> k = {1000.0, 0.0, 0.0};
  const double* params[] = {q.data(), centre.data(), point.data(), k.data()};
  double r[2];
  EXPECT_FALSE(cost.Evaluate(params, r, nullptr));
  point.z() = -5.0;  // behind the camera: evaluated, not rejected
  EXPECT_TRUE(cost.Evaluate(params, r, nullptr));
}

TEST(PositionPriorCost, WeighsHorizontalAndVerticalSeparately) {
  PositionPriorCost cost(Eigen::Vector3d(1.0, 2.0, 3.0), 0.5, 2.0);
  Eigen::Vector3d x(2.0, 1.0, 7.0);
  const double* params[] = {x.data()};
  Eigen::Vector3d r;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> j;
  double* jac[] = {j.data()};
  ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));
  EXPECT_DOUBLE_EQ(r.x(), 2.0);
  EXPECT_DOUBLE_EQ(r.y(), -2.0);
  EXPECT_DOUBLE_EQ(r.z(), 2.0);
  EXPECT_DOUBLE_EQ(j(0, 0), 2.0);
  EXPECT_DOUBLE_EQ(j(2, 2), 0.5);
  EXPECT_DOUBLE_EQ(j(0, 1), 0.0);
}

}  // namespace
}  // namespace aerotri
