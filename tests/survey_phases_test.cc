// SPDX-License-Identifier: BSD-3-Clause
// The survey adjustment's phases run alone (survey_phases.h), on a synthetic
// survey with known truth (46.5 N, 7.5 E; UTM 32N; 8 control points with
// 1 cm survey noise, 0.3 px marks) handed over in an arbitrary frame.
#include "libphoto/survey/survey_phases.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "libphoto/base/error.h"
#include "libphoto/simulate/synthetic_georef.h"
#include "libphoto/survey/quality_gates.h"

namespace aerotri {
namespace {

SyntheticGeoref Scene() {
  SyntheticSurveyOptions o;
  o.seed = 5;
  o.area_width_m = 200.0;
  o.area_height_m = 150.0;
  o.num_tie_points = 600;
  o.pixel_noise_px = 0.3;
  o.num_control_points = 8;
  o.num_check_points = 4;
  return MakeSyntheticGeoref(o, {});
}

// The model 20 times smaller, turned and moved: what another tool hands over.
const Similarity& Arbitrary() {
  static const Similarity s = [] {
    Similarity t;
    t.scale = 0.05;
    t.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()));
    t.translation = Eigen::Vector3d(3, -4, 5);
    return t;
  }();
  return s;
}

GcpFile OneTarget(const std::vector<std::pair<std::string, Eigen::Vector2d>>& marks) {
  GcpFile file;
  file.path = "gcp_list.txt";
  file.crs = "EPSG:32632";
  int line = 2;
  for (const auto& [name, xy] : marks) {
    GroundPoint p;
    p.name = name;
    p.xyz = Eigen::Vector3d(400000, 5150000, 500);
    p.measurements.push_back({"a.jpg", xy, line++, std::nullopt});
    file.points.push_back(p);
  }
  return file;
}

// Velocities from a GPS track: two strips flown at 12 m/s, photos every
// 2 s, a 25 s turn between them, positions with 5 cm of noise. Inside a
// strip the central difference gives the velocity to the noise's share
// (0.05·√2 / 4 s ≈ 0.02 m/s per axis); the strip's ends take their one
// neighbour's;
// a photo whose two neighbours disagree (here one across a sharp corner) is
// left out, as is one without a neighbour within the gap.
TEST(SurveyPhases, VelocitiesFromTheGpsTrackFollowEachStripAndSkipTheTurns) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::vector<TrackFix> fixes;
  auto add = [&](const std::string& name, const Eigen::Vector3d& p, double t) {
    fixes.push_back({name, p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)), t});
  };
  for (int k = 0; k < 8; ++k) add("east" + std::to_string(k), Eigen::Vector3d(24.0 * k, 0.0, 80.0), 2.0 * k);
  for (int k = 0; k < 8; ++k) add("west" + std::to_string(k), Eigen::Vector3d(168.0 - 24.0 * k, 40.0, 80.0), 39.0 + 2.0 * k);
  // A corner: east, then north at once.
  add("c0", Eigen::Vector3d(0.0, 500.0, 80.0), 100.0);
  add("c1", Eigen::Vector3d(24.0, 500.0, 80.0), 102.0);
  add("c2", Eigen::Vector3d(24.0, 524.0, 80.0), 104.0);
  add("alone", Eigen::Vector3d(900.0, 900.0, 80.0), 200.0);
  std::shuffle(fixes.begin(), fixes.end(), rng);  // any order in, time order used
  const std::map<std::string, Eigen::Vector3d> v = VelocitiesFromTrack(fixes, 3.0);
  double worst = 0.0;
  for (int k = 0; k < 8; ++k) {
    ASSERT_TRUE(v.count("east" + std::to_string(k)));
    ASSERT_TRUE(v.count("west" + std::to_string(k)));
    // 3 sigma of the difference's noise on each of 3 axes: 0.05·√2 / Δt per
    // axis, Δt 4 s inside a strip, 2 s (one-sided) at its ends.
    const double tol = 3.0 * std::sqrt(3.0) * 0.05 * std::sqrt(2.0) / ((k == 0 || k == 7) ? 2.0 : 4.0);
    const double e = (v.at("east" + std::to_string(k)) - Eigen::Vector3d(12.0, 0.0, 0.0)).norm();
    const double w = (v.at("west" + std::to_string(k)) - Eigen::Vector3d(-12.0, 0.0, 0.0)).norm();
    EXPECT_LT(e, tol) << k;
    EXPECT_LT(w, tol) << k;
    worst = std::max({worst, e, w});
  }
  EXPECT_GT(worst, 0.001);  // the noise shows: nothing was read from the truth
  EXPECT_EQ(v.count("c1"), 0u);
  EXPECT_TRUE(v.count("c0") && v.count("c2"));
  EXPECT_EQ(v.count("alone"), 0u);
  EXPECT_EQ(v.size(), 18u);
}

TEST(SurveyPhases, TwoNamesOnOneTargetAreSaidWithTheirLines) {
  const GcpFile twice = OneTarget({{"A", {100.0, 200.0}}, {"B", {101.0, 201.0}}});
  const std::optional<Finding> finding = CheckDuplicatedMarks(&twice, nullptr);
  ASSERT_TRUE(finding.has_value());
  EXPECT_EQ(finding->code, "MARK_DUPLICATED");
  EXPECT_NE(finding->message.find("A/B in a.jpg (gcp_list.txt:2 and gcp_list.txt:3)"), std::string::npos)
      << finding->message;
  // 3 px apart: two targets.
  const GcpFile apart = OneTarget({{"A", {100.0, 200.0}}, {"B", {103.0, 200.0}}});
  EXPECT_FALSE(CheckDuplicatedMarks(&apart, nullptr).has_value());
}

TEST(SurveyPhases, FrameAndDatumFollowTheGpsAndTheControlFile) {
  const SyntheticGeoref scene = Scene();
  SparseModel model = scene.tie_model;
  const GeoreferenceOptions options;  // no --crs: the control file's
  SurveyState s = StartSurvey(&model, scene.gps, &scene.control, &scene.checks, options);
  ChooseFrameAndDatum(&s);
  EXPECT_EQ(s.report.crs_source, "control file");
  EXPECT_EQ(s.report.crs, "EPSG:32632");
  EXPECT_FALSE(s.local);
  EXPECT_EQ(s.surveyed.size(), scene.control.points.size() + scene.checks.points.size());
  // The ENU origin is the mean GPS: within a few metres (GPS noise 2 / 4 m)
  // of the truth's mean camera position, which is about 60 m above ground.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Image& image : scene.survey.truth.images) mean += image.pose.centre_in_world;
  mean /= scene.survey.truth.images.size();
  const LocalFrame truth_frame(SyntheticGeorefOptions{}.origin);
  const Eigen::Vector3d origin_in_truth = truth_frame.EnuFromGeodetic(s.report.enu_origin);
  EXPECT_LT((origin_in_truth - mean).head<2>().norm(), 2.0);
  EXPECT_LT(std::abs(origin_in_truth.z() - mean.z()), 4.0);
  EXPECT_GT((origin_in_truth - mean).norm(), 1e-4);  // the GPS's, not the truth's
}

TEST(SurveyPhases, LocalControlRefusesGeodeticGps) {
  const SyntheticGeoref scene = Scene();
  SparseModel model = scene.tie_model;
  GcpFile local = scene.control;
  local.crs = "LOCAL";
  const GeoreferenceOptions options;
  SurveyState s = StartSurvey(&model, scene.gps, &local, nullptr, options);
  EXPECT_THROW(ChooseFrameAndDatum(&s), InvalidArgument);
}

TEST(SurveyPhases, InitialSimilarityFromControlRecoversTheScale) {
  const SyntheticGeoref scene = Scene();
  SparseModel model = scene.tie_model;
  for (Image& image : model.images) {
    image.pose.centre_in_world = Arbitrary().Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * Arbitrary().rotation.conjugate()).normalized();
  }
  for (Point& point : model.points) point.position = Arbitrary().Apply(point.position);
  const GeoreferenceOptions options;
  SurveyState s = StartSurvey(&model, scene.gps, &scene.control, &scene.checks, options);
  ChooseFrameAndDatum(&s);
  AttachPriors(&s);
  FitInitialSimilarity(&s);
  ASSERT_TRUE(s.control_datum);
  EXPECT_EQ(s.report.helmert_inliers, 8);
  EXPECT_EQ(s.report.datum_source.rfind("control points (8 of 8", 0), 0u) << s.report.datum_source;
  // The block's size is the truth's: control of 1 cm over ~200 m holds the
  // scale to 1e-4, the triangulated marks (0.3 px, ~2 cm) to a few 1e-4.
  const Image& first = model.images.front();
  const Image& last = model.images.back();
  const double truth = (scene.survey.truth.images.back().pose.centre_in_world -
                        scene.survey.truth.images.front().pose.centre_in_world)
                           .norm();
  const double adjusted = (last.pose.centre_in_world - first.pose.centre_in_world).norm();
  EXPECT_NEAR(adjusted / truth, 1.0, 2e-3);
  EXPECT_GT(std::abs(adjusted / truth - 1.0), 1e-7);  // fitted, not copied
  // The control residuals of the fit are at the noise: centimetres.
  EXPECT_LT(s.report.helmert_rms_m, 0.1);
  EXPECT_GT(s.report.helmert_rms_m, 0.001);
}

// The control file in EPSG:4326, longitude first (aerotri's order), or
// latitude first (the common mistake).
GcpFile Geographic(const GcpFile& control, bool latitude_first) {
  GcpFile file = control;
  file.crs = "EPSG:4326";
  const Crs utm = Crs::FromString(control.crs);
  for (GroundPoint& p : file.points) {
    const Geodetic g = utm.ToGeodetic(p.xyz);
    p.xyz = latitude_first ? Eigen::Vector3d(g.lat_deg, g.lon_deg, g.h_m) : Eigen::Vector3d(g.lon_deg, g.lat_deg, g.h_m);
  }
  return file;
}

bool HasFinding(const GeoreferenceReport& report, const std::string& code, std::string* message = nullptr) {
  for (const Finding& f : report.findings) {
    if (f.code != code) continue;
    if (message) *message = f.message;
    return true;
  }
  return false;
}

TEST(SurveyPhases, GeographicControlWithLatitudeFirstIsNamedSwappedBeforeAnyAdjustment) {
  const SyntheticGeoref scene = Scene();
  const GeoreferenceOptions options;
  for (const bool swapped : {false, true}) {
    SparseModel model = scene.tie_model;
    const GcpFile control = Geographic(scene.control, swapped);
    SurveyState s = StartSurvey(&model, scene.gps, &control, nullptr, options);
    ChooseFrameAndDatum(&s);
    AttachPriors(&s);
    std::string message;
    EXPECT_EQ(HasFinding(s.report, "CONTROL_OUTSIDE_SURVEY", &message), swapped) << message;
    if (!swapped) continue;
    EXPECT_NE(message.find("8 surveyed points lie outside"), std::string::npos) << message;
    EXPECT_NE(message.find("Read with the first two columns swapped, every one of them lies inside the survey"),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("longitude, latitude"), std::string::npos) << message;
  }
}

TEST(SurveyPhases, ControlNegatedIsNamedSo) {
  const SyntheticGeoref scene = Scene();
  SparseModel model = scene.tie_model;
  GcpFile control = Geographic(scene.control, false);
  for (GroundPoint& p : control.points) p.xyz.x() = -p.xyz.x();  // 7.5 W for 7.5 E
  const GeoreferenceOptions options;
  SurveyState s = StartSurvey(&model, scene.gps, &control, nullptr, options);
  ChooseFrameAndDatum(&s);
  AttachPriors(&s);
  std::string message;
  ASSERT_TRUE(HasFinding(s.report, "CONTROL_OUTSIDE_SURVEY", &message));
  EXPECT_NE(message.find("Read with the first column negated"), std::string::npos) << message;
}

TEST(SurveyPhases, ControlHeightsAllZeroAreTakenAsUnknownUnlessStated) {
  const SyntheticGeoref scene = Scene();
  GcpFile control = scene.control;
  for (GroundPoint& p : control.points) p.xyz.z() = 0.0;
  for (const bool stated : {false, true}) {
    SparseModel model = scene.tie_model;
    GeoreferenceOptions options;
    options.zero_heights_are_heights = stated;
    SurveyState s = StartSurvey(&model, scene.gps, &control, nullptr, options);
    ChooseFrameAndDatum(&s);
    EXPECT_EQ(HasFinding(s.report, "CONTROL_HEIGHTS_ZERO"), !stated);
    int in_plan = 0;
    for (const SurveyedPoint& p : s.surveyed) in_plan += p.source->horizontal_only;
    EXPECT_EQ(in_plan, stated ? 0 : static_cast<int>(control.points.size()));
  }
  // One real height among the zeros: heights, as given.
  control.points[0].xyz.z() = 512.0;
  SparseModel model = scene.tie_model;
  const GeoreferenceOptions options;
  SurveyState s = StartSurvey(&model, scene.gps, &control, nullptr, options);
  ChooseFrameAndDatum(&s);
  EXPECT_FALSE(HasFinding(s.report, "CONTROL_HEIGHTS_ZERO"));
}

// The check-point gate alone, on residuals stated by hand: posterior sigmas
// of 5 cm, no survey sigma (no priors in the empty model).
GeoreferenceReport ChecksWithResiduals(const std::vector<Eigen::Vector3d>& residuals) {
  GeoreferenceReport r;
  r.datum_source = "control points (8 of 8 in the initial similarity)";
  for (size_t k = 0; k < residuals.size(); ++k) {
    GroundPointResult p;
    p.name = "C" + std::to_string(k);
    p.role = PointRole::kCheck;
    p.solved = true;
    p.d_m = residuals[k];
    p.has_precision = true;
    p.sigma_m = Eigen::Vector3d::Constant(0.05);
    r.check.push_back(p);
  }
  return r;
}

const Finding* Only(const GeoreferenceReport& r, const std::string& code) {
  const Finding* found = nullptr;
  for (const Finding& f : r.findings) {
    if (f.code == code) found = &f;
  }
  return found;
}

TEST(CheckPointGates, ResidualsWithinTheirSigmasPass) {
  GeoreferenceReport r = ChecksWithResiduals({{0.05, -0.03, 0.08}, {-0.06, 0.02, -0.04}, {0.01, 0.09, 0.0}});
  CheckPointGates(SparseModel(), QualityGates(), &r);
  EXPECT_TRUE(r.findings.empty());
  EXPECT_EQ(r.check_test.tests, 9);
  EXPECT_NEAR(r.check_test.critical_value, FamilyWiseCriticalValue(9, 0.01), 1e-12);
  EXPECT_NEAR(r.check[0].w.z(), 0.08 / 0.05, 1e-12);
}

TEST(CheckPointGates, OnePointOffIsAWarningNamingIt) {
  GeoreferenceReport r = ChecksWithResiduals({{0.05, -0.03, 0.08}, {-0.06, 0.40, -0.04}, {0.01, 0.09, 0.0}});
  CheckPointGates(SparseModel(), QualityGates(), &r);
  const Finding* f = Only(r, "CHECK_POINTS_FAR");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kWarning);
  EXPECT_EQ(f->items, std::vector<std::string>{"C1"});
  EXPECT_NE(f->message.find("C1 (w 8.0 in y)"), std::string::npos) << f->message;
  EXPECT_NE(f->message.find("the others agree"), std::string::npos) << f->message;
}

// A common offset far beyond the sigmas: the survey is misplaced against
// its check points (another datum), said with the offset; no GPS here, so
// no GPS in the reasons.
TEST(CheckPointGates, ACommonOffsetFailsTheSurvey) {
  GeoreferenceReport r =
      ChecksWithResiduals({{10.02, 0.01, -0.03}, {9.96, -0.04, 0.05}, {10.05, 0.03, 0.01}, {9.99, 0.0, -0.02}});
  CheckPointGates(SparseModel(), QualityGates(), &r);
  const Finding* f = Only(r, "CHECK_POINTS_OFFSET");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kError);
  EXPECT_NE(f->message.find("(10.005, 0.000, 0.003) m"), std::string::npos) << f->message;
  EXPECT_EQ(f->message.find("GPS"), std::string::npos) << f->message;
}

// A layout turned by 180 degrees: residuals far beyond any sigma that share
// no offset: failed, not explained as an offset.
TEST(CheckPointGates, ResidualsFarBeyondAnySigmaFailTheSurvey) {
  GeoreferenceReport r =
      ChecksWithResiduals({{100.0, 40.0, 0.1}, {-100.0, -40.0, -0.1}, {60.0, -80.0, 0.0}, {-60.0, 80.0, 0.2}});
  CheckPointGates(SparseModel(), QualityGates(), &r);
  EXPECT_EQ(Only(r, "CHECK_POINTS_OFFSET"), nullptr);
  const Finding* f = Only(r, "CHECK_POINTS_FAR");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->severity, Severity::kError);
  EXPECT_EQ(f->items.size(), 4u);
}

// Without posterior sigmas, the datum's and a floor stand in: 2 cm.
TEST(CheckPointGates, WithoutAPosteriorTheDatumsSigmasStandIn) {
  GeoreferenceReport r = ChecksWithResiduals({{0.03, 0.0, 0.0}, {0.0, 0.03, 0.0}});
  for (GroundPointResult& p : r.check) p.has_precision = false;
  CheckPointGates(SparseModel(), QualityGates(), &r);
  EXPECT_FALSE(r.check_test.posterior);
  EXPECT_NEAR(r.check[0].predicted_sigma_m.x(), QualityGates().min_check_threshold_m / 5.0, 1e-12);
  EXPECT_TRUE(r.findings.empty());
}

}  // namespace
}  // namespace aerotri
