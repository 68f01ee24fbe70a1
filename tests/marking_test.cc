// SPDX-License-Identifier: BSD-3-Clause
// Control from coordinates alone: a rendered survey with each target kind,
// reconstructed by the pipeline, its targets marked by the mark stage and
// compared with their true centres (truth/marks.txt); a coordinates file
// with a point no photo sees, a point 30 m off its target and two points
// on one target, each reported as such; and the survey adjusted from the
// marks against the same survey from its truth marks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>

#include <nlohmann/json.hpp>

#include "georef/gcp_file.h"
#include "libphoto/base/atomic_file.h"
#include "georef/crs.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/survey/survey_phases.h"
#include "libphoto/targets/marking.h"
#include "libphoto/simulate/survey_writer.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

namespace fs = std::filesystem;

struct Kind {
  TargetPattern pattern;
  const char* name;
};

class Marking : public ::testing::TestWithParam<Kind> {
 protected:
  void SetUp() override {
    SimulationOptions sim;
    sim.survey.seed = 9;
    sim.survey.width = 1200;
    sim.survey.height = 900;
    sim.survey.brown_params = {950.0, 602.0, 448.0, -0.08, 0.05, -0.01, 0.0005, -0.0003};
    sim.survey.area_width_m = 60.0;
    sim.survey.area_height_m = 40.0;
    sim.survey.flight_height_m = 28.0;  // GSD 2.9 cm: a 1 m target 34 px across, a cross's bars 5 px
    sim.survey.num_tie_points = 500;
    sim.survey.num_control_points = 6;
    sim.survey.num_check_points = 4;
    sim.georef.seed = 9;
    sim.target_pattern = GetParam().pattern;
    WriteSyntheticSurvey(sim, dir_ / "survey");
    o_.images_dir = dir_ / "survey" / "images";
    o_.workspace = dir_ / "ws";
    o_.num_threads = 2;
    RunIngestStage(o_);
    RunFeatureStage(o_);
    RunMatchStage(o_);
    RunReconstructStage(o_);
  }
  testing::TempDir dir_;
  PipelineOptions o_;
};

// Every mark against the truth: *median and *worst in px; returns how many
// true marks (targets wholly inside a photo) were not marked.
int CompareWithTruth(const fs::path& truth_file, const std::vector<fs::path>& marks, double* median, double* worst,
                     int* extra) {
  std::map<std::pair<std::string, std::string>, Eigen::Vector2d> truth, got;
  const GcpFile t = ReadGcpFile(truth_file);
  for (const GroundPoint& p : t.points) {
    for (const GcpMeasurement& m : p.measurements) truth[{p.name, m.image}] = m.xy_px;
  }
  for (const fs::path& path : marks) {
    for (const GroundPoint& p : ReadGcpFile(path).points) {
      for (const GcpMeasurement& m : p.measurements) got[{p.name, m.image}] = m.xy_px;
    }
  }
  std::vector<double> errors;
  int missing = 0;
  *extra = 0;
  for (const auto& [key, xy] : truth) {
    const auto it = got.find(key);
    if (it != got.end()) {
      errors.push_back((it->second - xy).norm());
    } else if (xy.x() > 40 && xy.y() > 40 && xy.x() < 1160 && xy.y() < 860) {
      ++missing;  // a target wholly in the photo, not marked
      std::printf("  not marked: %s in %s at (%.1f, %.1f)\n", key.first.c_str(), key.second.c_str(), xy.x(), xy.y());
    }
  }
  for (const auto& [key, xy] : got) *extra += !truth.count(key);
  std::sort(errors.begin(), errors.end());
  *median = errors.empty() ? NAN : errors[errors.size() / 2];
  *worst = errors.empty() ? NAN : errors.back();
  return missing;
}

// The data of a review page (marks.html): the JSON its script reads.
nlohmann::json ReviewPageData(const fs::path& page) {
  const std::string html = ReadTextFile(page);
  const std::string open = "<script type='application/json' id='data'>";
  const size_t begin = html.find(open), end = html.find("</script>", begin);
  if (begin == std::string::npos || end == std::string::npos) return nullptr;
  return nlohmann::json::parse(html.substr(begin + open.size(), end - begin - open.size()));
}

TEST_P(Marking, TargetsAreMarkedAtTheirTrueCentresAndTheSurveyMatchesTheTruthMarks) {
  o_.gcp = dir_ / "survey" / "gcp_coordinates.txt";
  o_.checkpoints = dir_ / "survey" / "check_coordinates.txt";
  ASSERT_TRUE(NeedsMarking(o_));
  ASSERT_TRUE(RunMarkStage(o_));
  double median = 0, worst = 0;
  int extra = 0;
  const int missing = CompareWithTruth(dir_ / "survey" / "truth" / "marks.txt",
                                       {o_.workspace / "gcp_marks.txt", o_.workspace / "check_marks.txt"}, &median,
                                       &worst, &extra);
  std::printf("%s targets: median %.3f px, worst %.3f px, %d visible not marked, %d marks of nothing\n",
              GetParam().name, median, worst, missing, extra);
  // Measured at this GSD (cross bars 5 px): of about 100 visible marks per
  // kind, none left unmarked; median 0.014-0.030 px, worst 0.06-0.12 px
  // against centres rendered 8 x 8 supersampled.
  EXPECT_EQ(extra, 0);
  EXPECT_EQ(missing, 0);
  EXPECT_LT(median, 0.05);
  EXPECT_LT(worst, 0.15);
  const nlohmann::json marks = nlohmann::json::parse(ReadTextFile(o_.workspace / "marks.json"));
  EXPECT_GE(marks["control"]["marked"], 5);
  EXPECT_EQ(marks["checks"]["marked"], 4);
  // The review page: every point, a chip of every photo it was predicted in,
  // the coordinates' fields for the export; no residuals before adjusting.
  const nlohmann::json page = ReviewPageData(o_.workspace / "marks.html");
  ASSERT_TRUE(page.is_object());
  EXPECT_FALSE(page["adjusted"].get<bool>());
  ASSERT_EQ(page["points"].size(), marks["points"].size());
  for (size_t i = 0; i < page["points"].size(); ++i) {
    const auto& p = page["points"][i];
    EXPECT_EQ(p["name"], marks["points"][i]["name"]);
    EXPECT_FALSE(p["coordinates"].get<std::string>().empty()) << p["name"];
    EXPECT_EQ(p["photos"].size(), marks["points"][i]["photos"].size()) << p["name"];
    for (const auto& c : p["photos"]) {
      EXPECT_EQ(c["chip"].get<std::string>().rfind("data:image/jpeg;base64,", 0), 0u) << p["name"] << " " << c["image"];
    }
  }
  EXPECT_EQ(page["files"]["control"]["crs"], ReadGcpFile(o_.gcp).crs);
  // A rerun with the same inputs is done already.
  EXPECT_FALSE(RunMarkStage(o_));

  // Without GPS: the same photos, the model in a frame of its own (turned,
  // scaled, moved), the lists placed on the targets found in the photos.
  {
    IngestView ingest = LoadIngest(o_);
    SparseModel model = ToFullResolution(ReadColmapText(o_.workspace / "reconstruction"), ingest);
    Similarity arbitrary;
    arbitrary.scale = 0.37;
    arbitrary.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()));
    arbitrary.translation = Eigen::Vector3d(120.0, -40.0, 7.0);
    ApplySimilarity(arbitrary, &model);
    const GcpFile control = ReadGcpFile(o_.gcp), checks = ReadGcpFile(o_.checkpoints);
    const Geodetic origin = Crs::FromString(control.crs).ToGeodetic(control.points[0].xyz);
    MarkingOptions mo;
    mo.num_threads = 2;
    const MarkingResult r = MarkControl(model, ingest.ImagesDir(o_), {}, origin, control, &checks, mo);
    EXPECT_EQ(r.method, "targets");
    WriteGcpFile(r.control_marks, dir_ / "no_gps_control.txt");
    WriteGcpFile(r.check_marks, dir_ / "no_gps_checks.txt");
    double median_no_gps = 0, worst_no_gps = 0;
    int extra_no_gps = 0;
    const int missing_no_gps =
        CompareWithTruth(dir_ / "survey" / "truth" / "marks.txt",
                         {dir_ / "no_gps_control.txt", dir_ / "no_gps_checks.txt"}, &median_no_gps, &worst_no_gps,
                         &extra_no_gps);
    int marked_points = 0;
    for (const PointMarking& p : r.points) marked_points += p.Marked();
    std::printf("%s targets without GPS: %d targets found, %d of 10 points placed (RMS %.3f m), %d marked; median "
                "%.3f px, worst %.3f px, %d visible not marked, %d marks of nothing\n",
                GetParam().name, r.targets_found, r.placed_points, r.placement_rms_m, marked_points, median_no_gps,
                worst_no_gps, missing_no_gps, extra_no_gps);
    // The same marks as with GPS: the detections are the same; only how a
    // point finds its target differs.
    EXPECT_GE(r.placed_points, marked_points - 1);
    EXPECT_EQ(marked_points, marks["control"]["marked"].get<int>() + marks["checks"]["marked"].get<int>());
    EXPECT_EQ(extra_no_gps, 0);
    EXPECT_LE(missing_no_gps, 1.2 * missing + 2);  // whole photos, not windows: a few more or fewer
    EXPECT_LT(median_no_gps, 0.05);
    EXPECT_LT(worst_no_gps, 0.15);
  }

  // The survey from the marks against the survey from the true marks.
  const PipelineOptions marked = WithMarks(o_);
  EXPECT_EQ(marked.gcp, o_.workspace / "gcp_marks.txt");
  ASSERT_TRUE(RunGeoreferenceStage(marked));
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(o_.workspace / "report.json"));
  EXPECT_NE(report["status"], "failed");
  EXPECT_EQ(report["marking"]["control"]["marked"], marks["control"]["marked"]);
  // The report stage redraws the page with the adjustment's residuals and
  // w-tests, mark by mark.
  ASSERT_TRUE(RunReportStage(marked));
  const nlohmann::json adjusted_page = ReviewPageData(o_.workspace / "marks.html");
  EXPECT_TRUE(adjusted_page["adjusted"].get<bool>());
  int with_residual = 0;
  for (const auto& p : adjusted_page["points"]) {
    for (const auto& c : p["photos"]) with_residual += c.contains("residual_px");
  }
  EXPECT_EQ(with_residual, report["adjustment"]["data_snooping"]["marks"].size());
  const double auto_rmse = report["check_points"]["rmse_3d_m"];
  // The truth marks, split into control and checks as the survey's files.
  GcpFile control = ReadGcpFile(dir_ / "survey" / "gcp_list.txt"), checks = ReadGcpFile(dir_ / "survey" / "checkpoints.txt");
  const GcpFile truth = ReadGcpFile(dir_ / "survey" / "truth" / "marks.txt");
  for (GcpFile* f : {&control, &checks}) {
    for (GroundPoint& p : f->points) {
      for (const GroundPoint& q : truth.points) {
        if (q.name == p.name) p.measurements = q.measurements;
      }
    }
  }
  WriteGcpFile(control, dir_ / "true_control.txt");
  WriteGcpFile(checks, dir_ / "true_checks.txt");
  PipelineOptions by_truth = o_;
  by_truth.gcp = dir_ / "true_control.txt";
  by_truth.checkpoints = dir_ / "true_checks.txt";
  ASSERT_TRUE(RunGeoreferenceStage(by_truth));
  const double truth_rmse =
      nlohmann::json::parse(ReadTextFile(o_.workspace / "report.json"))["check_points"]["rmse_3d_m"];
  std::printf("%s targets: check RMSE 3D %.4f m from the marks, %.4f m from the true marks (%.2fx)\n",
              GetParam().name, auto_rmse, truth_rmse, auto_rmse / truth_rmse);
  EXPECT_LT(auto_rmse, 1.1 * truth_rmse + 0.002);
  // The survey from the marks made without GPS.
  PipelineOptions by_no_gps = o_;
  by_no_gps.gcp = dir_ / "no_gps_control.txt";
  by_no_gps.checkpoints = dir_ / "no_gps_checks.txt";
  ASSERT_TRUE(RunGeoreferenceStage(by_no_gps));
  const double no_gps_rmse =
      nlohmann::json::parse(ReadTextFile(o_.workspace / "report.json"))["check_points"]["rmse_3d_m"];
  std::printf("%s targets: check RMSE 3D %.4f m from the marks made without GPS (%.2fx the true marks')\n",
              GetParam().name, no_gps_rmse, no_gps_rmse / truth_rmse);
  EXPECT_LT(no_gps_rmse, 1.1 * truth_rmse + 0.002);
}

INSTANTIATE_TEST_SUITE_P(Kinds, Marking,
                         ::testing::Values(Kind{TargetPattern::kChecker, "checker"}, Kind{TargetPattern::kCross, "cross"},
                                           Kind{TargetPattern::kBullseye, "circle"}),
                         [](const auto& info) { return std::string(info.param.name); });

using MarkingProblems = Marking;

TEST_P(MarkingProblems, UnseenOffsetAndSharedPointsAreReportedNotMarked) {
  const GcpFile control = ReadGcpFile(dir_ / "survey" / "gcp_coordinates.txt");
  ASSERT_GE(control.points.size(), 6u);
  std::ofstream out(dir_ / "problems.txt");
  out << control.crs << "\n" << std::setprecision(12);
  const auto line = [&](const std::string& name, const Eigen::Vector3d& xyz) {
    out << name << " " << xyz.x() << " " << xyz.y() << " " << xyz.z() << "\n";
  };
  line("GOOD", control.points[0].xyz);
  line("AWAY", control.points[1].xyz + Eigen::Vector3d(2000.0, 0.0, 0.0));   // no photo sees it
  line("OFF30", control.points[2].xyz + Eigen::Vector3d(0.0, 30.0, 0.0));   // 30 m from its target
  line("TWIN_A", control.points[3].xyz);                                     // two names, one target
  line("TWIN_B", control.points[3].xyz + Eigen::Vector3d(0.04, -0.03, 0.0));
  // Two more good points: with them the GPS georeferencing's common offset
  // is known, which settles a good point with another target near it.
  line("GOOD4", control.points[4].xyz);
  line("GOOD5", control.points[5].xyz);
  out.close();
  o_.gcp = dir_ / "problems.txt";
  ASSERT_TRUE(RunMarkStage(o_));
  const nlohmann::json marks = nlohmann::json::parse(ReadTextFile(o_.workspace / "marks.json"));
  std::map<std::string, std::string> status;
  for (const auto& p : marks["points"]) {
    status[p["name"]] = p["status"];
    if (p.contains("reason")) std::printf("%s: %s\n", p["name"].get<std::string>().c_str(), p["reason"].get<std::string>().c_str());
    if (p.contains("offset_from_gps_georeferencing_m")) std::printf("%s offset %s\n", p["name"].get<std::string>().c_str(), p["offset_from_gps_georeferencing_m"].dump().c_str());
  }
  for (const char* good : {"GOOD", "GOOD4", "GOOD5"}) EXPECT_EQ(status[good], "MARKED") << good;
  EXPECT_EQ(status["AWAY"], "NOT_SEEN");
  EXPECT_EQ(status["OFF30"], "NOT_FOUND");
  EXPECT_EQ(status["TWIN_A"], "SHARED_TARGET");
  EXPECT_EQ(status["TWIN_B"], "SHARED_TARGET");
  // Only the good points are in the marks the survey reads.
  const GcpFile written = ReadGcpFile(o_.workspace / "gcp_marks.txt");
  ASSERT_EQ(written.points.size(), 3u);
  EXPECT_EQ(written.points[0].name, "GOOD");
  // The georeference stage names the points left out.
  ASSERT_TRUE(RunGeoreferenceStage(WithMarks(o_)));
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(o_.workspace / "report.json"));
  bool named = false;
  for (const auto& w : report["warnings"]) {
    if (w["code"] == "TARGETS_NOT_MARKED") named = w["items"].size() == 4;
  }
  EXPECT_TRUE(named) << report["warnings"].dump();
}

INSTANTIATE_TEST_SUITE_P(Checker, MarkingProblems, ::testing::Values(Kind{TargetPattern::kChecker, "checker"}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace aerotri
