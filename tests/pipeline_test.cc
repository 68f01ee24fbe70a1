// SPDX-License-Identifier: BSD-3-Clause
// The photo pipeline end to end on a small rendered survey with known truth,
// with the kinds of bad input a surveyor's folder holds: a corrupt file, a
// photo without GPS, a photo of somewhere else.
#include "libphoto/pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <gdal_priv.h>

#include <memory>
#include <opencv2/imgproc.hpp>

#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/point_cloud.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/simulate/render.h"
#include "libphoto/simulate/survey_writer.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {
namespace fs = std::filesystem;

// A new workspace with another's products up to the reconstruction.
void CopyTiePointProducts(const fs::path& from, const fs::path& to) {
  fs::create_directories(to);
  for (const char* item : {"ingest.json", "matches.bin", "matches.json", "reconstruction.json"}) {
    fs::copy_file(from / item, to / item, fs::copy_options::overwrite_existing);
  }
  for (const char* dir : {"features", "reconstruction"}) {
    fs::copy(from / dir, to / dir, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  }
}

// GDAL's command-line tools' output (independent of aerotri's code).
std::string Command(const std::string& cmd) {
  FILE* pipe = popen((cmd + " 2>/dev/null").c_str(), "r");
  std::string out;
  if (!pipe) return out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) out.append(buf, n);
  pclose(pipe);
  return out;
}

struct Rgb {
  cv::Mat grey, alpha;  // grey as float
  double gt[6] = {0, 1, 0, 0, 0, -1};
};

Rgb ReadRgb(const fs::path& path) {
  GDALAllRegister();
  Rgb r;
  std::unique_ptr<GDALDataset> ds(static_cast<GDALDataset*>(GDALOpen(path.string().c_str(), GA_ReadOnly)));
  if (!ds) return r;
  ds->GetGeoTransform(r.gt);
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  cv::Mat sum(h, w, CV_32F, cv::Scalar(0));
  for (int b = 1; b <= 3; ++b) {
    cv::Mat band(h, w, CV_32F);
    if (ds->GetRasterBand(b)->RasterIO(GF_Read, 0, 0, w, h, band.data, w, h, GDT_Float32, 0, 0) != CE_None) return r;
    sum += band / 3.0;
  }
  r.grey = sum;
  r.alpha = cv::Mat(h, w, CV_8U, cv::Scalar(255));
  GDALRasterBand* mask = ds->GetRasterCount() >= 4 ? ds->GetRasterBand(4) : ds->GetRasterBand(1)->GetMaskBand();
  if (mask->RasterIO(GF_Read, 0, 0, w, h, r.alpha.data, w, h, GDT_Byte, 0, 0) != CE_None) r.alpha = cv::Mat();
  return r;
}

class Pipeline : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    SimulationOptions sim;
    sim.survey.seed = 5;
    sim.survey.width = 640;
    sim.survey.height = 480;
    sim.survey.brown_params = {520.0, 322.0, 238.0, -0.08, 0.05, -0.01, 0.0005, -0.0003};
    sim.survey.area_width_m = 50.0;
    sim.survey.area_height_m = 36.0;
    sim.survey.flight_height_m = 40.0;
    sim.survey.num_tie_points = 500;
    sim.survey.num_control_points = 6;
    sim.survey.num_check_points = 4;
    sim.georef.seed = 5;
    WriteSyntheticSurvey(sim, dir_->path() / "survey");
    truth_ = new SparseModel(ReadColmapText(dir_->path() / "survey" / "truth" / "model"));
    truth_ortho_cell_ = ReadRgb(dir_->path() / "survey" / "truth" / "ortho.tif").gt[1];
    // Bad inputs beside the good photos.
    std::ofstream(dir_->path() / "survey" / "images" / "broken.jpg") << "not a jpeg at all";
    // A photo without EXIF (so without GPS or focal length), between two
    // photos of the first strip.
    RenderOptions render;
    Pose between = truth_->images[1].pose;
    between.centre_in_world = 0.5 * (truth_->images[1].pose.centre_in_world + truth_->images[2].pose.centre_in_world);
    cv::imwrite((dir_->path() / "survey" / "images" / "no_gps.jpg").string(),
                RenderImage(truth_->cameras[0], between, render));
    // A photo of somewhere else: the same camera 2 km east.
    Pose far = truth_->images[0].pose;
    far.centre_in_world.x() += 2000.0;
    cv::imwrite((dir_->path() / "survey" / "images" / "elsewhere.jpg").string(),
                RenderImage(truth_->cameras[0], far, render));
  }
  static void TearDownTestSuite() {
    delete truth_;
    delete dir_;
  }
  PipelineOptions Options(const std::string& workspace) const {
    PipelineOptions o;
    o.images_dir = dir_->path() / "survey" / "images";
    o.workspace = dir_->path() / workspace;
    o.gps_sigma_h_m = 2.0;
    o.gps_sigma_v_m = 4.0;
    // The truth orthoimage's cell, so that the two grids coincide.
    o.ortho_resolution_m = truth_ortho_cell_;
    // The adjustment is the product's (SurveyBundleOptions), as users get it.
    return o;
  }
  static testing::TempDir* dir_;
  static SparseModel* truth_;
  static double truth_ortho_cell_;
};
testing::TempDir* Pipeline::dir_ = nullptr;
SparseModel* Pipeline::truth_ = nullptr;
double Pipeline::truth_ortho_cell_ = 0.0;

TEST_F(Pipeline, PhotosAndControlToACentimetreSurvey) {
  PipelineOptions o = Options("ws_gcp");
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  RunPipeline(o);
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const int photos = static_cast<int>(truth_->images.size());
  EXPECT_EQ(report["images"]["total"], photos + 3);
  EXPECT_EQ(report["images"]["registered"], photos + 1);  // + the copy without GPS
  std::map<std::string, nlohmann::json> per_image;
  for (const auto& im : report["images"]["per_image"]) per_image[im["name"]] = im;
  EXPECT_FALSE(per_image["broken.jpg"]["registered"].get<bool>());
  EXPECT_NE(per_image["broken.jpg"]["why_not"].get<std::string>().find("unusable"), std::string::npos);
  EXPECT_FALSE(per_image["elsewhere.jpg"]["registered"].get<bool>());
  EXPECT_NE(per_image["elsewhere.jpg"]["why_not"].get<std::string>().find("no verified image pair"),
            std::string::npos);
  EXPECT_TRUE(per_image["no_gps.jpg"]["registered"].get<bool>());
  EXPECT_FALSE(per_image["no_gps.jpg"]["gps"].get<bool>());
  // Sub-pixel at the working resolution, and centimetres on check points
  // (GSD 7.7 cm, targets clicked with 0.3 px noise, survey noise 1 cm).
  EXPECT_LT(report["adjustment"]["final_rms_px"].get<double>(), 0.6);
  EXPECT_GT(report["adjustment"]["final_rms_px"].get<double>(), 0.05);
  EXPECT_EQ(report["check_points"]["count"], 4);
  EXPECT_LT(report["check_points"]["rmse_3d_m"].get<double>(), 0.08) << report["adjustment"]["intrinsics"].dump() << report["adjustment"]["datum"] << report["adjustment"]["final_rms_px"];
  EXPECT_GT(report["check_points"]["rmse_3d_m"].get<double>(), 0.003);
  // The calibration in mm, with the pitch from EXIF's focal-plane resolution
  // (the rendered sensor is 6.4 mm wide): c is the adjusted f in mm.
  {
    const auto& camera = report["adjustment"]["intrinsics"][0];
    ASSERT_TRUE(camera.contains("mm")) << camera.dump();
    EXPECT_NEAR(camera["mm"]["pixel_size_mm"].get<double>() * camera["width"].get<double>(), 6.4, 1e-3);
    EXPECT_NEAR(camera["mm"]["c_mm"].get<double>(),
                camera["params"]["f"].get<double>() * camera["mm"]["pixel_size_mm"].get<double>(), 1e-9);
  }
  // The ingest warnings name the bad files.
  const std::string warnings = report["ingest_warnings"].dump();
  EXPECT_NE(warnings.find("broken.jpg"), std::string::npos);
  EXPECT_NE(warnings.find("no_gps.jpg: no GPS"), std::string::npos);
  // The status: warnings (bad inputs, a photo left out), no error, the codes
  // naming what happened.
  EXPECT_EQ(report["status"], "warnings") << report["errors"].dump();
  EXPECT_TRUE(report["errors"].empty());
  std::map<std::string, nlohmann::json> by_code;
  for (const auto& w : report["warnings"]) by_code[w["code"]] = w;
  ASSERT_TRUE(by_code.count("IMAGES_NOT_REGISTERED")) << report["warnings"].dump(1);
  EXPECT_NE(by_code["IMAGES_NOT_REGISTERED"]["items"].dump().find("elsewhere.jpg"), std::string::npos);
  EXPECT_TRUE(by_code.count("INPUT"));
  // Full-resolution sparse model and cameras in the output CRS.
  EXPECT_TRUE(fs::exists(o.workspace / "sparse" / "images.txt"));
  EXPECT_TRUE(fs::exists(o.workspace / "cameras.csv"));
  // A second run resumes: every stage is skipped.
  EXPECT_FALSE(RunIngestStage(o));
  EXPECT_FALSE(RunFeatureStage(o));
  EXPECT_FALSE(RunMatchStage(o));
  EXPECT_FALSE(RunReconstructStage(o));
  EXPECT_FALSE(RunGeoreferenceStage(o));
  EXPECT_FALSE(RunDenseStage(o));
  EXPECT_FALSE(RunOrthoStage(o));
  EXPECT_FALSE(RunReportStage(o));
}

TEST_F(Pipeline, DsmMatchesTheTruthTerrain) {
  PipelineOptions o = Options("ws_gcp");
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  RunPipeline(o);  // resumes what the other test did, if it ran first
  const Raster dsm = ReadRaster(o.workspace / "dsm.tif");
  const Raster truth = ReadRaster(dir_->path() / "survey" / "truth" / "dem.tif");
  // Under the 2D EPSG:32632 the deliverables carry EGM96 heights (EPSG:5773),
  // the truth ellipsoidal ones: h = H + N, N from the geoid grid.
  EXPECT_NE(dsm.wkt.find("EGM96 height"), std::string::npos);
  const double undulation = Egm96Undulation(46.5, 7.5);
  // Inside the surveyed area away from its borders (truth has a 10 m margin
  // around the flown area; stay 8 m further in).
  const int margin = static_cast<int>(18.0 / truth.geotransform[1]);
  std::vector<double> abs_err;
  int cells = 0;
  for (int y = margin; y < truth.height - margin; ++y) {
    for (int x = margin; x < truth.width - margin; ++x) {
      ++cells;
      const auto z = SampleRaster(dsm, truth.X(x), truth.Y(y));
      if (z) abs_err.push_back(std::abs(*z + undulation - truth.at(x, y)));
    }
  }
  ASSERT_GT(cells, 100);
  const double filled = static_cast<double>(abs_err.size()) / cells;
  std::nth_element(abs_err.begin(), abs_err.begin() + abs_err.size() / 2, abs_err.end());
  const double median = abs_err[abs_err.size() / 2];
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const double gsd = report["gsd_m"];
  EXPECT_GT(filled, 0.95);
  EXPECT_LT(median, 2.0 * gsd) << "GSD " << gsd;
  EXPECT_GT(median, 0.002);  // the truth is not copied
  // The report samples the DSM at the check points.
  EXPECT_EQ(report["dsm"]["check_points"]["count"], 4);
  EXPECT_LT(report["dsm"]["check_points"]["rmse_z_m"].get<double>(), 3.0 * gsd);
  // LAZ by default: our reader gets back the points in the CRS, millimetre-quantised.
  const CrsCloud las = ReadLas(o.workspace / "cloud.laz");
  EXPECT_EQ(static_cast<long long>(las.xyz.size()), report["dense"]["points"].get<long long>());
  const auto& cloud = report["dense"]["cloud"];
  EXPECT_EQ(cloud["file"], "cloud.laz");
  EXPECT_EQ(cloud["bytes"].get<std::uintmax_t>(), fs::file_size(o.workspace / "cloud.laz"));
  EXPECT_LT(cloud["compression_ratio"].get<double>(), 0.3);
  EXPECT_GT(cloud["compression_ratio"].get<double>(), 0.02);
  EXPECT_FALSE(fs::exists(o.workspace / "cloud.las"));
  // Open meadow: nearly every point is ground (ASPRS 2), none unclassified 0.
  const long long ground = std::count(las.classes.begin(), las.classes.end(), 2);
  EXPECT_GT(ground, static_cast<long long>(0.95 * las.classes.size()));
  EXPECT_EQ(std::count(las.classes.begin(), las.classes.end(), 0), 0);
  EXPECT_NE(las.crs_wkt.find("UTM zone 32N"), std::string::npos);
  EXPECT_NEAR(las.xyz[0].x(), 384900.0, 500.0);
  // report.html is self-contained and shows what a client needs.
  const std::string html = ReadTextFile(o.workspace / "report.html");
  EXPECT_EQ(html.find("src='http"), std::string::npos);
  EXPECT_EQ(html.find("href='http"), std::string::npos);
  for (const char* needle : {"<svg", "data:image/png;base64,", "CHK1", "GCP1", "ASPRS", "Check points",
                             "Camera positions against GPS", "Reprojection error per image", "Coverage",
                             "tested to meet ASPRS", "check points:</b> ASPRS 2023 asks for at least 30",
                             "<h2>Camera calibration</h2>", "radial</tspan>", "<h2>Tie points</h2>", "height (m)",
                             "points/m&sup2;", "<h2>Processing</h2>", "@media print", "Cloud: cloud.laz (LAZ: LAS 1.4 compressed"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
}

TEST_F(Pipeline, OrthomosaicDtmAndContoursMatchTheTruth) {
  PipelineOptions o = Options("ws_gcp");
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  RunPipeline(o);
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const double gsd = report["gsd_m"];
  // The orthomosaic against the ground's true colours, on the same lattice.
  const Rgb ortho = ReadRgb(o.workspace / "ortho.tif"), truth = ReadRgb(dir_->path() / "survey" / "truth" / "ortho.tif");
  ASSERT_FALSE(ortho.grey.empty());
  ASSERT_FALSE(truth.grey.empty());
  ASSERT_NEAR(ortho.gt[1], truth.gt[1], 1e-12);
  const int ox = static_cast<int>(std::lround((ortho.gt[0] - truth.gt[0]) / truth.gt[1]));
  const int oy = static_cast<int>(std::lround((truth.gt[3] - ortho.gt[3]) / truth.gt[1]));
  const int T = 96;
  double sum2 = 0, max_shift = 0;
  int tiles = 0, tiles_total = 0;
  std::vector<float> diffs;
  for (int y = 0; y + T <= ortho.grey.rows; y += T) {
    for (int x = 0; x + T <= ortho.grey.cols; x += T) {
      const cv::Rect r(x, y, T, T), rt(x + ox, y + oy, T, T);
      if ((rt & cv::Rect(0, 0, truth.grey.cols, truth.grey.rows)) != rt) continue;
      ++tiles_total;
      if (cv::countNonZero(ortho.alpha(r) > 127) < T * T) continue;
      cv::Mat window;
      cv::createHanningWindow(window, r.size(), CV_32F);
      const cv::Point2d d = cv::phaseCorrelate(truth.grey(rt), ortho.grey(r), window);
      sum2 += d.dot(d);
      max_shift = std::max(max_shift, std::hypot(d.x, d.y));
      ++tiles;
      const double gain = cv::mean(truth.grey(rt))[0] / std::max(1.0, cv::mean(ortho.grey(r))[0]);
      cv::Mat diff = cv::abs(truth.grey(rt) - gain * ortho.grey(r));
      diffs.insert(diffs.end(), diff.begin<float>(), diff.end<float>());
    }
  }
  ASSERT_GT(tiles, 8);
  const double rmse_px = std::sqrt(sum2 / tiles);
  std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
  std::printf("ortho against truth: %d tiles, offset RMSE %.3f px (max %.3f), median |dgrey| %.1f DN\n", tiles,
              rmse_px, max_shift, diffs[diffs.size() / 2]);
  // Adjusted cameras (check points at ~3 cm) and a stereo DSM: within a cell.
  EXPECT_LT(rmse_px, 1.0);
  EXPECT_LT(max_shift, 1.5);
  EXPECT_GT(rmse_px, 0.01);
  EXPECT_LT(diffs[diffs.size() / 2], 20.0);  // JPEG photos, noise, exposure gains
  // The flown area (the truth's, less its 10 m margin) is filled.
  const double margin_px = 10.0 / truth.gt[1];
  long long inside = 0, filled = 0;
  for (int y = 0; y < ortho.grey.rows; ++y) {
    for (int x = 0; x < ortho.grey.cols; ++x) {
      const int tx = x + ox, ty = y + oy;
      if (tx < margin_px || ty < margin_px || tx >= truth.grey.cols - margin_px || ty >= truth.grey.rows - margin_px) continue;
      ++inside;
      filled += ortho.alpha.at<std::uint8_t>(y, x) > 127;
    }
  }
  EXPECT_GT(static_cast<double>(filled) / inside, 0.98) << filled << " of " << inside;
  // Check-point targets located in the ortho: within a GSD.
  ASSERT_TRUE(report.contains("ortho"));
  EXPECT_EQ(report["ortho"]["check_points"]["count"], 4) << report["ortho"].dump();
  // Located to a fraction of a cell (the truth ortho itself gives 0.3 GSD).
  EXPECT_LT(report["ortho"]["check_points"]["rmse_h_m"].get<double>(), 0.6 * gsd);
  // gdalinfo: a COG with a mask, the compound CRS on the DTM, the contours in ogrinfo.
  const std::string info = Command("gdalinfo '" + (o.workspace / "ortho.tif").string() + "'");
  if (!info.empty()) {
    EXPECT_NE(info.find("LAYOUT=COG"), std::string::npos);
    EXPECT_NE(info.find("Mask Flags: PER_DATASET"), std::string::npos);
    EXPECT_NE(info.find("Overviews"), std::string::npos);
    const std::string dtm = Command("gdalinfo '" + (o.workspace / "dtm.tif").string() + "'");
    EXPECT_NE(dtm.find("VERTCRS[\"EGM96 height\""), std::string::npos);
    EXPECT_NE(dtm.find("NoData Value=-9999"), std::string::npos);
    const std::string contours = Command("ogrinfo -so '" + (o.workspace / "contours.gpkg").string() + "' contours");
    EXPECT_NE(contours.find("Geometry: Line String"), std::string::npos);
    EXPECT_NE(contours.find("elevation: Real"), std::string::npos);
    EXPECT_NE(contours.find("index: Integer"), std::string::npos);
    EXPECT_NE(contours.find("EGM96 height"), std::string::npos);
  }
  // The DTM of an open meadow is its DSM: within a few centimetres at the check points.
  EXPECT_LT(report["dtm"]["check_points"]["rmse_z_m"].get<double>(), 3.0 * gsd);
  // The report shows them.
  const std::string html = ReadTextFile(o.workspace / "report.html");
  for (const char* needle : {"<h2>Orthomosaic</h2>", "<h2>Terrain model (DTM) and contours</h2>",
                             "This orthoimagery was tested to meet ASPRS", "EGM96 heights", "top left"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
}

TEST_F(Pipeline, InterruptedDenseStageResumesToTheSameCloud) {
  PipelineOptions o = Options("ws_gcp");
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  RunPipeline(o);
  const auto before = nlohmann::json::parse(ReadTextFile(o.workspace / "dense.json"));
  EXPECT_GE(before["tiles"].get<int>(), 1);
  // Fused, the depth maps are gone by default (most of a workspace's bytes).
  EXPECT_FALSE(fs::exists(o.workspace / "depth"));
  // Kept on request: the cloud rebuilt from new maps is the same cloud.
  o.keep_depth_maps = true;
  fs::remove(o.workspace / "cloud.laz");
  EXPECT_TRUE(RunDenseStage(o));
  EXPECT_EQ(nlohmann::json::parse(ReadTextFile(o.workspace / "dense.json"))["points"], before["points"]);
  // Interrupted after some depth maps: the cloud is missing, one depth map too.
  fs::remove(o.workspace / "cloud.laz");
  std::vector<fs::path> depth;
  for (const auto& e : fs::directory_iterator(o.workspace / "depth")) depth.push_back(e.path());
  ASSERT_GT(depth.size(), 3u);
  fs::remove(depth[1]);
  EXPECT_TRUE(RunDenseStage(o));
  EXPECT_TRUE(fs::exists(depth[1]));
  const auto after = nlohmann::json::parse(ReadTextFile(o.workspace / "dense.json"));
  EXPECT_EQ(after["points"], before["points"]);
  // Another cloud format is an option changed: the stage reruns, writes
  // cloud.las with the same points, and the earlier run's LAZ goes.
  const CrsCloud laz = ReadLas(o.workspace / "cloud.laz");
  o.cloud_format = "las";
  EXPECT_TRUE(RunDenseStage(o));
  EXPECT_FALSE(fs::exists(o.workspace / "cloud.laz"));
  const CrsCloud las = ReadLas(o.workspace / "cloud.las");
  ASSERT_EQ(las.xyz.size(), laz.xyz.size());
  EXPECT_EQ(las.xyz, laz.xyz);
  EXPECT_EQ(las.classes, laz.classes);
  EXPECT_EQ(nlohmann::json::parse(ReadTextFile(o.workspace / "dense.json"))["cloud"]["file"], "cloud.las");
  // COPC: the same points again, in the octree's order.
  o.cloud_format = "copc";
  EXPECT_TRUE(RunDenseStage(o));
  EXPECT_FALSE(fs::exists(o.workspace / "cloud.las"));
  CrsCloud copc = ReadLas(o.workspace / "cloud.copc.laz");
  auto sorted = [](std::vector<Eigen::Vector3d> v) {
    std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return std::tie(a.x(), a.y(), a.z()) < std::tie(b.x(), b.y(), b.z()); });
    return v;
  };
  EXPECT_EQ(sorted(copc.xyz), sorted(las.xyz));
}

TEST_F(Pipeline, DemAndCheckWorkOnAFinishedSurvey) {
  PipelineOptions o = Options("ws_gcp");
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  RunPipeline(o);
  const auto before = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  // Provenance: a library caller is named as such; the options are those that ran.
  ASSERT_TRUE(before.contains("provenance") && before.contains("dense")) << before.dump(1);
  EXPECT_EQ(before.at("provenance").value("software", ""), "aerotri (library)");
  EXPECT_EQ(before.at("provenance").at("options").at("georeference"), before.at("georeference_options"));
  EXPECT_EQ(before.at("provenance").at("options").at("ingest").value("gps_altitude", ""), "egm96");
  EXPECT_EQ(before.at("dense").value("options", nlohmann::json::object()).value("dsm_fill_m", -1.0), o.dsm_fill_m);
  // A product damaged since it was written (here cloud.laz, truncated) is
  // rebuilt on resume, never read, and the report is redone after it.
  {
    const auto las = o.workspace / "cloud.laz";
    const auto bytes = std::filesystem::file_size(las);
    std::filesystem::resize_file(las, bytes / 2);
    EXPECT_TRUE(RunDenseStage(o));
    EXPECT_EQ(std::filesystem::file_size(las), bytes);
    EXPECT_TRUE(RunReportStage(o));
    EXPECT_FALSE(RunDenseStage(o));  // intact now: resumed, not redone
  }
  // aerotri dem: another resolution from cloud.laz.
  o.dsm_resolution_m = 0.5;
  RebuildDsm(o, o.workspace / "dsm_0.5m.tif");
  const Raster coarse = ReadRaster(o.workspace / "dsm_0.5m.tif");
  EXPECT_DOUBLE_EQ(coarse.geotransform[1], 0.5);
  EXPECT_NE(coarse.wkt.find("UTM zone 32N"), std::string::npos);
  // --dsm-resolution 0 (the default): the dense stage's choice, twice the
  // dense spacing, so the rebuilt DSM lands on the grid size of dsm.tif.
  o.dsm_resolution_m = 0.0;
  const auto automatic = RebuildDsm(o);
  const Raster original = ReadRaster(o.workspace / "dsm.tif");
  char automatic_name[64];
  std::snprintf(automatic_name, sizeof automatic_name, "dsm_%gm.tif", original.geotransform[1]);
  EXPECT_EQ(automatic.filename().string(), automatic_name);
  EXPECT_DOUBLE_EQ(ReadRaster(automatic).geotransform[1], original.geotransform[1]);
  // aerotri check: the same check points give the same figures again.
  CheckSurvey(o);
  const auto after = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  EXPECT_EQ(after["check_points"]["count"], before["check_points"]["count"]);
  EXPECT_NEAR(after["check_points"]["rmse_3d_m"].get<double>(), before["check_points"]["rmse_3d_m"].get<double>(),
              1e-6);
  EXPECT_TRUE(after["dsm"]["check_points"].contains("rmse_z_m"));
  // The check says what made it, beside the adjustment's provenance.
  ASSERT_TRUE(after["provenance"].contains("check")) << after["provenance"].dump();
  EXPECT_FALSE(after["provenance"]["check"].value("date_utc", "").empty());
  EXPECT_EQ(after["provenance"]["check"]["options"]["leave_one_out"], false);
  EXPECT_EQ(after["provenance"]["check"]["options"]["checkpoints"].get<std::string>().size(), 16u);
  // A check-point file naming an image the survey does not have is reported, not fatal.
  std::ofstream(o.workspace / "odd_checks.txt") << "EPSG:32632\n384900 5150700 500 10 10 NOT_THERE.JPG X1\n";
  o.checkpoints = o.workspace / "odd_checks.txt";
  CheckSurvey(o);
  const auto odd = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  EXPECT_EQ(odd["check_points"]["count"], 0);
  EXPECT_NE(odd["check_warnings"].dump().find("NOT_THERE.JPG"), std::string::npos);
  // Leave the workspace as the other tests expect it.
  o.checkpoints = dir_->path() / "survey" / "checkpoints.txt";
  CheckSurvey(o);

  // aerotri check --leave-one-out: each control point withheld from the
  // survey's own adjustment, without touching the adjusted survey.
  ASSERT_FALSE(o.georef.leave_one_out);
  EXPECT_FALSE(odd.at("leave_one_out").value("computed", true));
  const std::string sparse_before = ReadTextFile(o.workspace / "sparse" / "images.txt");
  o.georef.leave_one_out = true;
  o.checkpoints.clear();
  CheckSurvey(o);
  const auto loo = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  ASSERT_TRUE(loo.at("leave_one_out").value("computed", false)) << loo.at("leave_one_out").dump();
  EXPECT_EQ(loo["leave_one_out"]["points"].size(), loo["control_points"]["points"].size());
  const double loo_rmse = loo["leave_one_out"]["rmse_3d_m"].get<double>();
  std::printf("leave-one-out RMSE %.4f m, control residual RMSE %.4f m, check RMSE %.4f m\n", loo_rmse,
              loo["control_points"]["rmse_3d_m"].get<double>(), loo["check_points"]["rmse_3d_m"].get<double>());
  // Withheld, a control point is a check point: its error is a check point's
  // size, larger than the residual the adjustment pulled it to.
  EXPECT_GT(loo_rmse, loo["control_points"]["rmse_3d_m"].get<double>());
  EXPECT_LT(loo_rmse, 3.0 * loo["check_points"]["rmse_3d_m"].get<double>());
  EXPECT_EQ(loo["check_points"], after["check_points"]);  // the check points as they were
  EXPECT_EQ(ReadTextFile(o.workspace / "sparse" / "images.txt"), sparse_before);
  // Other adjustment options than the survey's: refused, naming them.
  o.georef.gcp_sigma_h_m = 0.5;
  try {
    CheckSurvey(o);
    ADD_FAILURE() << "leave-one-out under other options than the survey's";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("gcp_sigma_h_m: 0.02 -> 0.5"), std::string::npos) << e.what();
  }
}

TEST_F(Pipeline, CompoundCrsGivesAGeoidHeightDsm) {
  // Reuse the tie points of a finished run; georeference again in EPSG:32632+5773.
  PipelineOptions base = Options("ws_gps");
  RunPipeline(base);
  PipelineOptions o = Options("ws_compound");
  CopyTiePointProducts(base.workspace, o.workspace);
  o.georef.output_crs = "EPSG:32632+5773";
  o.gcp = dir_->path() / "survey" / "gcp_list.txt";
  RunPipeline(o);
  const Raster ortho = ReadRaster(o.workspace / "dsm.tif");
  const Raster ellipsoidal = ReadRaster(dir_->path() / "survey" / "truth" / "dem.tif");
  EXPECT_NE(ortho.wkt.find("EGM96"), std::string::npos);
  // EGM96 undulation here: 50.09 m (cs2cs EPSG:4979 EPSG:4326+5773 at 46.5 7.5 gives -50.0934).
  const double cx = ellipsoidal.X(ellipsoidal.width / 2), cy = ellipsoidal.Y(ellipsoidal.height / 2);
  const auto z = SampleRaster(ortho, cx, cy);
  ASSERT_TRUE(z.has_value());
  const float truth = ellipsoidal.at(ellipsoidal.width / 2, ellipsoidal.height / 2);
  EXPECT_NEAR(truth - *z, 50.09, 0.3);
}

TEST_F(Pipeline, GpsAloneKeepsCamerasWithinTheGpsNoise) {
  PipelineOptions o = Options("ws_gps");
  RunPipeline(o);
  const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
  const Geodetic origin{report["enu_origin"]["lat_deg"], report["enu_origin"]["lon_deg"],
                        report["enu_origin"]["h_m"]};
  const LocalFrame frame(origin), truth_frame({46.5, 7.5, 500.0});
  const SparseModel model = ReadColmapText(o.workspace / "sparse");
  std::map<std::string, Eigen::Vector3d> truth_centre;
  for (const Image& image : truth_->images) {
    truth_centre[image.name] = frame.EnuFromGeodetic(truth_frame.GeodeticFromEnu(image.pose.centre_in_world));
  }
  double sum_h = 0.0, sum_v = 0.0;
  int n = 0;
  for (const Image& image : model.images) {
    const auto it = truth_centre.find(image.name);
    if (it == truth_centre.end()) continue;
    const Eigen::Vector3d d = image.pose.centre_in_world - it->second;
    sum_h += d.head<2>().squaredNorm() / 2.0;
    sum_v += d.z() * d.z();
    ++n;
  }
  ASSERT_GT(n, 10);
  // The datum of n GPS fixes of sigma 2 m / 4 m is good to about sigma /
  // sqrt(n) (plus a little scale and tilt): well inside one sigma, not zero.
  EXPECT_LT(std::sqrt(sum_h / n), 2.0);
  EXPECT_LT(std::sqrt(sum_v / n), 4.0);
  EXPECT_GT(std::sqrt(sum_h / n + sum_v / n), 0.01);
}


// A stage whose recorded options or inputs differ from the current ones
// reruns and says why; with the same ones it is done already.
TEST_F(Pipeline, ChangedOptionsRerunTheirStage) {
  PipelineOptions base = Options("ws_gps");
  RunPipeline(base);
  PipelineOptions o = Options("ws_rerun");
  CopyTiePointProducts(base.workspace, o.workspace);
  std::vector<std::string> log;
  o.log = [&log](const std::string& line) { log.push_back(line); };
  EXPECT_FALSE(RunIngestStage(o));  // same options: ingest.json stands
  EXPECT_TRUE(RunGeoreferenceStage(o));
  EXPECT_FALSE(RunGeoreferenceStage(o));
  // Another output CRS: the georeference reruns and says what changed.
  o.georef.output_crs = "EPSG:32632+5773";
  log.clear();
  EXPECT_TRUE(RunGeoreferenceStage(o));
  bool said = false;
  for (const auto& line : log) said |= line.find("crs: \"\" -> \"EPSG:32632+5773\"") != std::string::npos;
  EXPECT_TRUE(said);
  EXPECT_EQ(nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"))["crs"], "EPSG:32632+5773");
  // A certificate that states only the pixel pitch: the georeference reruns
  // and states the calibration in mm with it (full-resolution pitch, scaled
  // to the working pixels the adjustment's figures are in).
  const fs::path pitch = o.workspace.parent_path() / "pitch_only.txt";
  WriteTextFileAtomically(pitch, "units mm\npixel_size_mm 0.004\n");
  o.camera_file = pitch;
  EXPECT_TRUE(RunGeoreferenceStage(o));
  {
    const auto report = nlohmann::json::parse(ReadTextFile(o.workspace / "report.json"));
    const auto ingest = nlohmann::json::parse(ReadTextFile(o.workspace / "ingest.json"));
    const auto& im = ingest["images"][0];
    const double expected = 0.004 * im["width"].get<double>() / im["working_width"].get<double>();
    EXPECT_DOUBLE_EQ(report["adjustment"]["intrinsics"][0]["mm"]["pixel_size_mm"].get<double>(), expected);
    EXPECT_EQ(report["adjustment"]["intrinsics"][0]["mm"]["pixel_size_source"], "the camera file");
  }
  o.camera_file.clear();
  // Another GPS height reference: ingest reruns, and so does the georeference
  // (its input changed), which then finds the GPS 50 m from where it was.
  o.gps_altitude = AltitudeReference::kEllipsoid;
  EXPECT_TRUE(RunIngestStage(o));
  EXPECT_TRUE(RunGeoreferenceStage(o));
  // The dense stage: once, then again only when its options change.
  EXPECT_TRUE(RunDenseStage(o));
  EXPECT_FALSE(RunDenseStage(o));
  o.dsm_fill_m = 0.5;
  EXPECT_TRUE(RunDenseStage(o));

  // The tie-point stages record theirs too. Copied products under the same
  // options stand; a changed match option reruns matching, and the
  // reconstruction built on the old matches reruns after it.
  const auto said_in_log = [&log](const std::string& text) {
    bool found = false;
    for (const auto& line : log) found |= line.find(text) != std::string::npos;
    return found;
  };
  EXPECT_FALSE(RunFeatureStage(o));
  EXPECT_FALSE(RunMatchStage(o));
  EXPECT_FALSE(RunReconstructStage(o));
  log.clear();
  o.matching.min_inliers = 25;
  EXPECT_TRUE(RunMatchStage(o));
  EXPECT_TRUE(said_in_log("min_inliers: 20 -> 25")) << ::testing::PrintToString(log);
  EXPECT_FALSE(RunMatchStage(o));
  EXPECT_TRUE(RunReconstructStage(o));
  EXPECT_TRUE(said_in_log("reconstruct: options or inputs changed"));
  EXPECT_FALSE(RunReconstructStage(o));
  // A changed mapper option reruns the reconstruction only.
  o.mapper.min_pnp_inliers = 20;
  EXPECT_FALSE(RunMatchStage(o));
  EXPECT_TRUE(RunReconstructStage(o));
  // Other feature options: every image's features again, and the matches after them.
  log.clear();
  o.features.max_features = 6000;
  EXPECT_TRUE(RunFeatureStage(o));
  EXPECT_TRUE(said_in_log("max_features: 12000 -> 6000")) << ::testing::PrintToString(log);
  EXPECT_FALSE(RunFeatureStage(o));
  EXPECT_FALSE(fs::exists(o.workspace / "matches.bin"));
  EXPECT_TRUE(RunMatchStage(o));
  const MatchRecord matches = LoadMatchRecord(o);
  EXPECT_GT(matches.verified_pairs, 10);
  for (const MatchRecord::Image& im : matches.images) EXPECT_LE(im.features, 6000) << im.name;
  EXPECT_TRUE(RunReconstructStage(o));
  EXPECT_GE(LoadReconstructionRecord(o).registered, static_cast<int>(truth_->images.size()) - 2);
}

}  // namespace
}  // namespace aerotri
