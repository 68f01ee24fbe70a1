// SPDX-License-Identifier: BSD-3-Clause
// One typed battery run on every camera model: projection round trips,
// analytic Jacobians against Ceres Jets and central differences, and a
// negative control that the Jacobian checker must catch.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <random>

#include "camera_models/camera.h"
#include "libphoto/base/error.h"
#include "tests/jacobian_checks.h"

namespace aerotri {
namespace {

// Jets agree with the analytic Jacobian to rounding: both are exact.
constexpr double kJetTolerance = 1e-10;
// Central differences with h = 1e-6 (relative) carry O(h^2) truncation and
// O(eps/h) rounding, about 1e-7 relative on these magnitudes.
constexpr double kCentralDifferenceTolerance = 1e-5;
// Newton undistortion stops at 1e-9 px; 1e-6 px leaves room for the forward
// model's rounding at large radii.
constexpr double kRoundTripTolerancePx = 1e-6;

template <typename Model>
std::vector<double> TypicalParams();
// A 4000 x 3000 drone camera, f = 3000 px, moderate barrel distortion.
template <>
std::vector<double> TypicalParams<PinholeModel>() {
  return {3000.0, 1999.5, 1499.5};
}
template <>
std::vector<double> TypicalParams<BrownModel>() {
  return {3000.0, 2010.3, 1488.7, -0.12, 0.09, -0.02, 0.0011, -0.0007};
}
template <>
std::vector<double> TypicalParams<SnavelyModel>() {
  return {3000.0, -0.12, 0.09};
}

struct Jacobians {
  Eigen::Vector2d xy;
  Eigen::MatrixXd d_uv;      // 2 x 2
  Eigen::MatrixXd d_params;  // 2 x N
};

template <typename Model>
Jacobians Analytic(const std::vector<double>& params, double u, double v) {
  Eigen::Matrix<double, 2, 2, Eigen::RowMajor> d_uv;
  Eigen::Matrix<double, 2, Model::kNumParams, Eigen::RowMajor> d_params;
  Jacobians j;
  Model::ImageFromNormalizedWithJacobian(params.data(), u, v, j.xy.data(), d_uv.data(),
                                         d_params.data());
  j.d_uv = d_uv;
  j.d_params = d_params;
  return j;
}

template <typename Model>
Jacobians WithJets(const std::vector<double>& params, double u, double v) {
  constexpr int N = Model::kNumParams;
  using Jet = ceres::Jet<double, N + 2>;
  std::vector<Jet> p(N);
  for (int i = 0; i < N; ++i) p[i] = Jet(params[i], i);
  const Jet ju(u, N), jv(v, N + 1);
  Jet xy[2];
  Model::ImageFromNormalized(p.data(), ju, jv, xy);
  Jacobians j;
  j.xy = {xy[0].a, xy[1].a};
  j.d_uv.resize(2, 2);
  j.d_params.resize(2, N);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < N; ++c) j.d_params(r, c) = xy[r].v[c];
    j.d_uv(r, 0) = xy[r].v[N];
    j.d_uv(r, 1) = xy[r].v[N + 1];
  }
  return j;
}

template <typename Model>
Jacobians WithCentralDifferences(const std::vector<double>& params, double u, double v) {
  constexpr int N = Model::kNumParams;
  auto eval = [](const std::vector<double>& p, double uu, double vv) {
    Eigen::Vector2d xy;
    Model::ImageFromNormalized(p.data(), uu, vv, xy.data());
    return xy;
  };
  Jacobians j;
  j.xy = eval(params, u, v);
  j.d_uv.resize(2, 2);
  j.d_params.resize(2, N);
  const double hu = 1e-6 * std::max(1.0, std::abs(u));
  const double hv = 1e-6 * std::max(1.0, std::abs(v));
  j.d_uv.col(0) = (eval(params, u + hu, v) - eval(params, u - hu, v)) / (2 * hu);
  j.d_uv.col(1) = (eval(params, u, v + hv) - eval(params, u, v - hv)) / (2 * hv);
  for (int i = 0; i < N; ++i) {
    const double h = 1e-6 * std::max(1.0, std::abs(params[i]));
    std::vector<double> plus = params, minus = params;
    plus[i] += h;
    minus[i] -= h;
    j.d_params.col(i) = (eval(plus, u, v) - eval(minus, u, v)) / (2 * h);
  }
  return j;
}

template <typename Model>
class CameraModelTest : public ::testing::Test {
 protected:
  void SetUp() override { rng_.seed(20261122); }
  // Normalised coordinates across a 4000 x 3000 frame at f = 3000 (|u| < 0.67).
  std::pair<double, double> RandomUv() {
    std::uniform_real_distribution<double> du(-0.66, 0.66), dv(-0.5, 0.5);
    return {du(rng_), dv(rng_)};
  }
  std::mt19937 rng_;
};

using ModelTypes = ::testing::Types<PinholeModel, BrownModel, SnavelyModel>;
TYPED_TEST_SUITE(CameraModelTest, ModelTypes);

TYPED_TEST(CameraModelTest, AnalyticJacobianMatchesJets) {
  const auto params = TypicalParams<TypeParam>();
  for (int trial = 0; trial < 200; ++trial) {
    const auto [u, v] = this->RandomUv();
    const Jacobians a = Analytic<TypeParam>(params, u, v);
    const Jacobians jet = WithJets<TypeParam>(params, u, v);
    ASSERT_LT((a.xy - jet.xy).norm(), 1e-9);
    std::string where;
    ASSERT_LT(testing::WorstRelativeError(a.d_uv, jet.d_uv, &where), kJetTolerance)
        << "d_uv entry " << where << " at u=" << u << " v=" << v;
    ASSERT_LT(testing::WorstRelativeError(a.d_params, jet.d_params, &where), kJetTolerance)
        << "d_params entry " << where << " at u=" << u << " v=" << v;
  }
}

TYPED_TEST(CameraModelTest, AnalyticJacobianMatchesCentralDifferences) {
  const auto params = TypicalParams<TypeParam>();
  for (int trial = 0; trial < 200; ++trial) {
    const auto [u, v] = this->RandomUv();
    const Jacobians a = Analytic<TypeParam>(params, u, v);
    const Jacobians cd = WithCentralDifferences<TypeParam>(params, u, v);
    EXPECT_LT(testing::WorstRelativeError(a.d_uv, cd.d_uv), kCentralDifferenceTolerance);
    EXPECT_LT(testing::WorstRelativeError(a.d_params, cd.d_params),
              kCentralDifferenceTolerance);
  }
}

TYPED_TEST(CameraModelTest, CheckerCatchesAWrongJacobian) {
  // Negative control: the same checker must reject a Jacobian with one entry
  // off by 1 % (as a sign or factor slip in a derivation would be).
  const auto params = TypicalParams<TypeParam>();
  const auto [u, v] = this->RandomUv();
  Jacobians wrong = Analytic<TypeParam>(params, u, v);
  wrong.d_params(1, 0) *= 1.01;
  wrong.d_uv(0, 1) += 0.01 * std::abs(wrong.d_uv(0, 0));
  const Jacobians jet = WithJets<TypeParam>(params, u, v);
  EXPECT_GT(testing::WorstRelativeError(wrong.d_params, jet.d_params), kJetTolerance);
  EXPECT_GT(testing::WorstRelativeError(wrong.d_uv, jet.d_uv), kJetTolerance);
}

TYPED_TEST(CameraModelTest, RoundTripOverAPixelGrid) {
  Camera camera;
  camera.model = TypeParam::kId;
  camera.width = 4000;
  camera.height = 3000;
  camera.params = TypicalParams<TypeParam>();
  const Eigen::Vector2d centre =
      TypeParam::kId == CameraModelId::kSnavely ? Eigen::Vector2d(0, 0)
                                                : Eigen::Vector2d(1999.5, 1499.5);
  int checked = 0;
  for (int iy = 0; iy <= 20; ++iy) {
    for (int ix = 0; ix <= 20; ++ix) {
      // Corners included: offsets from -half to +half of the frame.
      const Eigen::Vector2d xy =
          centre + Eigen::Vector2d(-1999.5 + ix * 199.95, -1499.5 + iy * 149.95);
      const auto uv = camera.NormalizedFromImage(xy);
      ASSERT_TRUE(uv.has_value()) << "pixel " << xy.transpose();
      const Eigen::Vector2d back = camera.ImageFromNormalized(*uv);
      EXPECT_LT((back - xy).norm(), kRoundTripTolerancePx) << "pixel " << xy.transpose();
      // And the ray points through the pixel.
      const auto ray = camera.RayFromImage(xy);
      ASSERT_TRUE(ray.has_value());
      EXPECT_NEAR(ray->norm(), 1.0, 1e-12);
      EXPECT_LT((camera.ImageFromCamera(*ray * 37.0) - xy).norm(), kRoundTripTolerancePx);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 21 * 21);
}

TEST(BrownModel, MatchesOpenCvProjectPoints) {
  // Independent reference: OpenCV's calib3d projection with the same lens.
  const auto params = TypicalParams<BrownModel>();
  const auto dist = BrownModel::ToOpenCvDistCoeffs(params.data());
  cv::Mat k = (cv::Mat_<double>(3, 3) << params[0], 0, params[1], 0, params[0], params[2], 0,
               0, 1);
  std::vector<cv::Point3d> points;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> d(-0.6, 0.6);
  for (int i = 0; i < 100; ++i) points.emplace_back(d(rng) * 50, d(rng) * 40, 50.0 + 20 * d(rng));
  std::vector<cv::Point2d> projected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k,
                    std::vector<double>(dist.begin(), dist.end()), projected);
  Camera camera;
  camera.model = CameraModelId::kBrown;
  camera.params = params;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d xy =
        camera.ImageFromCamera(Eigen::Vector3d(points[i].x, points[i].y, points[i].z));
    EXPECT_NEAR(xy.x(), projected[i].x, 1e-8);
    EXPECT_NEAR(xy.y(), projected[i].y, 1e-8);
  }
}

TEST(BrownModel, UndistortionReportsNonConvergenceBeyondTheFold) {
  // Strong barrel distortion folds over at r ~ 0.9: far pixels have no preimage.
  Camera camera;
  camera.model = CameraModelId::kBrown;
  camera.params = {1000.0, 500.0, 500.0, -0.6, 0.0, 0.0, 0.0, 0.0};
  EXPECT_TRUE(camera.NormalizedFromImage({600.0, 550.0}).has_value());
  EXPECT_FALSE(camera.NormalizedFromImage({500.0 + 5000.0, 500.0}).has_value());
}

TEST(Camera, ValidateNamesTheProblem) {
  Camera camera = Camera::Create(CameraModelId::kBrown, 3000.0, 4000, 3000, 7);
  EXPECT_NO_THROW(camera.Validate());
  EXPECT_DOUBLE_EQ(camera.principal_point_px().x(), 1999.5);
  camera.params.pop_back();
  try {
    camera.Validate();
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("expected 8 parameters, got 7"), std::string::npos)
        << e.what();
  }
  camera = Camera::Create(CameraModelId::kPinhole, -5.0, 100, 100);
  EXPECT_THROW(camera.Validate(), InvalidArgument);
}

TEST(CameraModelInfo, NamesRoundTrip) {
  for (CameraModelId id : AllCameraModelIds()) {
    const auto& info = GetCameraModelInfo(id);
    EXPECT_EQ(CameraModelIdFromName(info.name), id);
    EXPECT_EQ(static_cast<int>(info.param_names.size()), info.num_params());
    VisitCameraModel(id, [&](auto m) { EXPECT_EQ(decltype(m)::kNumParams, info.num_params()); });
  }
  EXPECT_EQ(CameraModelIdFromName("brown"), CameraModelId::kBrown);
  EXPECT_FALSE(CameraModelIdFromName("fisheye_typo").has_value());
}

}  // namespace
}  // namespace aerotri
