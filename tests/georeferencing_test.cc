// SPDX-License-Identifier: BSD-3-Clause
// Georeferenced adjustment on a synthetic survey with known truth at a real
// location (46.5 N, 7.5 E; UTM 32N): GPS sigma 2 m horizontal / 4 m vertical,
// 8 control points with 1 cm survey noise, 6 check points, 0.3 px image noise.
#include "libphoto/survey/georeferencing.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

SyntheticSurveyOptions SurveyOptions(std::uint32_t seed) {
  SyntheticSurveyOptions o;
  o.seed = seed;
  o.area_width_m = 200.0;
  o.area_height_m = 150.0;
  o.num_tie_points = 1500;
  o.pixel_noise_px = 0.3;
  o.num_control_points = 8;
  o.num_check_points = 6;
  return o;
}

// The model as another tool would hand it over: an arbitrary frame and scale
// and a rough camera (focal 3 % off, no distortion).
SparseModel ArbitraryFrame(SparseModel model, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Similarity s;
  s.scale = 0.04 + 0.01 * std::abs(g(rng));
  s.rotation = Eigen::Quaterniond(
      Eigen::AngleAxisd(3.0 * g(rng), Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized()));
  s.translation = Eigen::Vector3d(10 * g(rng), 10 * g(rng), 10 * g(rng));
  for (Image& image : model.images) {
    image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
  }
  for (Point& point : model.points) point.position = s.Apply(point.position);
  testing::Perturb(&model, rng, 0.0005, 0.05, 0.0005, 0.03);
  for (Camera& c : model.cameras) {
    for (int i = 3; i < 8; ++i) c.params[i] = 0.0;
  }
  return model;
}

GeoreferenceOptions Options() {
  GeoreferenceOptions o;
  o.output_crs = "EPSG:32632";
  o.gcp_sigma_h_m = 0.01;
  o.gcp_sigma_v_m = 0.01;
  o.bundle.loss = LossType::kHuber;
  o.bundle.loss_scale_px = 2.0;
  return o;
}

TEST(Georeferencing, ControlPointsBringCheckPointsToCentimetres) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(21), {});
  SparseModel model = ArbitraryFrame(scene.tie_model, 21);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  EXPECT_NE(report.bundle.gauge.find("datum from priors"), std::string::npos);
  EXPECT_EQ(report.control_stats.count, 8);
  ASSERT_EQ(report.check_stats.count, 6);
  // Each check point is triangulated from ~10 rays of 0.3 px (0.8 cm at this
  // GSD) and sits in a datum fixed by 8 points of 1 cm: expect ~0.5-1.5 cm.
  EXPECT_GT(report.check_stats.rmse_3d_m, 0.002);
  EXPECT_LT(report.check_stats.rmse_3d_m, 0.04);
  EXPECT_LT(report.check_stats.rmse_h_m, 0.03);
  // Control points fit their survey to about its noise.
  EXPECT_LT(report.control_stats.rmse_3d_m, 0.03);
  EXPECT_LT(report.bundle.final_rms_px, 1.05 * 0.3 * std::sqrt(2.0));
  // Self-calibration finds the lens (truth f 3000, k1 -0.08).
  EXPECT_NEAR(model.cameras[0].params[0], 3000.0, 3.0);
  EXPECT_NEAR(model.cameras[0].params[3], -0.08, 0.005);
}

TEST(Georeferencing, GpsAloneStaysAtTheGpsLevel) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(22), {});
  SparseModel model = ArbitraryFrame(scene.tie_model, 22);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  EXPECT_EQ(report.control_stats.count, 0);
  ASSERT_EQ(report.check_stats.count, 6);
  // The datum is an average of ~60 fixes of 2 m / 4 m: a shift of a few
  // decimetres, not centimetres and not metres (scale and tilt add a little).
  EXPECT_GT(report.check_stats.rmse_3d_m, 0.1);
  EXPECT_LT(report.check_stats.rmse_3d_m, 2.5);
  // The camera residuals against GPS look like the GPS noise.
  double sum_h = 0.0;
  for (const CameraResult& c : report.cameras) sum_h += c.d_enu_m.head<2>().squaredNorm();
  const double rms_h = std::sqrt(sum_h / (2.0 * report.cameras.size()));
  EXPECT_GT(rms_h, 1.4);
  EXPECT_LT(rms_h, 2.6);
}

TEST(Georeferencing, ASimilarityOfTheInitialGuessDoesNotChangeTheResult) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(23), {});
  const SparseModel base = ArbitraryFrame(scene.tie_model, 23);
  GeoreferenceOptions options = Options();
  options.bundle.function_tolerance = 1e-14;
  options.bundle.parameter_tolerance = 1e-14;
  options.bundle.gradient_tolerance = 1e-14;
  options.bundle.max_iterations = 200;
  options.bundle.outlier_threshold_px = 0.0;

  SparseModel a = base;
  const GeoreferenceReport ra = GeoreferenceAndAdjust(&a, scene.gps, &scene.control, &scene.checks, options);
  // Same model, another frame and scale.
  SparseModel b = base;
  Similarity s;
  s.scale = 7.3;
  s.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, -1).normalized()));
  s.translation = {500.0, -20.0, 3.0};
  for (Image& image : b.images) {
    image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
  }
  for (Point& point : b.points) point.position = s.Apply(point.position);
  const GeoreferenceReport rb = GeoreferenceAndAdjust(&b, scene.gps, &scene.control, &scene.checks, options);

  double worst = 0.0;
  for (size_t i = 0; i < a.images.size(); ++i) {
    worst = std::max(worst, (a.images[i].pose.centre_in_world - b.images[i].pose.centre_in_world).norm());
  }
  EXPECT_LT(worst, 1e-5) << "camera centres differ by up to " << worst << " m";
  EXPECT_NEAR(ra.check_stats.rmse_3d_m, rb.check_stats.rmse_3d_m, 1e-6);
  EXPECT_NEAR(a.cameras[0].params[0], b.cameras[0].params[0], 1e-4);
}

TEST(Georeferencing, RefusesWhenNothingAnchorsTheDatum) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(24), {});
  SparseModel model = scene.tie_model;
  EXPECT_THROW(GeoreferenceAndAdjust(&model, {}, nullptr, &scene.checks, Options()),
               InvalidArgument);
}

TEST(Georeferencing, CompoundCrsReportsGeoidHeights) {
  SyntheticGeorefOptions geo;
  geo.crs = "EPSG:32632+5773";
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(25), geo);
  SparseModel model = ArbitraryFrame(scene.tie_model, 25);
  GeoreferenceOptions options = Options();
  options.output_crs = "";  // take the control file's
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
  EXPECT_EQ(report.crs, "EPSG:32632+5773");
  EXPECT_EQ(report.crs_source, "control file");
  EXPECT_LT(report.check_stats.rmse_3d_m, 0.04);
  // Orthometric heights: the EGM96 undulation here is 50.09 m
  // (echo "46.5 7.5 0" | cs2cs EPSG:4979 EPSG:4326+5773 gives -50.0934).
  ASSERT_FALSE(report.check.empty());
  const LocalFrame frame(geo.origin);
  for (size_t i = 0; i < report.check.size(); ++i) {
    const Point* truth = nullptr;
    for (const Point& p : scene.survey.truth.points) {
      if (p.name == report.check[i].name) truth = &p;
    }
    ASSERT_NE(truth, nullptr);
    const double h = frame.GeodeticFromEnu(truth->position).h_m;
    EXPECT_NEAR(report.check[i].surveyed_crs.z(), h - 50.09, 0.05) << report.check[i].name;
  }
}


// GPS altitudes in the wrong height reference (every fix 50 m high) against
// 8 correct control points: the control holds the datum, the GPS offset is
// found before the adjustment and estimated in it, and the lens is not bent
// to absorb it.
TEST(Georeferencing, ControlHoldsTheDatumAgainstAGpsHeightOffset) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(26), {});
  std::map<std::string, GpsFix> gps = scene.gps;
  for (auto& [name, fix] : gps) fix.position.h_m += 50.0;
  SparseModel model = ArbitraryFrame(scene.tie_model, 26);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, gps, &scene.control, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  ASSERT_TRUE(report.gps_vs_control.measured);
  EXPECT_TRUE(report.gps_vs_control.significant);
  EXPECT_TRUE(report.gps_vs_control.rejected.empty());
  // ~60 fixes of 4 m vertical noise: the mean is good to ~0.5 m.
  const double n = report.gps_vs_control.consistent;
  EXPECT_NEAR(report.gps_vs_control.offset_enu_m.z(), 50.0, 4.0 * 4.0 / std::sqrt(n));
  ASSERT_TRUE(report.bundle.gps_offset_estimated);
  EXPECT_NEAR(report.bundle.gps_offset_m.z(), 50.0, 4.0 * 4.0 / std::sqrt(n));
  EXPECT_NEAR(report.bundle.gps_offset_m.x(), 0.0, 4.0 * 2.0 / std::sqrt(n));
  bool warned = false;
  for (const Finding& f : report.findings) warned |= f.code == "GPS_CONTROL_OFFSET";
  EXPECT_TRUE(warned);
  EXPECT_EQ(SurveyStatus(report.findings), "warnings");
  // Focal length within 0.1 % of truth (3000 px), checks at the clean level.
  EXPECT_NEAR(model.cameras[0].params[0], 3000.0, 3.0);
  ASSERT_EQ(report.check_stats.count, 6);
  EXPECT_LT(report.check_stats.rmse_3d_m, 0.04);
  // Camera residuals against the offset-corrected GPS look like GPS noise.
  double sum_v = 0.0;
  for (const CameraResult& c : report.cameras) sum_v += c.d_enu_m.z() * c.d_enu_m.z();
  const double rms_v = std::sqrt(sum_v / report.cameras.size());
  EXPECT_GT(rms_v, 2.5);
  EXPECT_LT(rms_v, 5.5);

  // With --gps-offset never the conflict is still reported, and nothing is estimated.
  SparseModel held = ArbitraryFrame(scene.tie_model, 26);
  GeoreferenceOptions never = Options();
  never.gps_offset = GpsOffsetPolicy::kNever;
  const GeoreferenceReport r2 = GeoreferenceAndAdjust(&held, gps, &scene.control, &scene.checks, never);
  EXPECT_TRUE(r2.gps_vs_control.significant);
  EXPECT_FALSE(r2.bundle.gps_offset_estimated);
}

// Clean GPS: measured against the control, no offset found, none estimated.
TEST(Georeferencing, CleanGpsShowsNoOffset) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(27), {});
  SparseModel model = ArbitraryFrame(scene.tie_model, 27);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  ASSERT_TRUE(report.gps_vs_control.measured);
  EXPECT_FALSE(report.gps_vs_control.significant);
  EXPECT_FALSE(report.bundle.gps_offset_estimated);
  EXPECT_TRUE(report.gps_vs_control.rejected.empty());
  const double n = report.gps_vs_control.consistent;
  EXPECT_EQ(n, static_cast<double>(scene.gps.size()));
  // The mean of n fixes of 2 m / 4 m noise: within 4 standard errors of zero,
  // and its spread is the injected noise.
  EXPECT_LT(report.gps_vs_control.offset_enu_m.head<2>().norm(), 4.0 * 2.0 / std::sqrt(n));
  EXPECT_LT(std::abs(report.gps_vs_control.offset_enu_m.z()), 4.0 * 4.0 / std::sqrt(n));
  EXPECT_GT(report.gps_vs_control.rms_after_offset_m.x(), 1.4);
  EXPECT_LT(report.gps_vs_control.rms_after_offset_m.x(), 2.6);
  EXPECT_GT(report.gps_vs_control.rms_after_offset_m.z(), 2.8);
  EXPECT_LT(report.gps_vs_control.rms_after_offset_m.z(), 5.2);
}

// A third of the fixes 50 m off (blunders, not an offset): named, left out of
// the adjustment, and the result is that of the clean survey.
TEST(Georeferencing, BlunderedGpsFixesAreNamedAndLeftOut) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(28), {});
  SparseModel clean_model = ArbitraryFrame(scene.tie_model, 28);
  const GeoreferenceReport clean =
      GeoreferenceAndAdjust(&clean_model, scene.gps, &scene.control, &scene.checks, Options());

  std::map<std::string, GpsFix> gps = scene.gps;
  std::set<std::string> corrupted;
  std::mt19937 rng(28);
  std::uniform_real_distribution<double> angle(0.0, 2 * M_PI);
  int k = 0;
  const LocalFrame frame(gps.begin()->second.position);
  for (auto& [name, fix] : gps) {
    if (k++ % 3 != 0) continue;
    const double a = angle(rng);
    fix.position = frame.GeodeticFromEnu(frame.EnuFromGeodetic(fix.position) +
                                         Eigen::Vector3d(50.0 * std::cos(a), 50.0 * std::sin(a), 0.0));
    corrupted.insert(name);
  }
  SparseModel model = ArbitraryFrame(scene.tie_model, 28);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, gps, &scene.control, &scene.checks, Options());
  const std::set<std::string> rejected(report.gps_vs_control.rejected.begin(),
                                       report.gps_vs_control.rejected.end());
  EXPECT_EQ(rejected, corrupted);
  EXPECT_FALSE(report.gps_vs_control.significant);
  for (const CameraResult& c : report.cameras) {
    EXPECT_EQ(c.prior_rejected, corrupted.count(c.name) > 0) << c.name;
  }
  ASSERT_EQ(report.check_stats.count, 6);
  EXPECT_LT(report.check_stats.rmse_3d_m, 1.5 * clean.check_stats.rmse_3d_m);
}


// The stochastic model's check: with sigmas that match the injected noise
// (0.3 px on ties and marks, GPS 2 / 4 m, control 1 cm) sigma0 is 1; stated
// 1 px for the images, it is about 0.3.
TEST(Georeferencing, Sigma0IsOneWhenTheSigmasMatchTheNoise) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(29), {});
  GeoreferenceOptions options = Options();
  options.bundle.loss = LossType::kNone;
  options.bundle.outlier_threshold_px = 0.0;
  options.bundle.observation_sigma_px = 0.3;
  SparseModel model = ArbitraryFrame(scene.tie_model, 29);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
  SCOPED_TRACE(r.bundle.BriefReport());
  EXPECT_GT(r.bundle.redundancy, 10000);
  EXPECT_GT(r.bundle.sigma0, 0.9);
  EXPECT_LT(r.bundle.sigma0, 1.1);

  options.bundle.observation_sigma_px = 1.0;
  options.bundle.mark_sigma_px = 0.3;  // marks as stated, ties pessimistic
  SparseModel again = ArbitraryFrame(scene.tie_model, 29);
  const GeoreferenceReport p = GeoreferenceAndAdjust(&again, scene.gps, &scene.control, &scene.checks, options);
  EXPECT_GT(p.bundle.sigma0, 0.25);
  EXPECT_LT(p.bundle.sigma0, 0.4);
  std::printf("sigma0 %.4f (redundancy %d) with matching sigmas, %.4f with 1 px ties\n", r.bundle.sigma0,
              r.bundle.redundancy, p.bundle.sigma0);
}


// Sigmas that match the injected noise: 0.3 px on every image measurement,
// 1 cm survey noise, the GPS's own 2 / 4 m; least squares without a loss.
GeoreferenceOptions MatchingSigmas() {
  GeoreferenceOptions o = Options();
  o.bundle.loss = LossType::kNone;
  o.bundle.outlier_threshold_px = 0.0;
  o.bundle.observation_sigma_px = 0.3;
  return o;
}

// Check points' errors against their posterior sigmas, over seeds: with
// sigmas that describe the noise, (adjusted − surveyed) / sqrt(σ² + σ_survey²)
// is standard normal on every axis. Independent check points carry the
// cameras' covariance; inside the bundle they are free points.
// Independent check points (false) and check points in the bundle (true),
// as two cases: they run in parallel.
class CheckPointSigmas : public ::testing::TestWithParam<bool> {};

TEST_P(CheckPointSigmas, CheckPointErrorsMatchTheirPosteriorSigmas) {
  {
    const bool in_bundle = GetParam();
    double sum = 0.0;
    int n = 0;
    for (std::uint32_t seed = 40; seed < 46; ++seed) {
      const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(seed), {});
      GeoreferenceOptions options = MatchingSigmas();
      options.bundle.check_points_in_bundle = in_bundle;
      SparseModel model = ArbitraryFrame(scene.tie_model, seed);
      const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
      SCOPED_TRACE(r.bundle.BriefReport());
      ASSERT_TRUE(r.bundle.precision.computed) << r.bundle.precision.note;
      EXPECT_EQ(r.check_points_in_bundle, in_bundle);
      EXPECT_GT(r.bundle.sigma0, 0.9);
      EXPECT_LT(r.bundle.sigma0, 1.1);
      for (const GroundPointResult& p : r.check) {
        ASSERT_TRUE(p.solved && p.has_precision) << p.name;
        for (int a = 0; a < 3; ++a) {
          const double z = p.d_m[a] / std::hypot(p.sigma_m[a], 0.01);
          sum += z * z;
          ++n;
        }
      }
      // Cameras: centimetre-level centres, hundredths of a degree.
      for (const CameraResult& c : r.cameras) {
        ASSERT_TRUE(c.has_precision) << c.name;
        EXPECT_GT(c.sigma_position_m.minCoeff(), 1e-3);
        EXPECT_LT(c.sigma_position_m.maxCoeff(), 0.2);
        EXPECT_GT(c.sigma_opk_deg.minCoeff(), 1e-4);
        EXPECT_LT(c.sigma_opk_deg.maxCoeff(), 0.2);
      }
    }
    const double rms = std::sqrt(sum / n);
    std::printf("check points %s: RMS of error / posterior sigma %.3f over %d axes\n",
                in_bundle ? "in the bundle" : "independent", rms, n);
    EXPECT_GT(rms, 0.8);
    EXPECT_LT(rms, 1.25);
  }
}
INSTANTIATE_TEST_SUITE_P(Georeferencing, CheckPointSigmas, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? std::string("InTheBundle") : std::string("Independent");
                         });

// Variance-component estimation: the images stated at 1 px where the noise
// is 0.3 px. Each group's factor comes out as the truth says (ties 0.3,
// GPS 1) and the posterior sigmas are honest again; without the
// estimation, one σ0² scales the GPS-held datum down with the ties, and the
// check points' errors exceed their sigmas.
struct VceFigures {
  double z_rms = 0.0;          // check-point error / posterior sigma, RMS over axes
  double tie_sigma_px = 0.0;   // estimated image sigma of the ties, mean over seeds
  double gps_factor = 0.0;     // GPS horizontal factor, mean over seeds
  double sigma0 = 0.0;         // final sigma0, mean
};

VceFigures VceOverSeeds(bool estimate, bool with_control, std::uint32_t first, std::uint32_t last) {
  VceFigures f;
  double sum = 0.0;
  int n = 0, seeds = 0;
  for (std::uint32_t seed = first; seed < last; ++seed, ++seeds) {
    SyntheticGeorefOptions georef;
    georef.seed = seed;  // the GPS's own noise differs too: it holds the datum
    const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(seed), georef);
    GeoreferenceOptions options = MatchingSigmas();
    options.bundle.observation_sigma_px = 1.0;  // 0.3 px of noise
    options.bundle.estimate_variance_components = estimate;
    SparseModel model = ArbitraryFrame(scene.tie_model, seed);
    const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, with_control ? &scene.control : nullptr,
                                                       &scene.checks, options);
    SCOPED_TRACE(r.bundle.BriefReport());
    EXPECT_TRUE(r.bundle.precision.computed) << r.bundle.precision.note;
    for (const VarianceComponent& vc : r.bundle.variance_components) {
      if (vc.group == ObservationGroup::kTies) f.tie_sigma_px += vc.scale * vc.sigma0 * 1.0;
      if (vc.group == ObservationGroup::kGpsHorizontal) f.gps_factor += vc.scale * vc.sigma0;
    }
    f.sigma0 += r.bundle.sigma0;
    for (const GroundPointResult& p : r.check) {
      if (!p.solved || !p.has_precision) continue;
      for (int a = 0; a < 3; ++a) {
        const double z = p.d_m[a] / std::hypot(p.sigma_m[a], 0.01);
        sum += z * z;
        ++n;
      }
    }
  }
  f.z_rms = std::sqrt(sum / std::max(n, 1));
  f.tie_sigma_px /= seeds;
  f.gps_factor /= seeds;
  f.sigma0 /= seeds;
  std::printf("%s, %s: check error / sigma RMS %.3f (%d axes), ties %.3f px, GPS factor %.3f, sigma0 %.3f\n",
              with_control ? "control" : "GPS only", estimate ? "variance components estimated" : "stated sigmas",
              f.z_rms, n, f.tie_sigma_px, f.gps_factor, f.sigma0);
  return f;
}

class VarianceComponents : public ::testing::TestWithParam<bool> {};

TEST_P(VarianceComponents, EstimatedComponentsMakeThePosteriorSigmasHonest) {
  const bool with_control = GetParam();
  // GPS only, the GPS noise holds the datum: a dozen realisations of it.
  const std::uint32_t last = with_control ? 10 : 16;
  const VceFigures stated = VceOverSeeds(false, with_control, 4, last);
  const VceFigures vce = VceOverSeeds(true, with_control, 4, last);
  // Reported either way: the ties' own sigma0 says 0.3 px, the GPS's 1.
  EXPECT_GT(stated.tie_sigma_px, 0.27);
  EXPECT_LT(stated.tie_sigma_px, 0.33);
  EXPECT_GT(vce.tie_sigma_px, 0.27);
  EXPECT_LT(vce.tie_sigma_px, 0.33);
  EXPECT_GT(vce.gps_factor, 0.85);
  EXPECT_LT(vce.gps_factor, 1.15);
  EXPECT_GT(vce.sigma0, 0.97);
  EXPECT_LT(vce.sigma0, 1.03);
  EXPECT_GT(vce.z_rms, 0.8);
  EXPECT_LT(vce.z_rms, 1.25);
  // With the GPS holding the datum, one σ0² over everything is 3 times too
  // optimistic (30 seeds: 3.30 against 1.02 estimated).
  if (!with_control) { EXPECT_GT(stated.z_rms, 2.0); }
}
INSTANTIATE_TEST_SUITE_P(Georeferencing, VarianceComponents, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? std::string("WithControl") : std::string("GpsOnly");
                         });

// Camera centres against the truth over seeds, through the same statistic:
// the posterior sigmas of the exterior orientation are honest too.
TEST(Georeferencing, CameraCentreErrorsMatchTheirPosteriorSigmas) {
  double sum = 0.0;
  int n = 0;
  for (std::uint32_t seed = 50; seed < 53; ++seed) {
    const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(seed), {});
    SparseModel model = ArbitraryFrame(scene.tie_model, seed);
    const GeoreferenceReport r =
        GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, MatchingSigmas());
    ASSERT_TRUE(r.bundle.precision.computed) << r.bundle.precision.note;
    const LocalFrame truth_frame(SyntheticGeorefOptions{}.origin);
    const LocalFrame frame(r.enu_origin);
    const Crs crs = Crs::FromString(r.crs);
    for (size_t i = 0; i < model.images.size(); ++i) {
      const CameraResult* c = nullptr;
      for (const CameraResult& x : r.cameras) {
        if (x.name == model.images[i].name) c = &x;
      }
      ASSERT_TRUE(c && c->has_precision);
      const Eigen::Vector3d truth =
          crs.FromGeodetic(truth_frame.GeodeticFromEnu(scene.survey.truth.images[i].pose.centre_in_world));
      for (int a = 0; a < 3; ++a) {
        const double z = (c->position_crs[a] - truth[a]) / c->sigma_position_m[a];
        sum += z * z;
        ++n;
      }
    }
  }
  const double rms = std::sqrt(sum / n);
  std::printf("camera centres: RMS of error / posterior sigma %.3f over %d axes\n", rms, n);
  // Centres of one block are correlated (a datum error moves them all), so
  // the band is wider than for independent samples.
  EXPECT_GT(rms, 0.6);
  EXPECT_LT(rms, 1.6);
}

// Baarda's w-test: a 5 px blunder on one control mark is named by point and
// image; without it, nothing is flagged.
TEST(Georeferencing, WTestNamesABlunderedMark) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(61), {});
  GeoreferenceOptions options = MatchingSigmas();
  options.bundle = SurveyBundleOptions();  // the product's loss and rejection
  options.bundle.observation_sigma_px = 0.3;
  auto has = [](const GeoreferenceReport& r, const std::string& code) {
    for (const Finding& f : r.findings) {
      if (f.code == code) return &f;
    }
    return static_cast<const Finding*>(nullptr);
  };
  {
    SparseModel model = ArbitraryFrame(scene.tie_model, 61);
    const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
    ASSERT_TRUE(r.bundle.precision.computed) << r.bundle.precision.note;
    EXPECT_EQ(has(r, "MARK_BLUNDER"), nullptr);
    EXPECT_GT(r.marks.size(), 20u);
    double max_w = 0.0;
    for (const MarkResult& m : r.marks) max_w = std::max(max_w, m.w.cwiseAbs().maxCoeff());
    EXPECT_LT(max_w, r.w_critical);
  }
  GcpFile control = scene.control;
  GroundPoint& point = control.points.at(3);
  ASSERT_GE(point.measurements.size(), 3u);
  GcpMeasurement& mark = point.measurements.at(1);
  mark.xy_px += Eigen::Vector2d(3.0, -4.0);  // 5 px
  SparseModel model = ArbitraryFrame(scene.tie_model, 61);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &control, &scene.checks, options);
  const Finding* f = has(r, "MARK_BLUNDER");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->items, (std::vector<std::string>{point.name, mark.image})) << f->message;
  EXPECT_EQ(SurveyStatus(r.findings), "warnings");
}


// The w-test's critical values against the normal quantiles (Python's
// statistics.NormalDist().inv_cdf): per test, and Sidak's for the largest of
// n tests at a family-wise 1 %.
TEST(Georeferencing, WTestCriticalValuesAreTheNormalQuantiles) {
  EXPECT_NEAR(TwoSidedNormalCriticalValue(0.001), 3.2905267, 1e-6);
  EXPECT_NEAR(TwoSidedNormalCriticalValue(0.05), 1.9599640, 1e-6);
  EXPECT_NEAR(FamilyWiseCriticalValue(1, 0.01), 2.5758293, 1e-6);
  EXPECT_NEAR(FamilyWiseCriticalValue(200, 0.01), 4.0544592, 1e-6);
  EXPECT_NEAR(FamilyWiseCriticalValue(1600, 0.01), 4.5166878, 1e-6);
}

// A large clean survey expects a mark or two beyond the per-test 3.29: they
// are listed as suspect without a MARK_BLUNDER; a blunder beyond the
// family-wise value is named, and only it is rejected.
TEST(Georeferencing, DataSnoopingHoldsItsLevelAcrossTheSurvey) {
  std::vector<MarkResult> marks(800);
  for (size_t i = 0; i < marks.size(); ++i) {
    marks[i].point = "GCP" + std::to_string(i / 20);
    marks[i].image = "IMG_" + std::to_string(i);
    marks[i].redundancy = Eigen::Vector2d(0.8, 0.7);
    marks[i].w = Eigen::Vector2d(std::sin(i) * 2.0, std::cos(i) * 2.0);
  }
  ASSERT_EQ(CountMarkTests(marks), 1600);
  const double family = FamilyWiseCriticalValue(CountMarkTests(marks), 0.01);
  marks[417].w.y() = -3.4;  // as the 999-photo survey's largest
  EXPECT_TRUE(SnoopMarks(&marks, 3.29, family).empty());
  EXPECT_TRUE(marks[417].suspect);
  EXPECT_FALSE(marks[417].rejected);
  EXPECT_EQ(std::count_if(marks.begin(), marks.end(), [](const MarkResult& m) { return m.suspect; }), 1);

  marks[90].w.x() = 6.0;  // a blunder
  const std::vector<Finding> found = SnoopMarks(&marks, 3.29, family);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].code, "MARK_BLUNDER");
  EXPECT_EQ(found[0].items, (std::vector<std::string>{"GCP4", "IMG_90"}));
  EXPECT_NE(found[0].message.find("1 more mark above 3.29"), std::string::npos) << found[0].message;
  for (size_t i = 0; i < marks.size(); ++i) EXPECT_EQ(marks[i].rejected, i == 90) << i;
  EXPECT_EQ(SurveyStatus(found), "warnings");

  // A mark seen by too few images to be tested does not count.
  marks[0].redundancy = Eigen::Vector2d(0.0, 0.0);
  EXPECT_EQ(CountMarkTests(marks), 1598);
}

// Solved to the optimum: two starts (other frames, scales and perturbations
// of the same block) end at the same check points within 0.1 mm.
TEST(Georeferencing, TheResultDoesNotDependOnTheStart) {
  // A weak block: one short strip on control alone (no GPS), where attitude
  // and position trade against each other.
  SyntheticSurveyOptions so = SurveyOptions(71);
  so.area_width_m = 90.0;
  so.area_height_m = 20.0;
  so.num_tie_points = 600;
  const SyntheticGeoref scene = MakeSyntheticGeoref(so, {});
  const std::map<std::string, GpsFix> no_gps;
  const GeoreferenceOptions options = Options();
  SparseModel a = ArbitraryFrame(scene.tie_model, 71);
  SparseModel b = ArbitraryFrame(scene.tie_model, 72);
  const GeoreferenceReport ra = GeoreferenceAndAdjust(&a, no_gps, &scene.control, &scene.checks, options);
  const GeoreferenceReport rb = GeoreferenceAndAdjust(&b, no_gps, &scene.control, &scene.checks, options);
  std::printf("%d images\n", ra.bundle.num_images);
  EXPECT_TRUE(ra.bundle.converged) << ra.bundle.termination;
  EXPECT_TRUE(rb.bundle.converged) << rb.bundle.termination;
  ASSERT_EQ(ra.check.size(), rb.check.size());
  double worst = 0.0;
  for (size_t k = 0; k < ra.check.size(); ++k) {
    worst = std::max(worst, (ra.check[k].adjusted_crs - rb.check[k].adjusted_crs).cwiseAbs().maxCoeff());
  }
  std::printf("check points between two starts: %.2e m at most\n", worst);
  EXPECT_LT(worst, 1e-4);
}


// The stochastic model stated in the control files: sigma_px on every mark
// line is --mark-sigma-px for those marks, and sigma_x/y/z equal on both
// horizontal axes are sigma_h / sigma_v (a projected grid is conformal).
TEST(Georeferencing, SigmasInTheControlFileWeighTheirObservations) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(81), {});
  GeoreferenceOptions by_option = MatchingSigmas();
  by_option.bundle.mark_sigma_px = 0.5;
  SparseModel a = ArbitraryFrame(scene.tie_model, 81);
  const GeoreferenceReport ra = GeoreferenceAndAdjust(&a, scene.gps, &scene.control, &scene.checks, by_option);

  GcpFile control = scene.control, checks = scene.checks;
  for (GcpFile* f : {&control, &checks}) {
    for (GroundPoint& p : f->points) {
      for (GcpMeasurement& m : p.measurements) m.sigma_px = 0.5;
      p.sigma_xyz_m = Eigen::Vector3d(0.01, 0.01, 0.01);
    }
  }
  SparseModel b = ArbitraryFrame(scene.tie_model, 81);
  const GeoreferenceReport rb = GeoreferenceAndAdjust(&b, scene.gps, &control, &checks, MatchingSigmas());
  SparseModel c = ArbitraryFrame(scene.tie_model, 81);
  const GeoreferenceReport rc =
      GeoreferenceAndAdjust(&c, scene.gps, &scene.control, &scene.checks, MatchingSigmas());  // 0.3 px marks
  ASSERT_EQ(ra.check.size(), rb.check.size());
  double same = 0.0, other = 0.0;
  for (size_t k = 0; k < ra.check.size(); ++k) {
    same = std::max(same, (ra.check[k].adjusted_crs - rb.check[k].adjusted_crs).norm());
    other = std::max(other, (ra.check[k].adjusted_crs - rc.check[k].adjusted_crs).norm());
  }
  std::printf("file sigmas vs options: %.2e m; vs 0.3 px marks: %.2e m\n", same, other);
  EXPECT_LT(same, 2e-5);
  EXPECT_GT(other, 10 * same);
  EXPECT_NEAR(ra.bundle.sigma0, rb.bundle.sigma0, 1e-4);
}


// Leave-one-out is N separate adjustments: point k's figure is the check
// residual of an adjustment whose control lacks k. The table comes from one
// solve (the block-deletion update of its normal equations per point), with
// check points triangulated afterwards or, as classic aerial triangulation
// carries them, free points in the bundle.
class LeaveOneOutModes : public ::testing::TestWithParam<bool> {};

// Six control points, four check points, 700 tie points.
SyntheticGeoref LeaveOneOutScene() {
  SyntheticSurveyOptions so = SurveyOptions(91);
  so.num_tie_points = 700;
  so.num_control_points = 6;
  return MakeSyntheticGeoref(so, {});
}

TEST_P(LeaveOneOutModes, EqualsSeparateAdjustments) {
  const SyntheticGeoref scene = LeaveOneOutScene();
  GeoreferenceOptions options = Options();
  options.leave_one_out = true;
  options.bundle.check_points_in_bundle = GetParam();
  SparseModel model = ArbitraryFrame(scene.tie_model, 91);
  const SparseModel start = model;
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, options);
  const LeaveOneOut& loo = r.leave_one_out;
  ASSERT_TRUE(loo.computed) << loo.note;
  ASSERT_EQ(loo.points.size(), scene.control.points.size());
  // Every point from the update, taken from the survey's own final
  // precision pass: no solve of its own.
  EXPECT_EQ(loo.updated, 6);
  EXPECT_EQ(loo.adjustments, 0);
  EXPECT_EQ(loo.stats.count, 6);
  // Withheld, a control point is farther from its survey than adjusted.
  EXPECT_GT(loo.stats.rmse_3d_m, r.control_stats.rmse_3d_m);
  EXPECT_LT(loo.stats.rmse_3d_m, 0.1);
  // The table equals N separate adjustments (a cold start through every
  // phase) to 0.1 mm here; the bar is 1 mm. The points move by
  // centimetres when withheld, so the band is not met by chance.
  double largest = 0.0, moved = 0.0;
  for (size_t k = 0; k < scene.control.points.size(); ++k) {
    // The check points stay (inside the bundle they tie the block), the
    // withheld point one of them.
    GcpFile without = scene.control, checks = scene.checks;
    without.points.erase(without.points.begin() + static_cast<long>(k));
    checks.points.push_back(scene.control.points[k]);
    SparseModel copy = start;
    options.leave_one_out = false;
    const GeoreferenceReport separate = GeoreferenceAndAdjust(&copy, scene.gps, &without, &checks, options);
    ASSERT_EQ(separate.check.size(), checks.points.size());
    EXPECT_EQ(loo.points[k].name, scene.control.points[k].name);
    EXPECT_EQ(separate.check.back().name, scene.control.points[k].name);
    const double diff = (loo.points[k].d_m - separate.check.back().d_m).cwiseAbs().maxCoeff();
    largest = std::max(largest, diff);
    for (const GroundPointResult& c : r.control) {
      if (c.name == loo.points[k].name) moved = std::max(moved, (loo.points[k].d_m - c.d_m).norm());
    }
    EXPECT_LT(diff, 1e-4) << loo.points[k].name;
  }
  std::printf("leave-one-out against separate adjustments: largest difference %.2e m; withheld points move up "
              "to %.4f m\n", largest, moved);
  EXPECT_GT(moved, 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Georeferencing, LeaveOneOutModes, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? std::string("CheckPointsInBundle") : std::string("Triangulated");
                         });

// Too few control points to withhold one: said, not faked.
TEST(Georeferencing, LeaveOneOutNeedsFourControlPoints) {
  const SyntheticGeoref scene = LeaveOneOutScene();
  GeoreferenceOptions options = Options();
  GcpFile three = scene.control;
  three.points.resize(3);
  options.leave_one_out = true;
  SparseModel model = ArbitraryFrame(scene.tie_model, 91);
  const GeoreferenceReport few = GeoreferenceAndAdjust(&model, scene.gps, &three, &scene.checks, options);
  EXPECT_FALSE(few.leave_one_out.computed);
  EXPECT_NE(few.leave_one_out.note.find("4 or more control points"), std::string::npos);
}


// The exterior orientation as reported (centre in the CRS, omega / phi /
// kappa of R = Rx Ry Rz from the photo frame to the grid) re-projects the
// surveyed check points onto their measured marks: an end-to-end check of
// the stated convention, independent of the adjustment's own frames.
TEST(Georeferencing, ExteriorOrientationReprojectsTheCheckPoints) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(33), {});
  SparseModel model = ArbitraryFrame(scene.tie_model, 33);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  auto rot = [](int axis, double deg) {
    return Eigen::AngleAxisd(deg * M_PI / 180.0, Eigen::Vector3d::Unit(axis)).toRotationMatrix();
  };
  double sum = 0.0;
  int n = 0;
  for (const GroundPoint& p : scene.checks.points) {
    for (const GcpMeasurement& m : p.measurements) {
      const CameraResult* c = nullptr;
      int image = -1;
      for (const CameraResult& x : r.cameras) {
        if (x.name == m.image) c = &x;
      }
      for (size_t i = 0; i < model.images.size(); ++i) {
        if (model.images[i].name == m.image) image = static_cast<int>(i);
      }
      ASSERT_TRUE(c && image >= 0);
      const Eigen::Matrix3d grid_from_photo = rot(0, c->opk_deg.x()) * rot(1, c->opk_deg.y()) * rot(2, c->opk_deg.z());
      const Eigen::Vector3d photo = grid_from_photo.transpose() * (p.xyz - c->position_crs);
      const Eigen::Vector3d opencv(photo.x(), -photo.y(), -photo.z());
      const Eigen::Vector2d xy = model.cameras[model.images[image].camera].ImageFromCamera(opencv);
      sum += (xy - m.xy_px).squaredNorm();
      ++n;
    }
  }
  ASSERT_GT(n, 10);
  const double rms = std::sqrt(sum / n);
  std::printf("check marks re-projected through the reported EO: %.3f px RMS over %d\n", rms, n);
  EXPECT_LT(rms, 1.0);
}


// A local engineering frame: the control file's own Cartesian coordinates,
// no geodesy. The adjustment must be the least-squares solution in those
// coordinates, which an independent dense Gauss–Newton (numeric Jacobian,
// rotation vectors, the control file's coordinates minus their mean) finds
// to 0.1 mm on a tiny block.
TEST(Georeferencing, LocalFrameMatchesAnIndependentGaussNewton) {
  SyntheticSurveyOptions so = SurveyOptions(101);
  so.area_width_m = 60.0;
  so.area_height_m = 40.0;
  so.num_tie_points = 40;
  so.num_control_points = 6;
  so.num_check_points = 2;
  const SyntheticGeoref scene = MakeSyntheticGeoref(so, {});
  // The truth's ENU coordinates, shifted as a national grid treated as flat.
  const Eigen::Vector3d shift(512345.0, 5123456.0, 250.0);
  GcpFile control = scene.control, checks = scene.checks;
  for (GcpFile* f : {&control, &checks}) {
    f->crs = "LOCAL";
    for (GroundPoint& p : f->points) {
      for (const Point& t : scene.survey.truth.points) {
        if (t.name == p.name) p.xyz = t.position + shift;
      }
    }
  }
  GeoreferenceOptions options = Options();
  options.output_crs.clear();  // the control file's frame
  options.bundle.loss = LossType::kNone;
  options.bundle.outlier_threshold_px = 0.0;
  options.bundle.observation_sigma_px = 0.3;
  options.auto_refine = false;
  options.bundle.refine_intrinsics = IntrinsicsRefinement::kNone;
  SparseModel model = ArbitraryFrame(scene.tie_model, 101);
  model.cameras = scene.survey.truth.cameras;  // known interior orientation
  const std::map<std::string, GpsFix> no_gps;
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, no_gps, &control, &checks, options);
  ASSERT_TRUE(r.local_origin.has_value());
  EXPECT_EQ(r.crs, "LOCAL");
  EXPECT_LT(r.check_stats.rmse_3d_m, 0.05);

  // Independent dense Gauss–Newton from a perturbed copy of the solution.
  struct Unknowns {
    std::vector<Eigen::Matrix3d> r0;
    std::vector<Eigen::Vector3d> omega, centre;
    std::vector<Eigen::Vector3d> point;
  };
  std::vector<int> images, points;
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (model.images[i].registered) images.push_back(static_cast<int>(i));
  }
  std::vector<int> slot(model.points.size(), -1);
  std::vector<Eigen::Vector3d> prior(model.points.size());
  for (size_t p = 0; p < model.points.size(); ++p) {
    const Point& pt = model.points[p];
    if (pt.role == PointRole::kCheck) continue;
    slot[p] = static_cast<int>(points.size());
    points.push_back(static_cast<int>(p));
    if (pt.role == PointRole::kControl) {
      for (const GroundPoint& g : control.points) {
        if (g.name == pt.name) prior[p] = g.xyz - *r.local_origin;  // the file's coordinates, shifted only
      }
    }
  }
  std::vector<int> image_slot(model.images.size(), -1);
  for (size_t k = 0; k < images.size(); ++k) image_slot[images[k]] = static_cast<int>(k);
  const int n = 6 * static_cast<int>(images.size()) + 3 * static_cast<int>(points.size());
  auto residuals = [&](const Eigen::VectorXd& x) {
    std::vector<double> out;
    for (const Observation& obs : model.observations) {
      if (image_slot[obs.image] < 0 || slot[obs.point] < 0) continue;
      const int i = image_slot[obs.image];
      const Eigen::Vector3d w = x.segment<3>(6 * i), c = x.segment<3>(6 * i + 3);
      const Eigen::Matrix3d rot =
          (w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() : Eigen::Matrix3d::Identity()) *
          model.images[obs.image].pose.cam_from_world.toRotationMatrix();
      const Eigen::Vector3d X = x.segment<3>(6 * static_cast<int>(images.size()) + 3 * slot[obs.point]);
      const Eigen::Vector2d xy = model.cameras[model.images[obs.image].camera].ImageFromCamera(rot * (X - c));
      const Eigen::Vector2d e = (xy - obs.xy) / 0.3;
      out.push_back(e.x());
      out.push_back(e.y());
    }
    for (int p : points) {
      if (model.points[p].role != PointRole::kControl) continue;
      const Eigen::Vector3d X = x.segment<3>(6 * static_cast<int>(images.size()) + 3 * slot[p]);
      for (int a = 0; a < 3; ++a) out.push_back((X[a] - prior[p][a]) / 0.01);
    }
    return Eigen::Map<Eigen::VectorXd>(out.data(), static_cast<Eigen::Index>(out.size())).eval();
  };
  Eigen::VectorXd x(n);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t k = 0; k < images.size(); ++k) {
    x.segment<3>(6 * k) = 1e-4 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    x.segment<3>(6 * k + 3) = model.images[images[k]].pose.centre_in_world + 0.02 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  }
  for (size_t k = 0; k < points.size(); ++k) {
    x.segment<3>(6 * images.size() + 3 * k) = model.points[points[k]].position + 0.02 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  }
  for (int it = 0; it < 15; ++it) {
    const Eigen::VectorXd r0 = residuals(x);
    Eigen::MatrixXd j(r0.size(), n);
    for (int c = 0; c < n; ++c) {
      Eigen::VectorXd xp = x, xm = x;
      xp[c] += 1e-6;
      xm[c] -= 1e-6;
      j.col(c) = (residuals(xp) - residuals(xm)) / 2e-6;
    }
    x -= (j.transpose() * j).ldlt().solve(j.transpose() * r0);
  }
  double worst = 0.0;
  for (size_t k = 0; k < images.size(); ++k) {
    worst = std::max(worst, (x.segment<3>(6 * k + 3) - model.images[images[k]].pose.centre_in_world).cwiseAbs().maxCoeff());
  }
  for (size_t k = 0; k < points.size(); ++k) {
    worst = std::max(worst, (x.segment<3>(6 * images.size() + 3 * k) - model.points[points[k]].position).cwiseAbs().maxCoeff());
  }
  std::printf("local frame: %zu images, %zu points; aerotri vs dense Gauss-Newton %.2e m at most\n", images.size(),
              points.size(), worst);
  EXPECT_LT(worst, 1e-4);
  // Residuals are in the file's coordinates.
  for (const GroundPointResult& c : r.control) {
    for (const GroundPoint& p : control.points) {
      if (p.name == c.name) { EXPECT_LT((c.surveyed_crs - p.xyz).norm(), 1e-6); }
    }
  }
}

// A local frame takes no geodetic GPS, and no geodetic output CRS.
TEST(Georeferencing, LocalFrameRefusesGeodeticInputs) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(102), {});
  GcpFile control = scene.control;
  control.crs = "LOCAL";
  SparseModel model = ArbitraryFrame(scene.tie_model, 102);
  try {
    GeoreferenceAndAdjust(&model, scene.gps, &control, nullptr, Options());
    ADD_FAILURE() << "GPS accepted in a local frame";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("local engineering frame"), std::string::npos) << e.what();
  }
  GeoreferenceOptions options = Options();  // --crs EPSG:32632
  const std::map<std::string, GpsFix> no_gps;
  try {
    GeoreferenceAndAdjust(&model, no_gps, &control, nullptr, options);
    ADD_FAILURE() << "a geodetic --crs accepted for a local control file";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'EPSG:32632' is geodetic"), std::string::npos) << e.what();
  }
}

// Camera positions surveyed in the same local frame as the control (a
// geo.txt whose CRS is LOCAL) are accepted and placed in that frame: the
// adjusted cameras sit within the GPS noise of them, not hundreds of
// kilometres off; beside geodetic control they are refused.
TEST(Georeferencing, CameraPositionsInTheLocalFrameAreUsedThere) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(103), {});
  GcpFile control = scene.control;  // UTM numbers, read as a local Cartesian frame
  control.crs = "LOCAL";
  GcpFile checks = scene.checks;
  checks.crs = "LOCAL";
  const Crs utm = Crs::FromString("EPSG:32632");
  std::map<std::string, GpsFix> local_gps = scene.gps;
  for (auto& [name, fix] : local_gps) {
    fix.local_xyz = utm.FromGeodetic(fix.position);
    fix.position = {};  // no geodesy
  }
  SparseModel model = ArbitraryFrame(scene.tie_model, 103);
  GeoreferenceOptions options = Options();
  options.output_crs.clear();
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, local_gps, &control, &checks, options);
  EXPECT_TRUE(r.bundle.converged) << r.bundle.termination;
  EXPECT_EQ(r.bundle.num_gps_priors, static_cast<int>(local_gps.size()));
  double h2 = 0.0, v2 = 0.0;
  int n = 0;
  for (const CameraResult& c : r.cameras) {
    if (!c.has_prior) continue;
    const Eigen::Vector3d d = c.position_crs - *local_gps.at(c.name).local_xyz;
    h2 += 0.5 * d.head<2>().squaredNorm();
    v2 += d.z() * d.z();
    ++n;
  }
  ASSERT_GT(n, 20);
  const double rms_h = std::sqrt(h2 / n), rms_v = std::sqrt(v2 / n);
  std::printf("adjusted cameras minus local positions: %.2f m per horizontal axis, %.2f m vertical (noise 2 / 4 m)\n",
              rms_h, rms_v);
  EXPECT_GT(rms_h, 0.6 * 2.0);
  EXPECT_LT(rms_h, 1.4 * 2.0);
  EXPECT_GT(rms_v, 0.6 * 4.0);
  EXPECT_LT(rms_v, 1.4 * 4.0);
  EXPECT_LT(r.check_stats.rmse_3d_m, 0.1);

  SparseModel again = ArbitraryFrame(scene.tie_model, 103);
  try {
    GeoreferenceAndAdjust(&again, local_gps, &scene.control, nullptr, Options());
    ADD_FAILURE() << "local camera positions accepted beside geodetic control";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("is in a local engineering frame and the control is not"),
              std::string::npos)
        << e.what();
  }
}

// An RTK block (2 / 3 cm GNSS) whose antenna positions carry a constant
// offset of 2 / 2 / 10 cm: estimated with its posterior sigma, the offset is
// recovered, and it stays out of the focal length.
TEST(Georeferencing, RtkOffsetIsRecoveredAndKeptOutOfTheFocalLength) {
  SyntheticGeorefOptions rtk;
  rtk.gps_sigma_h_m = 0.02;
  rtk.gps_sigma_v_m = 0.03;
  const Eigen::Vector3d offset(0.02, 0.02, 0.10);
  double sum_offset = 0.0, sum_focal = 0.0;
  int n_offset = 0, n_focal = 0;
  for (std::uint32_t seed = 111; seed < 114; ++seed) {
    rtk.seed = seed;
    const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(seed), rtk);
    std::map<std::string, GpsFix> gps = scene.gps;
    const LocalFrame frame(rtk.origin);
    for (auto& [name, fix] : gps) fix.position = frame.GeodeticFromEnu(frame.EnuFromGeodetic(fix.position) + offset);
    GeoreferenceOptions options = MatchingSigmas();
    options.gps_offset = GpsOffsetPolicy::kAlways;
    SparseModel model = ArbitraryFrame(scene.tie_model, seed);
    const GeoreferenceReport r = GeoreferenceAndAdjust(&model, gps, &scene.control, &scene.checks, options);
    SCOPED_TRACE(r.bundle.BriefReport());
    ASSERT_TRUE(r.bundle.gps_offset_estimated);
    ASSERT_TRUE(r.bundle.precision.has_gps_offset);
    for (int a = 0; a < 3; ++a) {
      const double sigma = std::sqrt(r.bundle.precision.gps_offset_cov(a, a));
      const double z = (r.bundle.gps_offset_m[a] - offset[a]) / sigma;
      EXPECT_LT(std::abs(z), 3.0) << "axis " << a << ": " << r.bundle.gps_offset_m[a] << " ± " << sigma;
      sum_offset += z * z;
      ++n_offset;
    }
    ASSERT_FALSE(r.bundle.intrinsics_precision.empty());
    const IntrinsicsPrecision& p = r.bundle.intrinsics_precision[0];
    ASSERT_EQ(p.names[0], "f");
    const double z = (model.cameras[0].params[0] - scene.survey.truth.cameras[0].params[0]) /
                     (p.sigmas[0] * r.bundle.sigma0);
    sum_focal += z * z;
    ++n_focal;
    std::printf("seed %u: offset %.4f %.4f %.4f m (sigma %.4f %.4f %.4f), f - truth %.3f px (sigma %.3f)\n", seed,
                r.bundle.gps_offset_m.x(), r.bundle.gps_offset_m.y(), r.bundle.gps_offset_m.z(),
                std::sqrt(r.bundle.precision.gps_offset_cov(0, 0)), std::sqrt(r.bundle.precision.gps_offset_cov(1, 1)),
                std::sqrt(r.bundle.precision.gps_offset_cov(2, 2)),
                model.cameras[0].params[0] - scene.survey.truth.cameras[0].params[0], p.sigmas[0] * r.bundle.sigma0);
  }
  // Errors against their sigmas over 3 seeds (9 offset axes, 3 focal lengths).
  EXPECT_LT(std::sqrt(sum_offset / n_offset), 2.0);
  EXPECT_LT(std::sqrt(sum_focal / n_focal), 2.0);
}


// Two flights (a battery change: a 20-minute gap in capture times) whose
// RTK positions carry different offsets (each flight's base set-up or
// antenna mount): --gps-offset per-flight recovers each within 3 sigma and
// fits the GPS to its noise (sigma0 near 1); one shared offset cannot (sigma0
// well above 1, the offsets' difference pushed into the GPS residuals).
TEST(Georeferencing, EachFlightsGpsOffsetIsRecovered) {
  SyntheticGeorefOptions rtk;
  rtk.gps_sigma_h_m = 0.02;
  rtk.gps_sigma_v_m = 0.03;
  rtk.seed = 121;
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(121), rtk);
  const Eigen::Vector3d offsets[2] = {{0.03, -0.02, 0.12}, {-0.04, 0.03, -0.08}};
  std::map<std::string, GpsFix> gps = scene.gps;
  const LocalFrame frame(rtk.origin);
  const size_t half = gps.size() / 2;
  size_t k = 0;
  for (auto& [name, fix] : gps) {
    const int flight = k < half ? 0 : 1;
    fix.time_s = (flight == 0 ? 0.0 : 1200.0) + 2.0 * static_cast<double>(k);
    fix.position = frame.GeodeticFromEnu(frame.EnuFromGeodetic(fix.position) + offsets[flight]);
    ++k;
  }
  GeoreferenceOptions options = MatchingSigmas();
  options.gps_offset = GpsOffsetPolicy::kPerFlight;
  SparseModel model = ArbitraryFrame(scene.tie_model, 121);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, gps, &scene.control, &scene.checks, options);
  SCOPED_TRACE(r.bundle.BriefReport());
  ASSERT_TRUE(r.bundle.gps_offset_estimated);
  ASSERT_EQ(r.bundle.gps_flight_offsets_m.size(), 2u);
  ASSERT_EQ(r.bundle.precision.gps_flight_offset_cov.size(), 2u);
  for (int f = 0; f < 2; ++f) {
    for (int a = 0; a < 3; ++a) {
      const double sigma = std::sqrt(r.bundle.precision.gps_flight_offset_cov[f](a, a));
      const double e = r.bundle.gps_flight_offsets_m[f][a] - offsets[f][a];
      std::printf("flight %d axis %d: %.4f m (truth %.4f, sigma %.4f)\n", f + 1, a, r.bundle.gps_flight_offsets_m[f][a],
                  offsets[f][a], sigma);
      EXPECT_GT(sigma, 0.0);
      EXPECT_LT(sigma, 0.03);
      EXPECT_LT(std::abs(e), 3.0 * sigma) << "flight " << f + 1 << " axis " << a;
    }
  }
  for (const CameraResult& c : r.cameras) {
    if (c.has_prior) { EXPECT_EQ(c.flight, c.name < std::next(gps.begin(), half)->first ? 0 : 1) << c.name; }
  }
  // The GPS residuals (adjusted + offset − GPS) against their sigmas.
  const auto normalised_rms = [](const GeoreferenceReport& report) {
    double sum = 0.0;
    int n = 0;
    for (const CameraResult& c : report.cameras) {
      if (!c.has_prior || c.prior_rejected) continue;
      sum += std::pow(c.d_enu_m.x() / c.sigma_h_m, 2) + std::pow(c.d_enu_m.y() / c.sigma_h_m, 2) +
             std::pow(c.d_enu_m.z() / c.sigma_v_m, 2);
      n += 3;
    }
    return std::sqrt(sum / n);
  };
  const double per_flight = normalised_rms(r);
  std::printf("per flight: sigma0 %.3f, GPS residuals / sigma %.2f RMS\n", r.bundle.sigma0, per_flight);
  EXPECT_GT(r.bundle.sigma0, 0.85);
  EXPECT_LT(r.bundle.sigma0, 1.15);
  EXPECT_GT(per_flight, 0.6);
  EXPECT_LT(per_flight, 1.2);

  options.gps_offset = GpsOffsetPolicy::kAlways;
  SparseModel shared = ArbitraryFrame(scene.tie_model, 121);
  const GeoreferenceReport one = GeoreferenceAndAdjust(&shared, gps, &scene.control, &scene.checks, options);
  const double one_offset = normalised_rms(one);
  std::printf("one shared offset: sigma0 %.3f, GPS residuals / sigma %.2f RMS\n", one.bundle.sigma0, one_offset);
  EXPECT_TRUE(one.bundle.gps_flight_offsets_m.empty());
  EXPECT_GT(one_offset, 1.5 * per_flight);
}

// A GNSS antenna 10 / 10 / 20 cm from the camera centre (camera frame): on a
// lawn-mower block its horizontal part turns with the heading, so no constant
// offset absorbs it. Stated as the lever arm, the GPS residuals fall to the
// RTK noise.
TEST(Georeferencing, LeverArmTurnsWithTheCamera) {
  SyntheticGeorefOptions rtk;
  rtk.gps_sigma_h_m = 0.02;
  rtk.gps_sigma_v_m = 0.03;
  rtk.seed = 121;
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(121), rtk);
  const Eigen::Vector3d lever(0.10, 0.10, -0.20);
  std::map<std::string, GpsFix> gps = scene.gps;
  const LocalFrame frame(rtk.origin);
  for (const Image& image : scene.survey.truth.images) {
    GpsFix& fix = gps.at(image.name);
    fix.position = frame.GeodeticFromEnu(frame.EnuFromGeodetic(fix.position) + image.pose.cam_from_world.conjugate() * lever);
  }
  auto gps_rms_h = [](const GeoreferenceReport& r) {
    double sum = 0.0;
    for (const CameraResult& c : r.cameras) sum += c.d_enu_m.head<2>().squaredNorm();
    return std::sqrt(sum / r.cameras.size());
  };
  GeoreferenceOptions options = MatchingSigmas();
  options.gps_offset = GpsOffsetPolicy::kAlways;
  SparseModel a = ArbitraryFrame(scene.tie_model, 121);
  const GeoreferenceReport without = GeoreferenceAndAdjust(&a, gps, &scene.control, &scene.checks, options);
  options.bundle.gnss_lever_arm_m = lever;
  SparseModel b = ArbitraryFrame(scene.tie_model, 121);
  const GeoreferenceReport with = GeoreferenceAndAdjust(&b, gps, &scene.control, &scene.checks, options);
  std::printf("GPS horizontal residual RMS: %.4f m without the lever arm, %.4f m with it\n", gps_rms_h(without),
              gps_rms_h(with));
  // Two axes of 2 cm noise: about 2.8 cm, less what the adjustment absorbs.
  EXPECT_GT(gps_rms_h(with), 0.015);
  EXPECT_LT(gps_rms_h(with), 0.035);
  EXPECT_GT(gps_rms_h(without), 2.0 * gps_rms_h(with));
  EXPECT_LT(with.bundle.sigma0, 1.1);
  EXPECT_GT(without.bundle.sigma0, with.bundle.sigma0);
}


// A mark outside its image is skipped and said so, with file, line and the
// image's size; never the false "not measured in any image".
TEST(Georeferencing, MarksOutsideTheImageAreNamed) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(131), {});
  GcpFile control = scene.control;
  control.points.at(0).measurements.at(0).xy_px = Eigen::Vector2d(-40.0, 10.0);
  control.points.at(0).measurements.at(0).line = 17;
  SparseModel model = ArbitraryFrame(scene.tie_model, 131);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &control, &scene.checks, Options());
  bool named = false;
  for (const Finding& f : r.findings) {
    if (f.code == "INPUT" && f.message.find("simulated_gcp_list.txt:17: mark (-40.0, 10.0) px is outside image") == 0) {
      named = f.items == std::vector<std::string>{control.points[0].name};
    }
  }
  EXPECT_TRUE(named);
  EXPECT_TRUE(r.control.at(0).solved);  // its other marks still hold it
}


// Control that cannot belong to the survey (here: the northings of two
// points negated, as a wrong hemisphere would) is an error naming them,
// with the true reason, and does not pull the block.
TEST(Georeferencing, ControlOutsideTheSurveyIsAnErrorNamingThePoints) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(141), {});
  GcpFile control = scene.control;
  for (int k : {2, 5}) control.points.at(k).xyz.y() = -control.points[k].xyz.y();
  SparseModel model = ArbitraryFrame(scene.tie_model, 141);
  const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, &control, &scene.checks, Options());
  const Finding* f = nullptr;
  for (const Finding& x : r.findings) {
    if (x.code == "CONTROL_OUTSIDE_SURVEY") f = &x;
  }
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kError);
  EXPECT_EQ(f->items, (std::vector<std::string>{control.points[2].name, control.points[5].name}));
  EXPECT_EQ(SurveyStatus(r.findings), "failed");
  EXPECT_FALSE(r.control.at(2).solved);
  EXPECT_EQ(r.control.at(2).why_not.rfind("outside the survey: ", 0), 0u) << r.control[2].why_not;
  EXPECT_LT(r.check_stats.rmse_3d_m, 0.05);  // the other six hold the datum
  // The clean file: nothing flagged.
  SparseModel clean = ArbitraryFrame(scene.tie_model, 141);
  const GeoreferenceReport ok = GeoreferenceAndAdjust(&clean, scene.gps, &scene.control, &scene.checks, Options());
  for (const Finding& x : ok.findings) EXPECT_NE(x.code, "CONTROL_OUTSIDE_SURVEY");
}

TEST(Georeferencing, ControlNoisierThanStatedIsKeptEstimatedAndSaid) {
  // Handheld-GPS control (1.5 m per axis) in a file that claims 2 / 3 cm.
  SyntheticSurveyOptions so = SurveyOptions(91);
  so.num_control_points = 12;
  SyntheticGeorefOptions geo;
  geo.seed = 91;
  geo.gcp_noise_m = 1.5;
  const SyntheticGeoref scene = MakeSyntheticGeoref(so, geo);
  SparseModel model = ArbitraryFrame(scene.tie_model, 91);
  GeoreferenceOptions o = Options();
  o.gcp_sigma_h_m = 0.02;
  o.gcp_sigma_v_m = 0.03;
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, {}, &scene.control, &scene.checks, o);
  SCOPED_TRACE(report.bundle.BriefReport());
  const auto& cp = report.control_precision;
  ASSERT_TRUE(cp.measured);
  EXPECT_EQ(cp.points, 12) << "every control point is kept";
  EXPECT_EQ(report.helmert_inliers, 12);
  // 12 points, 29 degrees of freedom: the estimate's own sigma is ~13 %.
  EXPECT_NEAR(cp.estimated_m, 1.5, 0.3 * 1.5);
  EXPECT_NEAR(cp.stated_m, std::sqrt((2 * 0.02 * 0.02 + 0.03 * 0.03) / 3), 1e-9);
  EXPECT_TRUE(cp.adopted);
  bool said = false, inconsistent = false;
  for (const Finding& f : report.findings) {
    said = said || f.code == "CONTROL_WEAKER_THAN_STATED";
    inconsistent = inconsistent || f.code == "CONTROL_INCONSISTENT";
  }
  EXPECT_TRUE(said);
  EXPECT_FALSE(inconsistent);
  EXPECT_EQ(report.control_stats.count, 12);
  // The check points carry the same 1.5 m noise (2.6 m in 3D), and the datum
  // of 12 such points adds about a metre.
  ASSERT_EQ(report.check_stats.count, 6);
  EXPECT_GT(report.check_stats.rmse_3d_m, 1.5);
  EXPECT_LT(report.check_stats.rmse_3d_m, 4.5);
  EXPECT_LT(report.bundle.final_rms_px, 1.05 * 0.3 * std::sqrt(2.0)) << "the block is not bent to the control";
}

TEST(Georeferencing, ControlAsGoodAsStatedIsNotFlagged) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(92), {});  // 1 cm noise, 1 cm stated
  SparseModel model = ArbitraryFrame(scene.tie_model, 92);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, {}, &scene.control, &scene.checks, Options());
  ASSERT_TRUE(report.control_precision.measured);
  EXPECT_FALSE(report.control_precision.adopted);
  EXPECT_LT(report.control_precision.estimated_m, 3.0 * report.control_precision.stated_m);
  EXPECT_GT(report.control_precision.estimated_m, 0.3 * report.control_precision.stated_m);
  for (const Finding& f : report.findings) EXPECT_NE(f.code, "CONTROL_WEAKER_THAN_STATED");
}

TEST(Georeferencing, OneTargetLabelledAsTwoPointsIsNamed) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(93), {});
  GcpFile control = scene.control;
  // The first mark of point 0 copied to point 1 (same photo, same pixel).
  ASSERT_GE(control.points.size(), 2u);
  GcpMeasurement copy = control.points[0].measurements.at(0);
  copy.line = 999;
  control.points[1].measurements.push_back(copy);
  SparseModel model = ArbitraryFrame(scene.tie_model, 93);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, &control, &scene.checks, Options());
  const Finding* dup = nullptr;
  for (const Finding& f : report.findings) {
    if (f.code == "MARK_DUPLICATED") dup = &f;
  }
  ASSERT_NE(dup, nullptr);
  const std::string names = control.points[0].name + "/" + control.points[1].name + " in " + copy.image;
  EXPECT_NE(dup->message.find(names), std::string::npos) << dup->message;
  EXPECT_NE(dup->message.find(":999"), std::string::npos) << dup->message;
  ASSERT_EQ(dup->items.size(), 1u);
  // Clean files say nothing.
  SparseModel clean = ArbitraryFrame(scene.tie_model, 93);
  for (const Finding& f : GeoreferenceAndAdjust(&clean, scene.gps, &scene.control, &scene.checks, Options()).findings) {
    EXPECT_NE(f.code, "MARK_DUPLICATED");
  }
}

// The angle (degrees) between two cam_from_world rotations.
double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.normalized() * b.normalized().conjugate()).angle() * 180.0 / M_PI;
}

// A consumer drone's altitude drifting by 100 m over the flight, GPS only
// (the image sigma stated at 1 px for 0.3 px noise: the drift's sigma must
// rest on the GPS's own scatter, not on the tie points'):
// a similarity to those positions tilts the block by tens of degrees; the
// nadir attitude and the drift model keep every camera within 1° of its
// true attitude and recover the drift rate within its sigma.
TEST(Georeferencing, GpsAltitudeDriftIsEstimatedAndDoesNotTiltTheBlock) {
  SyntheticGeorefOptions georef;
  georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, 100.0);
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(41), georef);
  SparseModel model = ArbitraryFrame(scene.tie_model, 41);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  SCOPED_TRACE(report.gps_drift.note);
  const GpsDriftReport& drift = report.gps_drift;
  // The case is hard: the GPS alone would tilt the block by tens of degrees.
  EXPECT_GT(drift.gps_fit_tilt_deg, 10.0);
  ASSERT_TRUE(drift.estimated);
  EXPECT_TRUE(drift.attitude_prior);
  EXPECT_EQ(drift.vertical_source, "nadir");
  EXPECT_FALSE(drift.axes[0]);
  EXPECT_FALSE(drift.axes[1]);
  ASSERT_TRUE(drift.axes[2]);
  ASSERT_EQ(drift.flights.size(), 1u);
  const double duration = georef.seconds_per_photo * (scene.survey.truth.images.size() - 1);
  EXPECT_NEAR(drift.flights[0].duration_s, duration, 1e-6);
  const double true_rate = 100.0 / duration;
  const GpsDriftReport::Flight& f = drift.flights[0];
  ASSERT_GT(f.rate_sigma.z(), 0.0);
  // Within 3 sigma of the truth, and the sigma honest (not inflated to pass).
  EXPECT_LT(std::abs(f.rate_m_per_s.z() - true_rate), 3.0 * f.rate_sigma.z());
  EXPECT_LT(f.rate_sigma.z(), 0.05 * true_rate);
  // Every camera within 1° of its true attitude (the ENU frames of the truth
  // and of the adjustment differ by the distance between their origins:
  // thousandths of a degree).
  std::map<std::string, const Image*> truth;
  for (const Image& image : scene.survey.truth.images) truth[image.name] = &image;
  double worst = 0.0;
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    worst = std::max(worst, RotationAngleDeg(image.pose.cam_from_world, truth.at(image.name)->pose.cam_from_world));
  }
  EXPECT_LT(worst, 1.0);
  EXPECT_LT(report.tilt.mean_axis_tilt_deg, 1.0);
  bool said = false;
  for (const Finding& finding : report.findings) {
    said |= finding.code == "GPS_DRIFT";
    EXPECT_NE(finding.code, "CAMERA_ATTITUDE_IMPLAUSIBLE");
  }
  EXPECT_TRUE(said);
}

// With control the drift is measured against the control datum: estimated,
// the GPS kept (not rejected as inconsistent), the check points at the
// centimetre level.
TEST(Georeferencing, GpsDriftUnderControlIsEstimatedAndTheGpsKept) {
  SyntheticGeorefOptions georef;
  georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, 100.0);
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(42), georef);
  SparseModel model = ArbitraryFrame(scene.tie_model, 42);
  const GeoreferenceReport report =
      GeoreferenceAndAdjust(&model, scene.gps, &scene.control, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  SCOPED_TRACE(report.gps_drift.note);
  const GpsDriftReport& drift = report.gps_drift;
  ASSERT_TRUE(drift.estimated);
  EXPECT_FALSE(drift.attitude_prior);
  ASSERT_EQ(drift.flights.size(), 1u);
  const double true_rate = 100.0 / (georef.seconds_per_photo * (scene.survey.truth.images.size() - 1));
  const GpsDriftReport::Flight& f = drift.flights[0];
  ASSERT_GT(f.rate_sigma.z(), 0.0);
  EXPECT_LT(std::abs(f.rate_m_per_s.z() - true_rate), 3.0 * f.rate_sigma.z());
  EXPECT_LE(report.gps_vs_control.rejected.size(), 2u);
  ASSERT_EQ(report.check_stats.count, 6);
  EXPECT_LT(report.check_stats.rmse_3d_m, 0.08);
}

// Clean GPS: tested, no drift found, no attitude prior (a false drift would
// cost the GPS its say in the tilt).
TEST(Georeferencing, CleanGpsIsNotTakenForADrift) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(43), {});
  SparseModel model = ArbitraryFrame(scene.tie_model, 43);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, Options());
  SCOPED_TRACE(report.gps_drift.note);
  EXPECT_TRUE(report.viewing.nadir) << report.viewing.reason;
  EXPECT_TRUE(report.gps_drift.tested);
  EXPECT_FALSE(report.gps_drift.estimated);
  EXPECT_FALSE(report.gps_drift.attitude_prior);
  EXPECT_LT(report.gps_drift.gps_fit_tilt_deg, 3.0);
  EXPECT_LT(report.tilt.mean_axis_tilt_deg, 3.0);
}

// An oblique block (cameras 30° off nadir towards the image's top, which
// turns north and south strip by strip) whose GPS altitude drifts by 100 m
// over the flight. Its optical axes spread too far for the mean one to be
// taken as the vertical; its gimbal pitches (1° of noise, a compass 8° off,
// roll not stated) give each photo's vertical instead: every camera within
// 1° of its true attitude and the drift recovered within its sigma.
TEST(Georeferencing, ObliqueBlockWithDriftingGpsIsLevelledByItsGimbals) {
  SyntheticSurveyOptions survey = SurveyOptions(45);
  survey.gimbal_pitch_deg = -60.0;
  SyntheticGeorefOptions georef;
  georef.gps_drift_m = Eigen::Vector3d(0.0, 0.0, 100.0);
  const SyntheticGeoref scene = MakeSyntheticGeoref(survey, georef);
  std::mt19937 rng(45);
  std::normal_distribution<double> noise(0.0, 1.0);
  GeoreferenceOptions options = Options();
  for (const Image& image : scene.survey.truth.images) {
    GimbalAttitude a = AttitudeOf(image.pose);
    EXPECT_NEAR(a.pitch_deg, -60.0, 8.0) << image.name;
    a.pitch_deg += noise(rng);
    a.yaw_deg += 8.0 + noise(rng);
    options.gimbal[image.name] = a;
  }
  std::map<std::string, const Image*> truth;
  for (const Image& image : scene.survey.truth.images) truth[image.name] = &image;
  auto worst_attitude_deg = [&](const SparseModel& model) {
    double worst = 0.0;
    for (const Image& image : model.images) {
      if (!image.registered) continue;
      worst = std::max(worst, RotationAngleDeg(image.pose.cam_from_world, truth.at(image.name)->pose.cam_from_world));
    }
    return worst;
  };

  SparseModel model = ArbitraryFrame(scene.tie_model, 45);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, options);
  SCOPED_TRACE(report.bundle.BriefReport());
  SCOPED_TRACE(report.gps_drift.note);
  EXPECT_FALSE(report.viewing.nadir) << report.viewing.reason;
  EXPECT_TRUE(report.gimbal_vertical.usable) << report.gimbal_vertical.reason;
  const GpsDriftReport& drift = report.gps_drift;
  EXPECT_EQ(drift.vertical_source, "gimbal");
  EXPECT_GT(drift.gps_fit_tilt_deg, 10.0);
  EXPECT_TRUE(drift.attitude_prior);
  ASSERT_TRUE(drift.estimated);
  ASSERT_TRUE(drift.axes[2]);
  ASSERT_EQ(drift.flights.size(), 1u);
  const double true_rate = 100.0 / (georef.seconds_per_photo * (scene.survey.truth.images.size() - 1));
  const GpsDriftReport::Flight& f = drift.flights[0];
  ASSERT_GT(f.rate_sigma.z(), 0.0);
  EXPECT_LT(std::abs(f.rate_m_per_s.z() - true_rate), 3.0 * f.rate_sigma.z());
  EXPECT_LT(f.rate_sigma.z(), 0.05 * true_rate);
  EXPECT_LT(worst_attitude_deg(model), 1.0);
  bool said = false;
  for (const Finding& finding : report.findings) said |= finding.code == "GPS_DRIFT";
  EXPECT_TRUE(said);

  // Without the gimbal angles the block has no vertical of its own: the
  // GPS alone tilts it, and the report says its tilt rests on the GPS.
  SparseModel blind = ArbitraryFrame(scene.tie_model, 45);
  const GeoreferenceReport without = GeoreferenceAndAdjust(&blind, scene.gps, nullptr, &scene.checks, Options());
  EXPECT_TRUE(without.gps_drift.vertical_source.empty());
  EXPECT_FALSE(without.gps_drift.attitude_prior);
  EXPECT_GT(worst_attitude_deg(blind), 10.0);
  const Finding* note = nullptr;
  const Finding* error = nullptr;
  for (const Finding& finding : without.findings) {
    if (finding.code == "VERTICAL_FROM_GPS_ONLY") note = &finding;
    if (finding.code == "GROUND_TILTED_BY_GPS") error = &finding;
  }
  ASSERT_NE(note, nullptr);
  // The ground (12 m of relief on a 2 % slope) comes out sloping by the tilt:
  // an error, so the tilted survey is not delivered as if valid.
  EXPECT_GT(without.tilt.ground_slope_deg, 20.0);
  ASSERT_NE(error, nullptr);
  EXPECT_EQ(error->severity, Severity::kError);
  // Levelled by the gimbals the ground is as flat as the truth's.
  EXPECT_LT(report.tilt.ground_slope_deg, 3.0);
  for (const Finding& finding : report.findings) EXPECT_NE(finding.code, "GROUND_TILTED_BY_GPS");
}

// Control in plan only (geo_z 'nan'): its height is the adjustment's; the
// points still hold the plan, are reported without a vertical residual and
// stay out of the 3D statistics; the check points keep their centimetres.
TEST(Georeferencing, HorizontalOnlyControlHoldsThePlanAndLeavesTheHeightFree) {
  const SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(44), {});
  GcpFile control = scene.control;
  ASSERT_GE(control.points.size(), 8u);
  std::set<std::string> plan_only;
  for (size_t k = 0; k < 3; ++k) {
    control.points[k].xyz.z() = std::numeric_limits<double>::quiet_NaN();
    control.points[k].horizontal_only = true;
    plan_only.insert(control.points[k].name);
  }
  SparseModel model = ArbitraryFrame(scene.tie_model, 44);
  const GeoreferenceReport report = GeoreferenceAndAdjust(&model, scene.gps, &control, &scene.checks, Options());
  SCOPED_TRACE(report.bundle.BriefReport());
  EXPECT_EQ(report.control_stats.count, 5);
  int seen = 0;
  for (const GroundPointResult& r : report.control) {
    if (!plan_only.count(r.name)) continue;
    ++seen;
    EXPECT_TRUE(r.horizontal_only);
    ASSERT_TRUE(r.solved) << r.name << ": " << r.why_not;
    EXPECT_TRUE(std::isnan(r.d_m.z()));
    EXPECT_LT(r.d_m.head<2>().norm(), 0.05) << r.name;
  }
  EXPECT_EQ(seen, 3);
  ASSERT_EQ(report.check_stats.count, 6);
  EXPECT_LT(report.check_stats.rmse_3d_m, 0.08);
  for (const Finding& f : report.findings) EXPECT_NE(f.severity, Severity::kError) << f.code << ": " << f.message;
}

// Correlations that betray weak geometry are named; the distortion
// polynomial's own (k2-k3 near -1 in any block) are not a warning.
TEST(Georeferencing, CorrelatedInteriorOrientationIsNamedNotThePolynomial) {
  IntrinsicsPrecision p;
  p.camera = 0;
  p.names = {"f", "cx", "cy", "k1", "k2", "k3"};
  p.correlation.assign(6, std::vector<double>(6, 0.1));
  for (int k = 0; k < 6; ++k) p.correlation[k][k] = 1.0;
  p.correlation[4][5] = p.correlation[5][4] = -0.98;  // k2-k3
  EXPECT_TRUE(IntrinsicsCorrelationFindings({p}).empty());
  p.correlation[0][1] = p.correlation[1][0] = 0.95;  // f-cx
  p.correlation[2][3] = p.correlation[3][2] = -0.93;  // cy-k1
  const std::vector<Finding> f = IntrinsicsCorrelationFindings({p});
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].code, "INTRINSICS_CORRELATED");
  EXPECT_EQ(f[0].items, (std::vector<std::string>{"f-cx", "cy-k1"}));
  EXPECT_NE(f[0].message.find("camera group 1: intrinsics correlated beyond 0.90 (f-cx 0.950, cy-k1 -0.930)"),
            std::string::npos)
      << f[0].message;
}

}  // namespace
}  // namespace aerotri

namespace aerotri {
namespace {

// Issue 10's dome case: a flat nadir grid flown at one altitude, GPS only,
// strong radial distortion (k1 -0.15). The adjusted ground's dome against
// the truth (edge minus centre, fitted on every tie point) is within 2 GSD,
// or the report flags a dome whose amplitude is within 30 % of it. With the
// lens self-calibrated the dome is small; with the distortion held at zero
// (a wrong certificate) it is metres, and flagged at its size.
class FlatSingleAltitudeDome : public ::testing::TestWithParam<bool> {};

TEST_P(FlatSingleAltitudeDome, IsSmallOrFlaggedWithItsAmplitude) {
  const bool distortion_held = GetParam();
  for (std::uint32_t seed = 60; seed < 62; ++seed) {
    SyntheticSurveyOptions so = SurveyOptions(seed);
    so.relief_m = 0.0;
    so.brown_params[3] = -0.15;
    so.brown_params[4] = 0.0;
    so.num_check_points = 20;
    SyntheticGeorefOptions go;
    go.seed = seed;
    const SyntheticGeoref scene = MakeSyntheticGeoref(so, go);
    SparseModel model = ArbitraryFrame(scene.tie_model, seed);  // distortion starts at zero
    GeoreferenceOptions options = Options();
    if (distortion_held) {
      options.auto_refine = false;
      options.bundle.refine_intrinsics = IntrinsicsRefinement::kFocal;
    }
    const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, options);
    // The truth's dome: every adjusted tie point's height error.
    const LocalFrame truth_frame(go.origin);
    const LocalFrame frame(r.enu_origin);
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const Image& image : scene.survey.truth.images) centre += image.pose.centre_in_world.head<2>();
    centre /= static_cast<double>(scene.survey.truth.images.size());
    double radius = 0.0;
    for (const Image& image : scene.survey.truth.images) {
      radius = std::max(radius, (image.pose.centre_in_world.head<2>() - centre).norm());
    }
    std::vector<Eigen::Vector2d> xy;
    std::vector<double> dz;
    size_t k = 0;
    for (const Point& truth : scene.survey.truth.points) {
      if (truth.role != PointRole::kTie) continue;
      ASSERT_LT(k, model.points.size());
      const Point& adjusted = model.points[k++];
      ASSERT_EQ(adjusted.role, PointRole::kTie);
      xy.push_back(truth.position.head<2>());
      dz.push_back(truth_frame.EnuFromGeodetic(frame.GeodeticFromEnu(adjusted.position)).z() - truth.position.z());
    }
    const DomeTest truth = FitDome(xy, dz, centre, radius, "truth");
    const double gsd = scene.survey.gsd_m;
    bool flagged = false;
    for (const Finding& f : r.findings) flagged |= f.code == "DOME";
    std::printf("%s, seed %u: dome %.3f m (%.1f GSD) against the truth; reported %.3f +- %.3f m from %d %s%s\n",
                distortion_held ? "distortion held at 0" : "self-calibrated", seed, truth.amplitude_m,
                std::abs(truth.amplitude_m) / gsd, r.dome.amplitude_m, r.dome.amplitude_sigma_m, r.dome.points,
                r.dome.source.c_str(), flagged ? ", flagged" : "");
    if (distortion_held) {
      // Metres of dome: the case must be flagged, at its size.
      EXPECT_GT(std::abs(truth.amplitude_m), 20 * gsd);
      EXPECT_TRUE(flagged);
      EXPECT_NEAR(r.dome.amplitude_m, truth.amplitude_m, 0.3 * std::abs(truth.amplitude_m));
    } else {
      EXPECT_TRUE(std::abs(truth.amplitude_m) <= 2.0 * gsd ||
                  (flagged && std::abs(r.dome.amplitude_m - truth.amplitude_m) <= 0.3 * std::abs(truth.amplitude_m)));
      EXPECT_NEAR(model.cameras[0].params[3], -0.15, 0.005);  // k1 recovered
    }
  }
}
INSTANTIATE_TEST_SUITE_P(Georeferencing, FlatSingleAltitudeDome, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? std::string("DistortionHeld") : std::string("SelfCalibrated");
                         });

// A consumer GPS: 12 m of noise per axis in a file that states 3 m. Poor,
// not inconsistent: the survey is delivered (never failed), the adjustment
// estimates the GPS's sigma within 30 % of the truth, and the placement it
// states is honest: check-point errors over their predicted sigmas have an
// RMS near 1 over the seeds (each seed one realisation of the datum).
TEST(Georeferencing, PoorGpsIsDeliveredWithItsPlacementStated) {
  double sum = 0.0, gps_sigma = 0.0;
  int n = 0, seeds = 0;
  for (std::uint32_t seed = 4; seed < 12; ++seed, ++seeds) {
    SyntheticGeorefOptions georef;
    georef.seed = seed;
    georef.gps_sigma_h_m = 12.0;
    georef.gps_sigma_v_m = 12.0;
    SyntheticGeoref scene = MakeSyntheticGeoref(SurveyOptions(seed), georef);
    for (auto& [name, fix] : scene.gps) fix.sigma_h_m = fix.sigma_v_m = 3.0;
    GeoreferenceOptions options = MatchingSigmas();
    options.bundle.estimate_variance_components = true;
    SparseModel model = ArbitraryFrame(scene.tie_model, seed);
    const GeoreferenceReport r = GeoreferenceAndAdjust(&model, scene.gps, nullptr, &scene.checks, options);
    SCOPED_TRACE(r.bundle.BriefReport());
    EXPECT_NE(SurveyStatus(r.findings), "failed") << seed;
    bool stated = false;
    for (const Finding& f : r.findings) {
      EXPECT_NE(f.code, "GPS_MOSTLY_INCONSISTENT") << f.message;
      EXPECT_NE(f.code, "PRIORS_INCONSISTENT") << f.message;
      stated |= f.code == "SIGMAS_OPTIMISTIC" && f.message.find("placement") != std::string::npos;
    }
    EXPECT_TRUE(stated) << "the placement is said";
    EXPECT_TRUE(r.placement.computed);
    for (const VarianceComponent& vc : r.bundle.variance_components) {
      if (vc.group == ObservationGroup::kGpsHorizontal) gps_sigma += vc.EstimatedSigma();
    }
    for (const GroundPointResult& p : r.check) {
      if (!p.tested) continue;
      for (int a = 0; a < 3; ++a) {
        sum += p.w[a] * p.w[a];
        ++n;
      }
    }
  }
  gps_sigma /= seeds;
  const double rms = std::sqrt(sum / std::max(n, 1));
  std::printf("GPS 12 m stated 3 m: estimated %.2f m; check error / predicted sigma RMS %.3f (%d axes)\n",
              gps_sigma, rms, n);
  EXPECT_GT(gps_sigma, 0.7 * 12.0);
  EXPECT_LT(gps_sigma, 1.3 * 12.0);
  // Eight realisations of a datum (7 numbers each) over 18 axes: a wide band.
  EXPECT_GT(rms, 0.6);
  EXPECT_LT(rms, 1.4);
}

// Systematic errors injected into one clean block, each named for what it
// is; the clean block raises none of them.
class InjectedErrors : public ::testing::Test {
 protected:
  void SetUp() override { scene_ = MakeSyntheticGeoref(SurveyOptions(61), {}); }
  GeoreferenceReport Adjust(const GcpFile& control, const GcpFile& checks) const {
    GeoreferenceOptions options = MatchingSigmas();
    options.bundle.estimate_variance_components = true;
    SparseModel model = ArbitraryFrame(scene_.tie_model, 61);
    return GeoreferenceAndAdjust(&model, {}, &control, &checks, options);
  }
  static const Finding* Find(const GeoreferenceReport& r, const std::string& code) {
    for (const Finding& f : r.findings) {
      if (f.code == code) return &f;
    }
    return nullptr;
  }
  SyntheticGeoref scene_;
};

TEST_F(InjectedErrors, TheCleanBlockRaisesNone) {
  const GeoreferenceReport r = Adjust(scene_.control, scene_.checks);
  for (const char* code : {"MARKS_OFFSET", "MARK_BLUNDER", "CHECK_POINTS_FAR", "CHECK_POINTS_OFFSET"}) {
    const Finding* f = Find(r, code);
    EXPECT_EQ(f, nullptr) << code << ": " << (f ? f->message : "");
  }
  EXPECT_EQ(r.check_test.tests, 3 * static_cast<int>(scene_.checks.points.size()));
  EXPECT_TRUE(r.check_test.posterior);
}

// Every target mark of the photo that sees most of them, 2 px to the right.
TEST_F(InjectedErrors, OnePhotosMarksShiftedAreNamedAsItsOffset) {
  std::map<std::string, int> count;
  for (const GroundPoint& g : scene_.control.points) {
    for (const GcpMeasurement& m : g.measurements) ++count[m.image];
  }
  std::string image;
  for (const auto& [name, k] : count) {
    if (image.empty() || k > count[image]) image = name;
  }
  ASSERT_GE(count[image], 3);
  GcpFile control = scene_.control;
  for (GroundPoint& g : control.points) {
    for (GcpMeasurement& m : g.measurements) {
      if (m.image == image) m.xy_px.x() += 2.0;
    }
  }
  const GeoreferenceReport r = Adjust(control, scene_.checks);
  const Finding* f = Find(r, "MARKS_OFFSET");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->items, std::vector<std::string>{image}) << f->message;
  EXPECT_NE(f->message.find("in x"), std::string::npos) << f->message;
  const Finding* blunder = Find(r, "MARK_BLUNDER");
  if (blunder) {
    EXPECT_EQ(blunder->message.find(image), std::string::npos) << blunder->message;
  }
  EXPECT_NE(SurveyStatus(r.findings), "failed");
}

// One check point surveyed 5 of its predicted sigmas off in y: named alone,
// as the one the others do not back.
TEST_F(InjectedErrors, ACheckPointSurveyedOffIsNamedAlone) {
  const GeoreferenceReport clean = Adjust(scene_.control, scene_.checks);
  ASSERT_FALSE(clean.check.empty());
  const GroundPointResult& target = clean.check.at(2);
  ASSERT_TRUE(target.tested);
  GcpFile checks = scene_.checks;
  for (GroundPoint& g : checks.points) {
    // Surveyed where the block puts it, less 5 sigma: its residual is 5 sigma.
    if (g.name == target.name) g.xyz.y() += target.d_m.y() - 5.0 * target.predicted_sigma_m.y();
  }
  const GeoreferenceReport r = Adjust(scene_.control, checks);
  const Finding* f = Find(r, "CHECK_POINTS_FAR");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kWarning);
  EXPECT_EQ(f->items, std::vector<std::string>{target.name}) << f->message;
  EXPECT_NE(f->message.find("the others agree"), std::string::npos) << f->message;
  for (const GroundPointResult& p : r.check) {
    if (p.name == target.name) {
      EXPECT_NEAR(p.w.y(), 5.0, 0.05);
    }
  }
}

// The whole control 10 m east of where it was surveyed (another datum):
// the survey moves with it, the check points show the common offset, and
// the survey fails for it.
TEST_F(InjectedErrors, ControlShiftedTenMetresFailsAsAnOffset) {
  GcpFile control = scene_.control;
  for (GroundPoint& g : control.points) g.xyz.x() += 10.0;
  const GeoreferenceReport r = Adjust(control, scene_.checks);
  const Finding* f = Find(r, "CHECK_POINTS_OFFSET");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kError);
  EXPECT_EQ(SurveyStatus(r.findings), "failed");
  EXPECT_NE(f->message.find("different datums"), std::string::npos) << f->message;
  EXPECT_EQ(f->message.find("GPS"), std::string::npos) << "no GPS in this block: " << f->message;
  EXPECT_NEAR(r.check_stats.mean_x_m, 10.0, 0.1);
  EXPECT_NEAR(r.check_stats.mean_y_m, 0.0, 0.1);
}

}  // namespace
}  // namespace aerotri
