// SPDX-License-Identifier: BSD-3-Clause
// The review page (marks.html) in a real browser: this program writes the
// page of a small marked survey, tests/review/check_review_page.mjs drives
// it in headless Chromium (moves a mark, rejects one, places one where
// nothing was detected, nudges one with the keyboard, exports), and this
// program then reads the exported files with aerotri's own gcp_list.txt
// reader and compares every line with what the edits must give.
//
//   review_fixture write DIR   DIR/marks.html and DIR/scenario.json
//   review_fixture check DIR   DIR/export/gcp_list.txt, check_list.txt
//                              (exit 77 when the browser test did not run)
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "georef/gcp_file.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/report/review_page.h"

namespace fs = std::filesystem;
using json = nlohmann::json;
using aerotri::GcpFile;
using aerotri::GroundPoint;

namespace {

constexpr const char* kCrs = "EPSG:32632";

// Two control points marked, one not found, one check point: positions in
// pixels, (0, 0) at the centre of the top-left pixel.
json Marking() {
  const auto photo = [](const char* image, double px, double py, bool marked, double mx = 0, double my = 0) {
    json p = {{"image", image}, {"predicted_px", {px, py}}, {"marked", marked}};
    if (marked) {
      p["xy_px"] = {mx, my};
      p["confidence"] = 0.93;
      p["kind"] = "checker";
      p["reprojection_px"] = 0.21;
    }
    return p;
  };
  json points = json::array();
  points.push_back({{"name", "GCP1"}, {"role", "control"}, {"status", "MARKED"},
                    {"coordinates", "500010.5 5200020.25 310.125"}, {"sigmas", " sigma_h=0.02 sigma_v=0.03"},
                    {"photos", {photo("img_a.jpg", 203.1, 148.2, true, 200.37, 150.81),
                                photo("img_b.jpg", 322.9, 237.6, true, 320.12, 240.55),
                                photo("img_c.jpg", 413.4, 297.9, true, 410.90, 300.20)}}});
  points.push_back({{"name", "GCP2"}, {"role", "control"}, {"status", "MARKED"},
                    {"coordinates", "500030 5200040 312.5"}, {"sigmas", ""},
                    {"photos", {photo("img_a.jpg", 452.0, 96.0, true, 450.64, 98.43),
                                photo("img_b.jpg", 101.0, 377.0, true, 99.25, 380.77)}}});
  points.push_back({{"name", "GCP3"}, {"role", "control"}, {"status", "NOT_FOUND"},
                    {"reason", "no target within 6.0 m of its surveyed position in the 2 photos that should see it"},
                    {"coordinates", "500050 5200010 309"}, {"sigmas", ""},
                    {"photos", {photo("img_a.jpg", 560.4, 400.6, false), photo("img_c.jpg", 60.2, 40.7, false)}}});
  points.push_back({{"name", "CHK1"}, {"role", "check"}, {"status", "MARKED"},
                    {"coordinates", "500020 5200030 311"}, {"sigmas", ""},
                    {"photos", {photo("img_b.jpg", 250.0, 100.0, true, 251.33, 98.72),
                                photo("img_c.jpg", 300.0, 420.0, true, 301.48, 421.06)}}});
  return {{"search_radius_m", 6.0},
          {"files", {{"control", {{"path", "control.txt"}, {"crs", kCrs}}},
                     {"check", {{"path", "checks.txt"}, {"crs", kCrs}}}}},
          {"points", points}};
}

// The adjustment's verdict: GCP2's mark in img_b rejected by the w-test.
json AdjustmentMarks() {
  const auto mark = [](const char* point, const char* image, double vx, double vy, double wx, double wy, bool rejected) {
    return json{{"point", point}, {"image", image}, {"role", "control"}, {"residual_px", {vx, vy}},
                {"w", {wx, wy}}, {"suspect", rejected}, {"rejected", rejected}};
  };
  return json::array({mark("GCP1", "img_a.jpg", 0.12, -0.08, 0.4, -0.3, false),
                      mark("GCP1", "img_b.jpg", -0.05, 0.10, -0.2, 0.4, false),
                      mark("GCP1", "img_c.jpg", 0.02, 0.03, 0.1, 0.1, false),
                      mark("GCP2", "img_a.jpg", 0.30, 0.21, 1.1, 0.8, false),
                      mark("GCP2", "img_b.jpg", 2.10, -1.60, 5.3, -4.1, true)});
}

// A photo: noise texture with a checker target drawn at every mark.
cv::Mat Photo(const std::string& name, const json& marking) {
  cv::Mat photo(480, 640, CV_8UC3);
  std::mt19937 rng(static_cast<unsigned>(std::hash<std::string>()(name)));
  cv::randu(photo, cv::Scalar(70, 90, 60), cv::Scalar(140, 160, 120));
  cv::GaussianBlur(photo, photo, cv::Size(5, 5), 1.5);
  for (const json& p : marking["points"]) {
    for (const json& m : p["photos"]) {
      if (m["image"] != name || !m["marked"].get<bool>()) continue;
      const cv::Point2d c(m["xy_px"][0].get<double>(), m["xy_px"][1].get<double>());
      const double r = 9.0;
      cv::rectangle(photo, cv::Point2d(c.x - r, c.y - r), cv::Point2d(c.x + r, c.y + r), cv::Scalar(250, 250, 250), -1);
      cv::rectangle(photo, cv::Point2d(c.x - r, c.y - r), c, cv::Scalar(15, 15, 15), -1);
      cv::rectangle(photo, c, cv::Point2d(c.x + r, c.y + r), cv::Scalar(15, 15, 15), -1);
    }
  }
  return photo;
}

// What the browser test does, and what the exports must then hold.
json Scenario() {
  return {{"drag", {{"point", "GCP1"}, {"image", "img_b.jpg"}, {"by_px", {3.0, -2.0}}}},
          {"reject", {{"point", "GCP1"}, {"image", "img_c.jpg"}}},
          {"place", {{"point", "GCP3"}, {"image", "img_a.jpg"}, {"at_px", {562.0, 398.5}}}},
          {"nudge", {{"point", "CHK1"}, {"image", "img_c.jpg"}, {"keys", {"Shift+ArrowUp", "Shift+ArrowUp", "ArrowRight"}}}},
          {"adjustment_rejected", {{"point", "GCP2"}, {"image", "img_b.jpg"}}},
          // Chromium's pointer events carry fractional CSS pixels, so a
          // drag lands where it was aimed; the export writes 3 decimals.
          {"tolerance_px", 0.01},
          {"control",
           {{"GCP1", {{"img_a.jpg", {200.37, 150.81}}, {"img_b.jpg", {323.12, 238.55}}}},
            {"GCP2", {{"img_a.jpg", {450.64, 98.43}}}},
            {"GCP3", {{"img_a.jpg", {562.0, 398.5}}}}}},
          {"check", {{"CHK1", {{"img_b.jpg", {251.33, 98.72}}, {"img_c.jpg", {301.58, 419.06}}}}}}};
}

int Write(const fs::path& dir) {
  fs::create_directories(dir);
  fs::remove_all(dir / "export");
  aerotri::ReviewPageInput in;
  in.marking = Marking();
  in.adjustment_marks = AdjustmentMarks();
  in.title = "review fixture";
  std::map<std::string, cv::Mat> photos;
  for (const char* name : {"img_a.jpg", "img_b.jpg", "img_c.jpg"}) photos[name] = Photo(name, in.marking);
  const std::string html = aerotri::RenderReviewPage(in, [&](const std::string& name) { return photos.at(name); });
  aerotri::WriteTextFileAtomically(dir / "marks.html", html);
  aerotri::WriteTextFileAtomically(dir / "scenario.json", Scenario().dump(2) + "\n");
  std::printf("wrote %s (%zu bytes)\n", (dir / "marks.html").string().c_str(), html.size());
  return 0;
}

// Each exported file against the scenario: the same points, photos and
// coordinates, the marks within the tolerance, the sigmas kept.
int CheckFile(const fs::path& path, const json& want, double tolerance) {
  const GcpFile file = aerotri::ReadGcpFile(path);
  int failures = 0;
  const auto fail = [&](const std::string& what) {
    std::printf("FAIL: %s: %s\n", path.filename().string().c_str(), what.c_str());
    ++failures;
  };
  if (file.crs != kCrs) fail("CRS line '" + file.crs + "'");
  if (file.points.size() != want.size()) fail(std::to_string(file.points.size()) + " points, want " + std::to_string(want.size()));
  for (const GroundPoint& p : file.points) {
    if (!want.contains(p.name)) {
      fail("point " + p.name + " should not be exported");
      continue;
    }
    const json& marks = want[p.name];
    if (p.measurements.size() != marks.size()) fail(p.name + ": " + std::to_string(p.measurements.size()) + " marks");
    for (const auto& m : p.measurements) {
      if (!marks.contains(m.image)) {
        fail(p.name + " in " + m.image + " should not be exported");
        continue;
      }
      const double dx = m.xy_px.x() - marks[m.image][0].get<double>(), dy = m.xy_px.y() - marks[m.image][1].get<double>();
      std::printf("%s %s: (%.3f, %.3f), expected off by (%+.3f, %+.3f) px\n", p.name.c_str(), m.image.c_str(),
                  m.xy_px.x(), m.xy_px.y(), dx, dy);
      if (std::hypot(dx, dy) > tolerance) fail(p.name + " in " + m.image + " off by more than the tolerance");
    }
    if (p.name == "GCP1" && (!p.sigma_h_m || std::abs(*p.sigma_h_m - 0.02) > 1e-12 || !p.sigma_v_m ||
                             std::abs(*p.sigma_v_m - 0.03) > 1e-12)) {
      fail("GCP1's sigmas were not kept");
    }
  }
  return failures;
}

int Check(const fs::path& dir) {
  const fs::path control = dir / "export" / "gcp_list.txt", checks = dir / "export" / "check_list.txt";
  if (!fs::exists(control) || !fs::exists(checks)) {
    std::printf("no exported files in %s: the browser test did not run (skipped)\n", (dir / "export").string().c_str());
    return 77;
  }
  std::ifstream in(dir / "scenario.json");
  const json scenario = json::parse(in);
  const double tolerance = scenario["tolerance_px"].get<double>();
  const int failures = CheckFile(control, scenario["control"], tolerance) + CheckFile(checks, scenario["check"], tolerance);
  std::printf(failures ? "FAILED\n" : "ok: both exported files read back as the edits left them\n");
  return failures ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::string(argv[1]) != "write" && std::string(argv[1]) != "check")) {
    std::fprintf(stderr, "usage: review_fixture write|check DIR\n");
    return 2;
  }
  try {
    return std::string(argv[1]) == "write" ? Write(argv[2]) : Check(argv[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "review_fixture: %s\n", e.what());
    return 1;
  }
}
