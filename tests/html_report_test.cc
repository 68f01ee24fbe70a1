// SPDX-License-Identifier: BSD-3-Clause
// report.html from report.json content: what a quality report must show
// (ASPRS 2023 sentence and its 30-point minimum, camera calibration, tie
// points, timings), readable axes, and charts that stay readable on a
// 500-image survey.
#include "libphoto/report/html_report.h"
#include "libphoto/report/report_json.h"

#include <gtest/gtest.h>

#include <regex>
#include <string>

namespace aerotri {
namespace {

using json = nlohmann::json;

json Images(int n, bool with_gps) {
  json cameras = json::array(), per_image = json::array(), matching = json::array();
  for (int i = 0; i < n; ++i) {
    const std::string name = "IMG_" + std::to_string(1000 + i) + ".JPG";
    // GPS residuals spread from -9.44 m to -1.27 m east: the axis must not
    // print those values but round ones.
    cameras.push_back({{"name", name}, {"gps_prior", with_gps}, {"de_m", -9.44 + 8.17 * i / std::max(1, n - 1)},
                       {"dn_m", 0.5}, {"du_m", -0.25}});
    per_image.push_back({{"name", name}, {"registered", true}, {"reprojection_rms_px", 0.2 + 0.001 * i}});
    matching.push_back({{"name", name}, {"verified_pairs", 12}});
  }
  return {{"cameras", cameras},
          {"images", {{"registered", n}, {"total", n}, {"per_image", per_image}}},
          {"matching", {{"strategy", "gps"}, {"verified_pairs", 12 * n / 2}, {"per_image", matching}}}};
}

json WithAccuracy(json r, int check_points) {
  r["check_points"] = {{"count", check_points}, {"points", json::array()}};
  r["asprs"] = {{"based_on", "6 check points"},
                {"edition_2014", {{"horizontal_accuracy_95_m", 0.046}, {"nva_95_m", 0.036}}},
                {"edition_2023", {{"rmse_h_m", 0.0265}, {"rmse_v_m", 0.0186}, {"rmse_3d_m", 0.0324}}}};
  return r;
}

TEST(HtmlReport, AsprsStatementAndItsThirtyPointMinimum) {
  const std::string few = RenderHtmlReport(WithAccuracy(Images(5, true), 6), "");
  EXPECT_NE(few.find("tested to meet ASPRS Positional Accuracy Standards for Digital Geospatial Data, Edition 2 "
                     "(2023) for a 3.0 cm RMSE<sub>H</sub> horizontal positional accuracy class"),
            std::string::npos);
  EXPECT_NE(few.find("RMSE<sub>H</sub> = 2.6 cm"), std::string::npos);
  EXPECT_NE(few.find("2.0 cm RMSE<sub>V</sub> vertical positional accuracy class"), std::string::npos);
  EXPECT_NE(few.find("Only 6 check points"), std::string::npos);
  const std::string enough = RenderHtmlReport(WithAccuracy(Images(5, true), 30), "");
  EXPECT_EQ(enough.find("Only 30 check points"), std::string::npos);
  EXPECT_NE(enough.find("tested to meet ASPRS"), std::string::npos);
}

TEST(HtmlReport, NoCheckPointsMeansNoAccuracyStatement) {
  json r = WithAccuracy(Images(5, true), 0);
  r["asprs"]["edition_2023"] = {{"rmse_h_m", 0.0}, {"rmse_v_m", 0.0}, {"rmse_3d_m", 0.0}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("No check points:</b> the accuracy of this survey is not tested"), std::string::npos);
  EXPECT_EQ(html.find("tested to meet ASPRS"), std::string::npos);
  EXPECT_EQ(html.find("2023: RMSE"), std::string::npos);
  EXPECT_NE(html.find("check points RMSE 3D<b>none</b>"), std::string::npos);
}

TEST(HtmlReport, AxesHaveRoundTicksAndCountsPrintAsIntegers) {
  const std::string html = RenderHtmlReport(Images(12, true), "");
  // Ticks at multiples of 2 m from -10 to 2, never at the data's extremes.
  EXPECT_NE(html.find(">-10</text>"), std::string::npos);
  EXPECT_NE(html.find(">-4</text>"), std::string::npos);
  EXPECT_EQ(html.find(">-9.44</text>"), std::string::npos);
  EXPECT_EQ(html.find(">-1.27</text>"), std::string::npos);
  EXPECT_NE(html.find("verified pairs: 12 image pairs"), std::string::npos);
  EXPECT_EQ(html.find("12.000 image pairs"), std::string::npos);
  EXPECT_NE(html.find("@media print"), std::string::npos);
}

TEST(HtmlReport, FiveHundredImagesGetDistributionsNotFiveHundredBars) {
  const std::string small = RenderHtmlReport(Images(40, true), "");
  const std::string large = RenderHtmlReport(Images(500, true), "");
  auto count = [](const std::string& s, const std::string& needle) {
    size_t n = 0;
    for (size_t p = s.find(needle); p != std::string::npos; p = s.find(needle, p + 1)) ++n;
    return n;
  };
  // 40 images: one bar per image per chart (GPS has three series).
  EXPECT_GE(count(small, "<rect"), 40u * 5);
  // 500: histograms, far fewer shapes than images, and the worst named.
  EXPECT_LT(count(large, "<rect"), 200u);
  EXPECT_NE(large.find("500 cameras: median"), std::string::npos);
  EXPECT_NE(large.find("500 images: median"), std::string::npos);
  EXPECT_NE(large.find("largest: IMG_1499.JPG 0.699"), std::string::npos);
}

// The GNSS drift as estimated, the cameras' tilt, and the DSM's coverage of
// the ground the photos see (a warning below 90 %).
TEST(HtmlReport, AttitudeDriftAndFootprintCoverage) {
  json r = Images(5, true);
  r["adjustment"] = {{"attitude",
                      {{"nadir_block", true},
                       {"viewing", "optical axes within 2.3 deg (median) of their mean"},
                       {"mean_axis_tilt_deg", 0.14},
                       {"median_tilt_deg", 2.3},
                       {"max_tilt_deg", 6.7},
                       {"ground_slope_deg", 2.34},
                       {"ground_slope_points", 5120},
                       {"gimbal",
                        {{"images", 18},
                         {"block_tilt_deg", 0.6},
                         {"pitch_difference_median_deg", 1.33},
                         {"pitch_difference_max_deg", 2.8},
                         {"yaw_difference_median_deg", 3.9},
                         {"yaw_bias_deg", -6.07}}}}}};
  r["gps_drift"] = {{"note", "levelled by its mean optical axis"},
                    {"estimated", true},
                    {"vertical_source", "nadir"},
                    {"attitude_prior", true},
                    {"attitude_prior_sigma_deg_per_photo", 5.0},
                    {"axes", {{"e", false}, {"n", false}, {"u", true}}},
                    {"flights",
                     {{{"images", 88},
                       {"duration_s", 174.0},
                       {"trend_m_per_s", {{"e_m", 0.0}, {"n_m", 0.0}, {"u_m", 0.5805}}},
                       {"rate_m_per_s", {{"e_m", 0.0}, {"n_m", 0.0}, {"u_m", 0.5803}}},
                       {"rate_sigma_m_per_s", {{"e_m", 0.0}, {"n_m", 0.0}, {"u_m", 0.0083}}}}}}};
  r["dsm"] = {{"footprint_coverage",
               {{"seen_by_2_m2", 10000.0}, {"covered_m2", 8460.0}, {"fraction", 0.846},
                {"seen_by_exactly_2_m2", 2500.0}, {"seen_by_1_m2", 1200.0}}}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("<h2>Attitude and GNSS drift</h2>"), std::string::npos);
  EXPECT_NE(html.find("mean optical axis 0.1&deg;"), std::string::npos);
  EXPECT_NE(html.find("The ground's mean slope: 2.3&deg; (plane through 5120 tie points)."), std::string::npos);
  EXPECT_NE(html.find("gimbal angles (18 photos): the block 0.6&deg; off the vertical their pitches state; per photo "
                      "pitch differs by 1.3&deg; (median), 2.8&deg; at most; headings by 3.9&deg; (median) after a "
                      "common compass offset of -6.1&deg;"),
            std::string::npos);
  EXPECT_NE(html.find("Tilt held by an attitude prior (the nadir photos' optical axes down) of 5&deg; per photo."),
            std::string::npos);
  EXPECT_NE(html.find("<td>U</td><td>0.5805</td><td>0.5803</td><td>0.0083</td><td>101.0</td>"), std::string::npos)
      << html.substr(html.find("Attitude and GNSS"), 1500);
  EXPECT_NE(html.find("<p class='warn'>The DSM covers 84.6 % of the ground seen by two or more photos"),
            std::string::npos);
  r["dsm"]["footprint_coverage"]["fraction"] = 0.95;
  EXPECT_NE(RenderHtmlReport(r, "").find("<p>The DSM covers 95.0 %"), std::string::npos);
}

TEST(HtmlReport, CameraCalibrationTieTracksAndTimings) {
  json r = Images(5, true);
  r["adjustment"] = {
      {"refined_intrinsics", "f,cx,cy"},
      {"intrinsics",
       {{{"camera", 1},
         {"model", "PINHOLE"},
         {"width", 1000},
         {"height", 750},
         {"params", {{"f", 801.25}, {"cx", 499.5}, {"cy", 374.5}}},
         {"initial_params", {{"f", 800.0}, {"cx", 499.5}, {"cy", 374.5}}},
         {"distortion_curve",
          {{"radius_px", {0.0, 300.0, 625.0}}, {"radial_px", {0.0, -1.5, -4.0}}, {"tangential_px", {0, 0, 0.1}}}}}}},
      {"intrinsics_precision", {{{"camera", 1}, {"sigma", {{"f", 0.75}, {"cx", 0.5}}}}}},
      {"tracks",
       {{"tie_points", 100}, {"mean_length", 3.5}, {"median_length", 3}, {"max_length", 12},
        {"by_length", {{"2", 40}, {"3", 30}, {"10+", 2}}}}}};
  r["timings"] = {{"features", {{"wall_s", 16.6}, {"peak_rss_mb", 430}}},
                  {"dense", {{"wall_s", 48.0}, {"peak_rss_mb", 1063}}}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("<h2>Camera calibration</h2>"), std::string::npos);
  // f: initial, adjusted, change and sigma; cy's sigma not computed: held.
  EXPECT_NE(html.find("<td>f (px)</td><td>800.00</td><td>801.25</td><td>1.25</td><td>0.75</td>"), std::string::npos)
      << html.substr(html.find("Camera calibration"), 900);
  EXPECT_NE(html.find("<td>cy (px)</td><td>374.50</td><td>374.50</td><td>0.00</td><td>held</td>"), std::string::npos);
  EXPECT_NE(html.find("radial</tspan>"), std::string::npos);
  EXPECT_NE(html.find("100 tie points, measured in 3.50 images on average"), std::string::npos);
  EXPECT_NE(html.find("<td>tie points</td><td>40</td><td>30</td>"), std::string::npos);
  EXPECT_NE(html.find("<tr class='total'><td>total</td><td>64.6</td>"), std::string::npos);
}

// With the pixel pitch from EXIF, the calibration in mm: c = f p, x0 and y0
// from the image centre with y up, sigmas scaled alike; without it, none.
TEST(HtmlReport, CalibrationInMillimetresWhereThePixelPitchIsKnown) {
  json adjustment = {
      {"intrinsics",
       {{{"camera", 1}, {"width", 1000}, {"height", 750},
         {"params", {{"f", 800.0}, {"cx", 509.5}, {"cy", 364.5}, {"k1", -0.1}}}},
        {{"camera", 2}, {"width", 1000}, {"height", 750}, {"params", {{"f", 800.0}, {"cx", 499.5}, {"cy", 374.5}}}}}},
      {"intrinsics_precision", {{{"camera", 1}, {"sigma", {{"f", 0.5}, {"cx", 0.25}, {"cy", 0.2}}}}}}};
  AddIntrinsicsInMm(&adjustment, {0.0064, 0.0});
  const json& mm = adjustment["intrinsics"][0]["mm"];
  EXPECT_DOUBLE_EQ(mm["c_mm"].get<double>(), 5.12);
  EXPECT_DOUBLE_EQ(mm["x0_mm"].get<double>(), 10.0 * 0.0064);   // right of the centre
  EXPECT_DOUBLE_EQ(mm["y0_mm"].get<double>(), 10.0 * 0.0064);   // above it: cy is 10 px up the image
  EXPECT_DOUBLE_EQ(mm["sigma_c_mm"].get<double>(), 0.0032);
  EXPECT_DOUBLE_EQ(mm["sigma_y0_mm"].get<double>(), 0.2 * 0.0064);
  EXPECT_FALSE(adjustment["intrinsics"][1].contains("mm"));  // pitch unknown
  json r = Images(5, true);
  r["adjustment"] = adjustment;
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("pixel pitch 6.400 &micro;m from EXIF): camera constant c 5.1200 &plusmn; 0.0032 mm, "
                      "principal point x0 0.0640 &plusmn; 0.0016 mm, y0 0.0640 &plusmn; 0.0013 mm"),
            std::string::npos)
      << html.substr(html.find("Camera calibration"), 1500);
}

// The estimated GPS offsets, one per flight, with their sigmas.
TEST(HtmlReport, GpsOffsetsPerFlightWithTheirSigmas) {
  json r = Images(5, true);
  r["adjustment"]["gps_offset"] = {
      {"estimated", true},
      {"per_flight", true},
      {"offset", {{"e_m", 0.03}, {"n_m", -0.02}, {"u_m", 0.12}}},
      {"flights",
       {{{"flight", 1}, {"photos", 31}, {"offset", {{"e_m", 0.03}, {"n_m", -0.02}, {"u_m", 0.12}}},
         {"sigma", {{"e_m", 0.007}, {"n_m", 0.009}, {"u_m", 0.021}}}},
        {{"flight", 2}, {"photos", 32}, {"offset", {{"e_m", -0.04}, {"n_m", 0.03}, {"u_m", -0.08}}},
         {"sigma", {{"e_m", 0.007}, {"n_m", 0.009}, {"u_m", 0.021}}}}}}};
  r["gps_drift"] = {{"note", "no significant trend"}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("GPS offset estimated (GPS minus camera centre, east / north / up metres, one per flight)"),
            std::string::npos);
  EXPECT_NE(html.find("<tr><td>2</td><td>32</td><td>-0.040</td><td>0.030</td><td>-0.080</td><td>0.007</td>"
                      "<td>0.009</td><td>0.021</td></tr>"),
            std::string::npos)
      << html.substr(html.find("GPS offset"), 800);
}

TEST(HtmlReport, VarianceComponentsPerGroup) {
  json r = Images(5, true);
  r["adjustment"]["sigma0"] = 1.0;
  r["adjustment"]["variance_components"] = {
      {"estimated", true},
      {"iterations", 2},
      {"sigma0_stated", 0.31},
      {"groups",
       {{{"group", "tie_points"}, {"unit", "px"}, {"rows", 67564}, {"redundancy", 58276.0}, {"stated_sigma", 1.0},
         {"sigma0", 1.0}, {"scale", 0.3}, {"estimated_sigma", 0.3}, {"estimated", true}},
        {{"group", "control_points"}, {"unit", "m"}, {"rows", 24}, {"redundancy", 6.3}, {"stated_sigma", 0.024},
         {"sigma0", 0.32}, {"scale", 1.0}, {"estimated_sigma", 0.0077}, {"estimated", false}}}}};
  r["adjustment"]["solves"] = {
      {{"kind", "robust screening (huber)"}, {"iterations", 6}, {"time_s", 26.8}},
      {{"kind", "least squares"}, {"iterations", 2}, {"time_s", 12.7}},
      {{"kind", "variance components 1"}, {"iterations", 2}, {"time_s", 12.6}}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("re-solved 2 time(s)); &sigma;<sub>0</sub> with the stated sigmas was 0.310."), std::string::npos);
  EXPECT_NE(html.find("<tr><td>solves</td><td>robust screening (huber) 6 it., 26.8 s; least squares 2 it., 12.7 s; "
                      "variance components 1 2 it., 12.6 s</td></tr>"),
            std::string::npos)
      << html.substr(html.find("Adjustment statistics"), 900);
  EXPECT_NE(html.find("<tr><td>tie_points</td><td>67564</td><td>58276.0</td><td>1.000 px</td><td>1.000</td>"
                      "<td>0.300 px</td><td>0.300 px</td></tr>"),
            std::string::npos)
      << html.substr(html.find("Variance components"), 900);
  EXPECT_NE(html.find("<tr><td>control_points</td><td>24</td><td>6.3</td><td>0.024 m</td><td>0.320</td>"
                      "<td>0.008 m</td><td>0.024 m</td></tr>"),
            std::string::npos);
}

// Check points with their w per axis against the predicted sigma, the
// rejected one marked, and the test's size stated under the table.
TEST(HtmlReport, CheckPointsShowTheirWAndTheTest) {
  json r = WithAccuracy(Images(3, true), 2);
  r["check_points"]["points"] = {
      {{"name", "351"}, {"images", 4}, {"solved", true}, {"dx_m", 0.167}, {"dy_m", 0.008}, {"dz_m", -0.459},
       {"reprojection_rms_px", 1.5}, {"w", {2.84, 0.20, -1.88}}, {"rejected", false}},
      {{"name", "410"}, {"images", 3}, {"solved", true}, {"dx_m", 0.096}, {"dy_m", -0.296}, {"dz_m", 0.136},
       {"reprojection_rms_px", 0.9}, {"w", {2.42, -7.26, 0.74}}, {"rejected", true}}};
  r["check_points"]["test"] = {{"tests", 6}, {"family_alpha", 0.01}, {"critical_value", 3.14},
                               {"predicted_from", "posterior covariance and survey sigmas"}};
  const std::string html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("<th>w x, y, z</th>"), std::string::npos);
  EXPECT_NE(html.find("<td>2.8, 0.2, -1.9</td>"), std::string::npos) << html.substr(html.find("Check points"), 1500);
  EXPECT_NE(html.find("<td class='warn'>2.4, -7.3, 0.7 (rejected)</td>"), std::string::npos);
  EXPECT_NE(html.find("exceeds 3.14, the critical value at 1 % over all 6 axis tests"), std::string::npos);
}

// Data snooping states both levels: marks beyond the per-test value against
// how many a clean survey expects, and the largest against the family-wise
// value that decides MARK_BLUNDER.
TEST(HtmlReport, DataSnoopingStatesBothLevels) {
  json r = Images(5, true);
  r["adjustment"]["precision"] = {{"computed", true}};
  json marks = json::array();
  for (int i = 0; i < 800; ++i) {
    marks.push_back({{"point", "GCP" + std::to_string(i / 20)}, {"image", "IMG_" + std::to_string(i)},
                     {"w", {i == 417 ? -3.4 : 1.0, 0.5}}, {"suspect", i == 417}, {"rejected", false}});
  }
  r["adjustment"]["data_snooping"] = {{"critical_value", 3.29},        {"tests", 1600},
                                      {"family_alpha", 0.01},          {"critical_value_family", 4.5167},
                                      {"suspects", 1},                 {"expected_suspects_without_blunders", 1.6},
                                      {"marks", marks}};
  std::string html = RenderHtmlReport(r, "");
  const std::string clean =
      "Baarda's w-test on 800 marks (1600 tests): 1 above 3.29 (&alpha;<sub>0</sub> 0.1 % per test; 1.6 expected "
      "without blunders); largest |w| 3.40 (GCP20 on IMG_417) against 4.52 for the largest of all tests "
      "(&alpha; 1.0 %) &mdash; none rejected.";
  EXPECT_NE(html.find(clean), std::string::npos) << html.substr(html.find("Data snooping"), 600);
  r["adjustment"]["data_snooping"]["marks"][90]["w"][0] = 6.0;
  html = RenderHtmlReport(r, "");
  EXPECT_NE(html.find("largest |w| 6.00 (GCP4 on IMG_90) against 4.52 for the largest of all tests (&alpha; 1.0 %) "
                      "&mdash; <b>rejected: measure this mark again</b>."),
            std::string::npos)
      << html.substr(html.find("Data snooping"), 600);
}

TEST(HtmlReport, DsmPreviewHasALegendAndAScaleBar) {
  json r = Images(5, true);
  r["dsm"] = {{"file", "dsm.tif"}, {"width", 900}, {"height", 600}, {"resolution_m", 0.16},
              {"filled_fraction", 0.98}, {"cells_with_points", 500000},
              {"preview", {{"width_px", 900}, {"height_px", 600}, {"metres_per_px", 0.16},
                           {"z_low_m", 101.3}, {"z_high_m", 118.9}}}};
  r["dense"] = {{"points", 5000000}};
  const std::string html = RenderHtmlReport(r, std::string("\x89PNG", 4));
  EXPECT_NE(html.find("height (m)"), std::string::npos);
  // 900 px of 0.16 m is 144 m: the bar is a round 20 or 50 m.
  EXPECT_TRUE(std::regex_search(html, std::regex(">(20|50) m</text>"))) << html.substr(html.find("Elevation"), 600);
  EXPECT_NE(html.find(">105</text>"), std::string::npos);  // a round height on the legend
  EXPECT_NE(html.find("points/m&sup2;"), std::string::npos);
}

TEST(HtmlReport, OrthoAndTerrainSectionsStateTheirAccuracy) {
  json r = Images(5, true);
  r["dsm"] = {{"file", "dsm.tif"}, {"width", 900}, {"height", 600}, {"resolution_m", 0.16},
              {"filled_fraction", 0.98}, {"cells_with_points", 500000}};
  r["dense"] = {{"points", 5000000}};
  r["heights"] = {{"crs", "EPSG:32632+5773"}, {"description", "EGM96 heights (EPSG:5773)"}};
  r["ground"] = {{"method", "SMRF (Pingel et al. 2013)"}, {"ground", 750}, {"above_ground", 240}, {"noise", 10},
                 {"cell_m", 0.5}, {"window_m", 18.0}, {"slope", 0.15}};
  r["dtm"] = {{"file", "dtm.tif"}, {"interpolated_fraction", 0.12},
              {"check_points", {{"count", 6}, {"rmse_z_m", 0.047}}}};
  r["contours"] = {{"lines", 22}, {"interval_m", 1.0}, {"index_every", 5}, {"smoothing_sigma_m", 2.0}};
  r["ortho"] = {{"file", "ortho.tif"}, {"width", 2016}, {"height", 1810}, {"resolution_m", 0.078},
                {"cog", true}, {"compress", "JPEG"}, {"surface", "dsm.tif"}, {"images_used", 35},
                {"filled_fraction", 0.9999},
                {"preview", {{"width_px", 900}, {"height_px", 808}, {"metres_per_px", 0.175},
                             {"x_min", 384820.0}, {"y_max", 5150765.0}, {"x_max", 384977.2}, {"y_min", 5150623.8}}},
                {"check_points",
                 {{"count", 2}, {"rmse_x_m", 0.03}, {"rmse_y_m", 0.04}, {"rmse_h_m", 0.05},
                  {"method", "saddle"},
                  {"points", {{{"name", "CHK1"}, {"located", true}, {"d_m", {0.03, -0.04}}, {"dh_m", 0.05}},
                              {{"name", "CHK2"}, {"located", true}, {"d_m", {-0.03, 0.04}}, {"dh_m", 0.05}},
                              {{"name", "CHK3"}, {"located", false}, {"reason", "no target centre stands out"}}}}}}};
  const std::string png("\x89PNG", 4);
  const std::string html = RenderHtmlReport(r, std::map<std::string, std::string>{{"dsm", png}, {"dtm", png}, {"ortho", png}});
  for (const char* needle :
       {"<h2>Terrain model (DTM) and contours</h2>", "75.0 % ground, 24.0 % above ground", "12.0 % of its cells interpolated",
        "22 lines every 1.00 m", "RMSE z 0.047 m", "<h2>Orthomosaic</h2>", "2016 x 1810 cells of 0.078 m",
        "Cloud-Optimised GeoTIFF", "from 35 photos", "not located: no target centre stands out",
        "tested to meet ASPRS Positional Accuracy Standards for Digital Geospatial Data, Edition 2 (2023) for a 5.0 cm "
        "RMSE<sub>H</sub>",
        "2 check points; ASPRS 2023 asks for at least 30", "top left 384820.0, 5150765.0", "Heights: EGM96 heights"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
  // Without a located target, no accuracy is claimed for the ortho.
  r["ortho"]["check_points"] = {{"count", 0}, {"points", {{{"name", "CHK3"}, {"located", false}, {"reason", "x"}}}}};
  const std::string none = RenderHtmlReport(r, std::map<std::string, std::string>{{"dsm", png}});
  EXPECT_EQ(none.find("This orthoimagery was tested"), std::string::npos);
  EXPECT_NE(none.find("no horizontal accuracy is stated for it"), std::string::npos);
}

}  // namespace
}  // namespace aerotri
