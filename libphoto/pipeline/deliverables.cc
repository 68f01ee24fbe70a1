// SPDX-License-Identifier: BSD-3-Clause
// The deliverable stages: dense cloud, LAS / PLY, DSM; and the report.
#include <gdal_utils.h>
#include <gdal_priv.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <set>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/base/parallel.h"
#include "libphoto/dense/dense_stereo.h"
#include "libphoto/export/cloud_tiles.h"
#include "libphoto/export/contours.h"
#include "libphoto/export/dsm.h"
#include "libphoto/export/point_cloud.h"
#include "libphoto/export/terrain.h"
#include "libphoto/ortho/orthomosaic.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/workspace.h"
#include "libphoto/report/html_report.h"
#include "libphoto/report/report_json.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string CloudFileName(const PipelineOptions& o) {
  if (o.cloud_format == "las") return "cloud.las";
  if (o.cloud_format == "copc") return "cloud.copc.laz";
  return "cloud.laz";
}

namespace {

// The adjusted survey's cameras (georeferenced/), each photo with the
// rolling shutter the adjustment modelled it with (georeferenced/
// rolling_shutter.txt: the photos' stated motion or their GPS track's, the
// readout stated or estimated), so that every deliverable sees each row from
// where its camera was. A report that says a camera group was adjusted as a
// rolling shutter while no photo of it carries a motion is a workspace
// written before the motion was kept: refused, rather than taken for global.
SparseModel ReadSurveyModel(const PipelineOptions& o, const json& report) {
  const fs::path dir = o.workspace / "georeferenced";
  SparseModel model = ReadColmapText(dir);
  if (!report.contains("adjustment") || !report["adjustment"].contains("shutter")) return model;
  for (const json& shutter : report["adjustment"]["shutter"]) {
    if (shutter.value("model", "") != "rolling") continue;
    const int camera_id = shutter.value("camera", -1);
    const bool carried = std::any_of(model.images.begin(), model.images.end(), [&](const Image& image) {
      return image.rolling_shutter && model.cameras[image.camera].id == camera_id;
    });
    if (!carried) {
      throw InvalidArgument((o.workspace / "report.json").string() + ": camera " + std::to_string(camera_id) +
                            " was adjusted as a rolling shutter, but " + (dir / "rolling_shutter.txt").string() +
                            " gives none of its photos a motion (a workspace from an earlier aerotri): rerun "
                            "`aerotri georeference --force`");
    }
  }
  return model;
}

struct GeoFrame {
  LocalFrame frame;
  Crs crs;
};

GeoFrame FrameOf(const json& report) {
  if (!report.value("georeferenced", false) || !report.contains("crs") || report["crs"].is_null()) {
    throw InvalidArgument("the survey is not georeferenced (no GPS and no control points): no LAS, DSM or "
                          "check-point figures can be given in a CRS");
  }
  const auto& o = report.at("enu_origin");
  Crs crs = Crs::FromString(report.at("crs").get<std::string>());
  if (crs.IsLocal() && report.contains("crs_local_origin")) {
    const auto& c = report["crs_local_origin"];
    crs = crs.LocalAt({c.at(0).get<double>(), c.at(1).get<double>(), c.at(2).get<double>()});
  }
  return {LocalFrame({o.at("lat_deg"), o.at("lon_deg"), o.at("h_m")}), crs};
}

// The CRS of the deliverables (cloud, DSM, DTM, contours, ortho): the output
// CRS when it says what its heights are (compound, vertical axis, geocentric,
// local, or options.heights "ellipsoidal"); a 2D CRS named by an EPSG code
// becomes code+5773 (EGM96 heights) when PROJ has the geoid grid. `note`:
// the heights in words, for the files' metadata and the report.
Crs DeliverableCrs(const GeoFrame& g, const PipelineOptions& o, std::string* note) {
  const Crs& crs = g.crs;
  if (crs.IsLocal() || crs.IsGeocentric()) {
    *note = crs.IsLocal() ? "z of the local frame" : "geocentric Z (no heights)";
    return crs;
  }
  if (crs.HasVerticalDatum()) {
    *note = "heights of the vertical datum of " + crs.Name();
    return crs;
  }
  const std::string ellipsoidal = "WGS84 ellipsoidal heights (" + crs.Name() + " is 2D)";
  static const std::regex epsg("^\\s*EPSG:([0-9]+)\\s*$", std::regex::icase);
  std::smatch m;
  const std::string def = crs.definition();
  if (o.heights != "egm96" || !std::regex_match(def, m, epsg)) {
    *note = ellipsoidal;
    return crs;
  }
  try {
    const Crs compound = Crs::FromString("EPSG:" + m[1].str() + "+5773");
    compound.FromGeodetic(g.frame.GeodeticFromEnu(Eigen::Vector3d::Zero()));  // the grid is there
    *note = "EGM96 heights (EPSG:5773)";
    return compound;
  } catch (const Error& e) {
    Log(o, std::string("warning: deliverables: no EGM96 geoid (") + e.what() + "); heights stay " + ellipsoidal);
    *note = ellipsoidal;
    return crs;
  }
}

// The frame the dense stage wrote its products in (dense.json "crs"; the
// output CRS for a workspace written before it was recorded).
GeoFrame DeliverableFrame(const json& report, const json& dense) {
  GeoFrame g = FrameOf(report);
  if (dense.contains("crs") && dense["crs"].is_string() && dense["crs"].get<std::string>() != g.crs.definition()) {
    g.crs = Crs::FromString(dense["crs"].get<std::string>());
  }
  return g;
}

double DsmResolution(const PipelineOptions& o, double cloud_resolution) {
  if (o.dsm_resolution_m > 0) return o.dsm_resolution_m;
  return std::max(0.01, std::round(2.0 * cloud_resolution * 100.0) / 100.0);
}

// status: the survey's (report.json), written into the GeoTIFF's metadata
// as AEROTRI_SURVEY_STATUS so that a DSM of a failed survey says so.
void WriteDsmRaster(const Raster& dsm, const DsmSummary& summary, double resolution, const PipelineOptions& o,
                    const std::string& status, const std::string& heights, const fs::path& path, json* info) {
  RasterWriteOptions w;
  w.cog = o.cog;
  if (!status.empty()) w.metadata["AEROTRI_SURVEY_STATUS"] = status;
  if (!heights.empty()) w.metadata["AEROTRI_HEIGHTS"] = heights;
  WriteRaster(dsm, path, w);
  const double cells = static_cast<double>(summary.width) * summary.height;
  *info = {{"file", path.filename().string()},
           {"resolution_m", resolution},
           {"width", summary.width},
           {"height", summary.height},
           {"cells_with_points", summary.cells_with_data},
           {"cells_filled", summary.cells_filled},
           {"filled_fraction", cells > 0 ? (summary.cells_with_data + summary.cells_filled) / cells : 0.0},
           {"fill_max_distance_m", o.dsm_fill_m},
           {"cog", o.cog}};
}

// A preview of the DSM, at most max_size pixels wide: elevation colours
// (2nd to 98th percentile of the heights) shaded by a multidirectional
// hillshade, nodata white; with what its legend and scale bar need.
struct DsmPreview {
  std::string png;
  json info;
};

// A raster opened for a preview at most max_size pixels wide: its size, the
// preview's, and what a preview's scale bar and corner coordinates need.
struct PreviewSource {
  GDALDatasetH dataset = nullptr;  // the caller closes it
  int w = 0, h = 0, pw = 0, ph = 0;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  json Info() const {
    return {{"width_px", pw},        {"height_px", ph},  {"metres_per_px", std::abs(gt[1]) * w / pw},
            {"x_min", gt[0]},        {"y_max", gt[3]},   {"x_max", gt[0] + w * gt[1]},
            {"y_min", gt[3] + h * gt[5]}};
  }
};

PreviewSource OpenForPreview(const fs::path& path, int max_size) {
  GDALAllRegister();
  PreviewSource p;
  p.dataset = GDALOpen(path.string().c_str(), GA_ReadOnly);
  if (!p.dataset) return p;
  p.w = GDALGetRasterXSize(p.dataset);
  p.h = GDALGetRasterYSize(p.dataset);
  GDALGetGeoTransform(p.dataset, p.gt);
  const double s = std::min(1.0, static_cast<double>(max_size) / std::max(p.w, p.h));
  p.pw = std::max(1, static_cast<int>(p.w * s));
  p.ph = std::max(1, static_cast<int>(p.h * s));
  return p;
}

DsmPreview DsmPreviewPng(const fs::path& dsm, int max_size) {
  DsmPreview out;
  const PreviewSource source = OpenForPreview(dsm, max_size);
  GDALDatasetH src = source.dataset;
  if (!src) return out;
  const int pw = source.pw, ph = source.ph;
  const std::string sw = std::to_string(pw), sh = std::to_string(ph);
  const char* tr_args[] = {"-of", "MEM", "-outsize", sw.c_str(), sh.c_str(), "-r", "average", nullptr};
  GDALTranslateOptions* tr = GDALTranslateOptionsNew(const_cast<char**>(tr_args), nullptr);
  GDALDatasetH small = GDALTranslate("", src, tr, nullptr);
  GDALTranslateOptionsFree(tr);
  GDALClose(src);
  if (!small) return out;
  const char* hs_args[] = {"-of", "MEM", "-compute_edges", "-multidirectional", nullptr};
  GDALDEMProcessingOptions* hs = GDALDEMProcessingOptionsNew(const_cast<char**>(hs_args), nullptr);
  GDALDatasetH shade = GDALDEMProcessing("", small, "hillshade", nullptr, hs, nullptr);
  GDALDEMProcessingOptionsFree(hs);
  std::vector<float> z(static_cast<size_t>(pw) * ph);
  std::vector<unsigned char> light(z.size(), 255);
  GDALRasterBandH zb = GDALGetRasterBand(small, 1);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(zb, &has_nodata);
  bool ok = GDALRasterIO(zb, GF_Read, 0, 0, pw, ph, z.data(), pw, ph, GDT_Float32, 0, 0) == CE_None;
  if (shade) {
    ok = ok && GDALRasterIO(GDALGetRasterBand(shade, 1), GF_Read, 0, 0, pw, ph, light.data(), pw, ph, GDT_Byte, 0,
                            0) == CE_None;
    GDALClose(shade);
  }
  GDALClose(small);
  if (!ok) return out;
  auto valid = [&](float v) { return std::isfinite(v) && !(has_nodata && v == static_cast<float>(nodata)); };
  std::vector<float> heights;
  for (float v : z) {
    if (valid(v)) heights.push_back(v);
  }
  if (heights.empty()) return out;
  std::sort(heights.begin(), heights.end());
  const double lo = heights[heights.size() * 2 / 100], hi = heights[heights.size() * 98 / 100];
  const double span = hi > lo ? hi - lo : 1.0;
  GDALDriverH mem = GDALGetDriverByName("MEM");
  GDALDatasetH rgb = GDALCreate(mem, "", pw, ph, 3, GDT_Byte, nullptr);
  std::vector<unsigned char> band(z.size());
  for (int b = 0; b < 3; ++b) {
    for (size_t k = 0; k < z.size(); ++k) {
      if (!valid(z[k])) {
        band[k] = 255;
        continue;
      }
      // Shade multiplies the colour, lifted so that flat ground keeps it.
      const double shading = 0.35 + 0.65 * light[k] / 255.0;
      band[k] = static_cast<unsigned char>(std::clamp(ElevationRampColour((z[k] - lo) / span)[b] * shading, 0.0, 255.0));
    }
    if (GDALRasterIO(GDALGetRasterBand(rgb, b + 1), GF_Write, 0, 0, pw, ph, band.data(), pw, ph, GDT_Byte, 0, 0) !=
        CE_None) {
      GDALClose(rgb);
      return out;
    }
  }
  const std::string vsi = "/vsimem/aerotri_dsm_preview.png";
  GDALDatasetH png = GDALCreateCopy(GDALGetDriverByName("PNG"), vsi.c_str(), rgb, FALSE, nullptr, nullptr, nullptr);
  GDALClose(rgb);
  if (!png) return out;
  GDALClose(png);
  vsi_l_offset length = 0;
  GByte* bytes = VSIGetMemFileBuffer(vsi.c_str(), &length, TRUE);
  out.png.assign(reinterpret_cast<const char*>(bytes), static_cast<size_t>(length));
  CPLFree(bytes);
  VSIUnlink((vsi + ".aux.xml").c_str());
  out.info = source.Info();
  out.info["z_low_m"] = lo;
  out.info["z_high_m"] = hi;
  out.info["z_range"] = "2nd to 98th percentile of the heights";
  return out;
}

// DSM heights at the check points against their surveyed heights.
// Surveyed positions are in the output CRS, the DSM in the deliverables' CRS.
json DsmAtCheckPoints(const json& report, const Raster& dsm, const GeoFrame& output, const GeoFrame& deliverable) {
  json out = {{"points", json::array()}};
  double sum = 0.0;
  int n = 0;
  for (const auto& p : report.value("check_points", json::object()).value("points", json::array())) {
    if (!p.contains("surveyed")) continue;
    json e = {{"name", p.value("name", "")}};
    const Eigen::Vector3d surveyed(p["surveyed"][0].get<double>(), p["surveyed"][1].get<double>(),
                                   p["surveyed"][2].get<double>());
    const Eigen::Vector3d q = deliverable.crs.FromGeodetic(output.crs.ToGeodetic(surveyed));
    const auto z = SampleRaster(dsm, q.x(), q.y());
    if (z) {
      const double dz = *z - q.z();
      e["dz_m"] = dz;
      sum += dz * dz;
      ++n;
    }
    out["points"].push_back(e);
  }
  out["count"] = n;
  out["rmse_z_m"] = n > 0 ? std::sqrt(sum / n) : 0.0;
  return out;
}

// Images that see each cell of a coarse grid over the DSM.
json Coverage(const SparseModel& model, const Raster& dsm, const GeoFrame& g) {
  const int nx = 60, ny = std::max(1, static_cast<int>(60.0 * dsm.height / std::max(1, dsm.width)));
  std::vector<int> counts(static_cast<size_t>(nx) * ny, -1);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const int px = static_cast<int>((x + 0.5) * dsm.width / nx), py = static_cast<int>((y + 0.5) * dsm.height / ny);
      const float z = dsm.at(px, py);
      if (z == static_cast<float>(dsm.nodata)) continue;
      const Eigen::Vector3d enu = g.frame.EnuFromGeodetic(g.crs.ToGeodetic({dsm.X(px), dsm.Y(py), z}));
      int c = 0;
      for (const Image& image : model.images) {
        if (!image.registered) continue;
        const Camera& cam = model.cameras[image.camera];
        const Eigen::Vector3d pc = image.pose.CamFromWorld(enu);
        if (pc.z() <= 0) continue;
        const Eigen::Vector2d xy = cam.ImageFromCamera(pc);
        c += xy.x() >= 0 && xy.y() >= 0 && xy.x() < cam.width && xy.y() < cam.height;
      }
      counts[static_cast<size_t>(y) * nx + x] = c;
    }
  }
  return {{"nx", nx}, {"ny", ny}, {"counts", counts}};
}

// The DSM against the ground the photos cover (issue 17: a raster's valid
// share says nothing when its extent is a bounding box). Every ground sample
// of the union of the DSM's extent and the photos' footprints is projected
// into the photos (at the DSM's height where it has one, else the DSM's
// median height); the ground seen by two or more photos is what dense
// matching could cover, and the share of it with a DSM height is the
// coverage. Samples on a grid of at most ~160,000 cells; a 60 x N map of
// the states for the report: 0 seen by fewer than 2 photos, 1 covered,
// 2 seen by 2 or more but without a DSM height.
json FootprintCoverage(const SparseModel& model, const Raster& dsm, const GeoFrame& g) {
  json out = {{"method", "ground seen by 2 or more photos (each photo's frame projected on the DSM, or on its median "
                         "height outside it) against the DSM's valid cells"}};
  std::vector<float> valid_z;
  for (size_t k = 0; k < dsm.values.size(); k += std::max<size_t>(1, dsm.values.size() / 200000)) {
    if (dsm.values[k] != static_cast<float>(dsm.nodata)) valid_z.push_back(dsm.values[k]);
  }
  if (valid_z.empty() || dsm.width <= 0) return out;
  std::nth_element(valid_z.begin(), valid_z.begin() + valid_z.size() / 2, valid_z.end());
  const double median_z = valid_z[valid_z.size() / 2];
  auto enu_of = [&](double x, double y, double z) { return g.frame.EnuFromGeodetic(g.crs.ToGeodetic({x, y, z})); };
  const double ground_up = enu_of(dsm.X(0.5 * dsm.width), dsm.Y(0.5 * dsm.height), median_z).z();

  // Each photo's footprint on the ground plane: its centre and radius (ENU),
  // and the extent of its corners in the CRS.
  struct Footprint {
    const Image* image;
    Eigen::Vector2d centre;
    double radius;
  };
  std::vector<Footprint> footprints;
  double x0 = dsm.geotransform[0], x1 = dsm.geotransform[0] + dsm.width * dsm.geotransform[1];
  double y1 = dsm.geotransform[3], y0 = dsm.geotransform[3] + dsm.height * dsm.geotransform[5];
  for (const Image& image : model.images) {
    if (!image.registered) continue;
    const Camera& cam = model.cameras[image.camera];
    const Eigen::Vector3d c = image.pose.centre_in_world;
    double radius = 0.0;
    bool ok = true;
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(cam.width - 0.5, -0.5),
                                         Eigen::Vector2d(-0.5, cam.height - 0.5),
                                         Eigen::Vector2d(cam.width - 0.5, cam.height - 0.5)}) {
      const auto ray = cam.RayFromImage(corner);
      if (!ray) {
        ok = false;
        break;
      }
      const Eigen::Vector3d d = image.pose.cam_from_world.conjugate() * *ray;
      // A corner ray at or above the horizon: the footprint is unbounded (an
      // oblique photo); such a photo is judged by projection alone, within
      // five flying heights.
      const double t = d.z() < -1e-3 ? (ground_up - c.z()) / d.z() : -1.0;
      if (!(t > 0.0) || t * d.head<2>().norm() > 5.0 * std::abs(c.z() - ground_up)) {
        radius = std::max(radius, 5.0 * std::abs(c.z() - ground_up));
        continue;
      }
      const Eigen::Vector3d on_ground = c + t * d;
      radius = std::max(radius, (on_ground - c).head<2>().norm());
      const Eigen::Vector3d xyz = g.crs.FromGeodetic(g.frame.GeodeticFromEnu(on_ground));
      x0 = std::min(x0, xyz.x()), x1 = std::max(x1, xyz.x());
      y0 = std::min(y0, xyz.y()), y1 = std::max(y1, xyz.y());
    }
    if (ok) footprints.push_back({&image, c.head<2>(), 1.05 * radius});
  }
  const double cell = std::abs(dsm.geotransform[1]);
  const double step = std::max(cell, std::sqrt((x1 - x0) * (y1 - y0) / 160000.0));
  const int nx = std::max(1, static_cast<int>(std::ceil((x1 - x0) / step)));
  const int ny = std::max(1, static_cast<int>(std::ceil((y1 - y0) / step)));
  const int mx = 60, my = std::max(1, static_cast<int>(std::lround(60.0 * ny / nx)));
  std::vector<int> map_seen(static_cast<size_t>(mx) * my, 0), map_covered(map_seen.size(), 0);
  long long seen2 = 0, covered = 0, seen1 = 0, outside = 0, exactly2 = 0, covered2 = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = x0 + (i + 0.5) * step, y = y1 - (j + 0.5) * step;
      const int px = static_cast<int>(std::floor((x - dsm.geotransform[0]) / dsm.geotransform[1]));
      const int py = static_cast<int>(std::floor((y - dsm.geotransform[3]) / dsm.geotransform[5]));
      const bool inside = px >= 0 && py >= 0 && px < dsm.width && py < dsm.height;
      const bool has_z = inside && dsm.at(px, py) != static_cast<float>(dsm.nodata);
      const Eigen::Vector3d p = enu_of(x, y, has_z ? dsm.at(px, py) : median_z);
      int views = 0;
      for (const Footprint& f : footprints) {
        if ((p.head<2>() - f.centre).norm() > f.radius) continue;
        const Eigen::Vector3d pc = f.image->pose.CamFromWorld(p);
        if (pc.z() <= 0) continue;
        const Camera& cam = model.cameras[f.image->camera];
        const Eigen::Vector2d xy = cam.ImageFromCamera(pc);
        if (xy.x() >= 0 && xy.y() >= 0 && xy.x() < cam.width && xy.y() < cam.height && ++views >= 3) break;
      }
      if (views == 1) ++seen1;
      if (views < 2) continue;
      ++seen2;
      if (views == 2) {
        ++exactly2;
        covered2 += has_z;
      }
      covered += has_z;
      outside += !inside;
      const size_t m = static_cast<size_t>(std::min(my - 1, j * my / ny)) * mx + std::min(mx - 1, i * mx / nx);
      ++map_seen[m];
      map_covered[m] += has_z;
    }
  }
  std::vector<int> map(map_seen.size(), 0);
  for (size_t m = 0; m < map.size(); ++m) {
    if (map_seen[m] > 0) map[m] = 2 * map_covered[m] >= map_seen[m] ? 1 : 2;
  }
  const double a = step * step;
  out["sample_m"] = step;
  out["seen_by_2_m2"] = seen2 * a;
  out["seen_by_1_m2"] = seen1 * a;
  out["covered_m2"] = covered * a;
  // Ground seen by exactly two photos is one stereo pair's at most.
  out["seen_by_exactly_2_m2"] = exactly2 * a;
  out["covered_of_seen_by_exactly_2_m2"] = covered2 * a;
  out["outside_dsm_extent_m2"] = outside * a;
  out["fraction"] = seen2 > 0 ? static_cast<double>(covered) / seen2 : 0.0;
  out["map"] = {{"nx", mx}, {"ny", my}, {"states", map}, {"extent", {x0, y0, x1, y1}},
                {"legend", "0: seen by fewer than 2 photos, 1: DSM, 2: seen by 2 or more photos, no DSM"}};
  return out;
}

// A preview of the orthomosaic, at most max_size pixels wide (GDAL reads its
// overviews), transparent cells white; with what its scale bar needs.
DsmPreview OrthoPreviewPng(const fs::path& ortho, int max_size) {
  DsmPreview out;
  const PreviewSource source = OpenForPreview(ortho, max_size);
  GDALDatasetH src = source.dataset;
  if (!src) return out;
  const int w = source.w, h = source.h, pw = source.pw, ph = source.ph;
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = GRIORA_Average;
  cv::Mat bgr[3], alpha(ph, pw, CV_8U, cv::Scalar(255));
  bool ok = true;
  for (int b = 0; b < 3 && ok; ++b) {
    bgr[2 - b] = cv::Mat(ph, pw, CV_8U);  // OpenCV's order
    ok = GDALRasterIOEx(GDALGetRasterBand(src, b + 1), GF_Read, 0, 0, w, h, bgr[2 - b].data, pw, ph, GDT_Byte, 0, 0,
                        &extra) == CE_None;
  }
  // The alpha band, or the mask of a JPEG COG.
  GDALRasterBandH mask = GDALGetRasterCount(src) >= 4 ? GDALGetRasterBand(src, 4)
                                                      : GDALGetMaskBand(GDALGetRasterBand(src, 1));
  if (ok && mask) {
    ok = GDALRasterIOEx(mask, GF_Read, 0, 0, w, h, alpha.data, pw, ph, GDT_Byte, 0, 0, &extra) == CE_None;
  }
  GDALClose(src);
  if (!ok) return out;
  cv::Mat rgb;
  cv::merge(bgr, 3, rgb);
  rgb.setTo(cv::Scalar(255, 255, 255), alpha < 128);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", rgb, png)) return out;
  out.png.assign(png.begin(), png.end());
  out.info = source.Info();
  return out;
}

// Check-point targets located in the orthomosaic: within 1.5 m of the
// surveyed position, the strongest saddle (the centre of a checker target:
// most negative Hessian determinant of the smoothed grey image), refined to
// a fraction of a cell by a quadratic fit. A target whose saddle does not
// stand out (weaker than a third of the window's contrast) is "not located"
// rather than a guess.
json OrthoAtCheckPoints(const json& report, const fs::path& ortho, const GeoFrame& output,
                        const GeoFrame& deliverable) {
  json out = {{"points", json::array()},
              {"method", "checker-target centre (saddle point) located in the orthomosaic within 1.5 m of the "
                         "surveyed position"}};
  GDALAllRegister();
  GDALDatasetH src = GDALOpen(ortho.string().c_str(), GA_ReadOnly);
  if (!src) return out;
  const int w = GDALGetRasterXSize(src), h = GDALGetRasterYSize(src);
  double gt[6];
  GDALGetGeoTransform(src, gt);
  const double cell = std::abs(gt[1]);
  const int half = std::max(8, static_cast<int>(std::ceil(1.5 / cell)));
  std::vector<Eigen::Vector2d> errors;
  for (const auto& p : report.value("check_points", json::object()).value("points", json::array())) {
    if (!p.contains("surveyed")) continue;
    json e = {{"name", p.value("name", "")}};
    const Eigen::Vector3d surveyed(p["surveyed"][0].get<double>(), p["surveyed"][1].get<double>(),
                                   p["surveyed"][2].get<double>());
    const Eigen::Vector3d q = deliverable.crs.FromGeodetic(output.crs.ToGeodetic(surveyed));
    const double px = (q.x() - gt[0]) / gt[1], py = (q.y() - gt[3]) / gt[5];
    const int x0 = static_cast<int>(px) - half, y0 = static_cast<int>(py) - half, size = 2 * half + 1;
    if (x0 < 0 || y0 < 0 || x0 + size > w || y0 + size > h) {
      e["located"] = false;
      e["reason"] = "outside the orthomosaic";
      out["points"].push_back(e);
      continue;
    }
    cv::Mat rgb[3], alpha;
    bool ok = true;
    for (int b = 0; b < 3 && ok; ++b) {
      rgb[b] = cv::Mat(size, size, CV_8U);
      ok = GDALRasterIO(GDALGetRasterBand(src, b + 1), GF_Read, x0, y0, size, size, rgb[b].data, size, size, GDT_Byte,
                        0, 0) == CE_None;
    }
    GDALRasterBandH mask = GDALGetRasterCount(src) >= 4 ? GDALGetRasterBand(src, 4)
                                                        : GDALGetMaskBand(GDALGetRasterBand(src, 1));
    alpha = cv::Mat(size, size, CV_8U);
    ok = ok && GDALRasterIO(mask, GF_Read, x0, y0, size, size, alpha.data, size, size, GDT_Byte, 0, 0) == CE_None;
    if (!ok || cv::countNonZero(alpha < 128) > 0) {
      e["located"] = false;
      e["reason"] = "the orthomosaic has gaps around it";
      out["points"].push_back(e);
      continue;
    }
    // Grey in float: 8-bit sums saturate on the white squares and bend the edges.
    cv::Mat grey(size, size, CV_32F, cv::Scalar(0)), f;
    for (const cv::Mat& band : rgb) {
      cv::Mat b32;
      band.convertTo(b32, CV_32F, 1.0 / 3.0);
      grey += b32;
    }
    cv::GaussianBlur(grey, f, cv::Size(0, 0), 1.5);
    cv::Mat dxx, dyy, dxy;
    cv::Sobel(f, dxx, CV_32F, 2, 0, 3);
    cv::Sobel(f, dyy, CV_32F, 0, 2, 3);
    cv::Sobel(f, dxy, CV_32F, 1, 1, 3);
    cv::Mat det = dxx.mul(dyy) - dxy.mul(dxy);
    double min_det, max_det;
    cv::Point at;
    const int border = 4;
    cv::minMaxLoc(det(cv::Rect(border, border, size - 2 * border, size - 2 * border)), &min_det, &max_det, &at);
    at += cv::Point(border, border);
    double lo, hi;
    cv::minMaxLoc(f, &lo, &hi);
    const double contrast = std::max(1.0, hi - lo);
    // A saddle of contrast c smoothed by sigma: |det| ~ (c / sigma^2)^2 x kernel gain; compare in the same units.
    if (!(min_det < 0) || std::sqrt(-min_det) < contrast / 3.0) {
      e["located"] = false;
      e["reason"] = "no target centre stands out";
      out["points"].push_back(e);
      continue;
    }
    // Sub-pixel: the stationary point of a quadratic fitted (least squares)
    // to the smoothed image over 7 x 7 cells, recentred until it settles; a
    // checker's centre is an exact saddle of the smoothed image.
    Eigen::Vector2d c(at.x, at.y);
    bool settled = false;
    for (int it = 0; it < 5 && !settled; ++it) {
      const int cx = static_cast<int>(std::lround(c.x())), cy = static_cast<int>(std::lround(c.y()));
      if (cx < 3 || cy < 3 || cx >= size - 3 || cy >= size - 3) break;
      Eigen::Matrix<double, 49, 6> a;
      Eigen::Matrix<double, 49, 1> b;
      int k = 0;
      for (int v = -3; v <= 3; ++v) {
        for (int u = -3; u <= 3; ++u, ++k) {
          a.row(k) << 1.0, u, v, u * u, u * v, v * v;
          b(k) = f.at<float>(cy + v, cx + u);
        }
      }
      const Eigen::Matrix<double, 6, 1> p = a.colPivHouseholderQr().solve(b);
      Eigen::Matrix2d h;
      h << 2 * p(3), p(4), p(4), 2 * p(5);
      if (!(h.determinant() < 0)) break;  // not a saddle
      const Eigen::Vector2d step = h.lu().solve(-Eigen::Vector2d(p(1), p(2)));
      if (step.norm() > 3.0) break;
      c = Eigen::Vector2d(cx, cy) + step;
      settled = step.cwiseAbs().maxCoeff() <= 0.5;
    }
    if (!settled) {
      e["located"] = false;
      e["reason"] = "the target centre does not fit a saddle";
      out["points"].push_back(e);
      continue;
    }
    // Pixel (i, j) centre is at i + 0.5 cells from the window's corner.
    const double x = gt[0] + (x0 + c.x() + 0.5) * gt[1], y = gt[3] + (y0 + c.y() + 0.5) * gt[5];
    const Eigen::Vector2d d(x - q.x(), y - q.y());
    e["located"] = true;
    e["d_m"] = {d.x(), d.y()};
    e["dh_m"] = d.norm();
    errors.push_back(d);
    out["points"].push_back(e);
  }
  GDALClose(src);
  double sx = 0, sy = 0;
  for (const auto& d : errors) sx += d.x() * d.x(), sy += d.y() * d.y();
  const int n = static_cast<int>(errors.size());
  out["count"] = n;
  if (n > 0) {
    out["rmse_x_m"] = std::sqrt(sx / n);
    out["rmse_y_m"] = std::sqrt(sy / n);
    out["rmse_h_m"] = std::sqrt((sx + sy) / n);
  }
  return out;
}

}  // namespace

namespace {

using DenseStep = PipelineOptions::DenseStep;

// The dense matching and fusion options of the pipeline's.
DenseOptions DenseOptionsOf(const PipelineOptions& o) {
  DenseOptions d;
  d.resolution_m = o.dense_resolution_m;
  d.image_scale = o.dense_image_scale;
  d.min_views = o.dense_min_views;
  d.num_threads = o.num_threads;
  d.work_dir = o.workspace / "depth";
  return d;
}

// A workflow's dense shares (PipelineOptions::DenseStep) keep their records
// and fused points in OUTPUT/dense_parts/: depth_K_of_N.json, and
// fused_K_of_N.pts with fused_K_of_N.json.
fs::path ShareFile(const PipelineOptions& o, const char* what, int k, const std::string& ext) {
  return o.workspace / "dense_parts" /
         (std::string(what) + "_" + std::to_string(k + 1) + "_of_" + std::to_string(o.dense_shares) + ext);
}

// A share's record, when it was made under the current dense options.
std::optional<json> CurrentShareRecord(const PipelineOptions& o, const fs::path& record) {
  if (!fs::exists(record)) return std::nullopt;
  json r = ReadJson(record, "dense");
  if (!FingerprintChanges(r.value("options", json()), DenseFingerprint(o)).empty()) return std::nullopt;
  return r;
}

// Every share's record of one step, or InvalidArgument naming the first
// missing (or stale) one and the job that makes it.
std::vector<json> ShareRecords(const PipelineOptions& o, const char* what, const char* option) {
  std::vector<json> records;
  for (int k = 0; k < o.dense_shares; ++k) {
    const fs::path record = ShareFile(o, what, k, ".json");
    std::optional<json> r = CurrentShareRecord(o, record);
    if (!r) {
      throw InvalidArgument(record.string() + (fs::exists(record) ? ": made under other dense options" : ": missing") +
                            "; run aerotri dense -o " + o.workspace.string() + " " + option + " " +
                            std::to_string(k + 1) + "/" + std::to_string(o.dense_shares) + " first");
    }
    records.push_back(std::move(*r));
  }
  return records;
}

// The fused points of a share on disk: "AERFUS01", then per point x, y, z
// (double, the deliverables' CRS) and r, g, b.
constexpr char kFusedMagic[8] = {'A', 'E', 'R', 'F', 'U', 'S', '0', '1'};
constexpr std::size_t kFusedRecord = 3 * sizeof(double) + 3;

void WriteFusedPoints(std::ostream& out, const DenseCloud& part) {
  std::vector<char> buffer(part.positions.size() * kFusedRecord);
  char* at = buffer.data();
  for (size_t k = 0; k < part.positions.size(); ++k) {
    std::memcpy(at, part.positions[k].data(), 3 * sizeof(double));
    std::memcpy(at + 3 * sizeof(double), part.colours[k].data(), 3);
    at += kFusedRecord;
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
}

// Reads a share's fused points in batches of at most `batch` points; the
// file must hold exactly `points` (its record's count).
void ReadFusedPoints(const fs::path& path, std::uint64_t points, std::size_t batch,
                     const std::function<void(const std::vector<Eigen::Vector3d>&,
                                              const std::vector<std::array<std::uint8_t, 3>>&)>& take) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (!in || !in.read(magic, 8) || std::memcmp(magic, kFusedMagic, 8) != 0 || ec ||
      size != 8 + points * kFusedRecord) {
    throw IoError(path.string(), "not the " + std::to_string(points) + " fused points its record names (" +
                                     (ec ? std::string("unreadable") : std::to_string(size) + " bytes") +
                                     "); run its fusion share again (--fuse-share K/N --force)");
  }
  std::vector<char> buffer;
  std::vector<Eigen::Vector3d> xyz;
  std::vector<std::array<std::uint8_t, 3>> rgb;
  for (std::uint64_t done = 0; done < points;) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(batch, points - done));
    buffer.resize(n * kFusedRecord);
    if (!in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()))) {
      throw IoError(path.string(), "cut short after " + std::to_string(done) + " points");
    }
    xyz.resize(n);
    rgb.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      std::memcpy(xyz[k].data(), buffer.data() + k * kFusedRecord, 3 * sizeof(double));
      std::memcpy(rgb[k].data(), buffer.data() + k * kFusedRecord + 3 * sizeof(double), 3);
    }
    take(xyz, rgb);
    done += n;
  }
}

// The report of a survey the dense stage may work from: georeferenced (a
// share throws, the whole stage warns and returns nullopt) and not failed
// (unless keep_going).
std::optional<json> DenseReport(const PipelineOptions& o) {
  json report = ReadJson(o.workspace / "report.json", "georeference");
  if (!report.value("georeferenced", false)) {
    if (o.dense_step == DenseStep::kDepthShare || o.dense_step == DenseStep::kFuseShare) {
      throw InvalidArgument((o.workspace / "report.json").string() +
                            ": the survey is not georeferenced; a dense share has nothing to work in");
    }
    Log(o, "warning: dense: the survey is not georeferenced; no cloud or DSM in a CRS is written");
    return std::nullopt;
  }
  if (report.value("status", "") == "failed" && !o.keep_going) {
    throw InvalidArgument((o.workspace / "report.json").string() +
                          ": the adjustment failed (see its errors); no cloud or DSM is written from it "
                          "(--keep-going writes them, tagged as failed)");
  }
  return report;
}

// One job of a workflow's dense stage: the depth maps of a share of the
// pairs, or the fusion of a share of the tiles (once every depth share is
// done) into the deliverables' CRS. Each writes only its own files; its
// record (with its time and peak memory) says it is done.
bool RunDenseShare(const PipelineOptions& o) {
  const bool depth_step = o.dense_step == DenseStep::kDepthShare;
  const int k = o.dense_share;
  const fs::path record = ShareFile(o, depth_step ? "depth" : "fused", k, ".json");
  const std::string what = std::string("dense: ") + (depth_step ? "depth maps" : "fusion") + " share " +
                           std::to_string(k + 1) + " of " + std::to_string(o.dense_shares);
  if (!o.force && CurrentShareRecord(o, record)) {
    Log(o, what + ": done already (" + record.string() + ")");
    return false;
  }
  const auto start = BeginStage();
  const json report = *DenseReport(o);
  // What was made from this step's earlier output is stale now: the fused
  // shares (after depth maps) and the deliverables' record, so that the
  // steps after this one rerun.
  if (depth_step) {
    for (int j = 0; j < o.dense_shares; ++j) {
      fs::remove(ShareFile(o, "fused", j, ".json"));
      fs::remove(ShareFile(o, "fused", j, ".pts"));
    }
  }
  fs::remove(o.workspace / "dense.json");
  fs::remove(o.workspace / "report.html");
  const IngestView ingest = LoadIngest(o);
  const SparseModel model = ReadSurveyModel(o, report);
  const fs::path images_dir = ingest.ImagesDir(o);
  const int max_dimension = ingest.record.working_max_dimension;
  const DenseOptions d = DenseOptionsOf(o);
  const DenseShare share{k, o.dense_shares};
  const ProgressCallback progress = StageProgress(o, "dense");
  fs::create_directories(record.parent_path());
  DenseSummary summary;
  json out = {{"share", k + 1}, {"shares", o.dense_shares}, {"options", DenseFingerprint(o)}};
  if (depth_step) {
    // This share's files of an earlier attempt are kept (resumed) only when
    // it ran under the same options; the model's own changes remove them
    // all (the georeference stage).
    const fs::path started = ShareFile(o, "depth", k, ".started.json");
    if (o.force || !CurrentShareRecord(o, started)) {
      for (const fs::path& f : DepthMapPaths(model, d, share)) fs::remove(f);
      WriteTextFileAtomically(started, json({{"options", DenseFingerprint(o)}}).dump(2) + "\n");
    }
    ComputeDepthMaps(
        model, [&](int i) { return LoadWorkingImage(images_dir / model.images[i].name, max_dimension); }, d, share,
        progress, &summary);
    out["pairs"] = summary.pairs;
    out["pairs_failed"] = summary.pairs_failed;
    out["depth_points"] = summary.depth_points;
    Log(o, what + ": " + std::to_string(summary.pairs) + " depth maps (" + std::to_string(summary.pairs_failed) +
               " pairs failed)");
  } else {
    // Every depth map the depth shares made must still be there (a
    // finished dense stage removes them): fusing fewer would thin the
    // cloud where they are missing, silently.
    int made = 0, present = 0;
    for (const json& r : ShareRecords(o, "depth", "--depth-share")) made += r.value("pairs", 0);
    for (const fs::path& f : DepthMapPaths(model, d, DenseShare{})) present += fs::exists(f) ? 1 : 0;
    if (present != made) {
      throw InvalidArgument(d.work_dir.string() + ": " + std::to_string(present) + " depth maps where the depth "
                            "shares made " + std::to_string(made) + "; run them again (aerotri dense --depth-share "
                            "K/" + std::to_string(o.dense_shares) + " --force for each K)");
    }
    const GeoFrame g = FrameOf(report);
    std::string heights;
    const GeoFrame deliverable{g.frame, DeliverableCrs(g, o, &heights)};
    FusedTileSink sink;
    sink.prepare = [&](DenseCloud* part) {
      const Crs crs = Crs::FromString(deliverable.crs.definition());  // one per thread: PROJ objects are not shared
      for (Eigen::Vector3d& p : part->positions) p = crs.FromGeodetic(deliverable.frame.GeodeticFromEnu(p));
    };
    const fs::path points = ShareFile(o, "fused", k, ".pts");
    WriteFileAtomically(points, [&](std::ostream& stream) {
      stream.write(kFusedMagic, 8);
      sink.consume = [&](DenseCloud&& part) { WriteFusedPoints(stream, part); };
      FuseModelDepthMaps(model, d, share, progress, sink, &summary);
    });
    out["points"] = summary.fused_points;
    out["tiles"] = summary.tiles;
    out["resolution_m"] = summary.resolution_m;
    Log(o, what + ": " + std::to_string(summary.fused_points) + " points in " + std::to_string(summary.tiles) +
               " tiles");
  }
  out["wall_s"] = std::chrono::duration<double>(Clock::now() - start).count();
  out["peak_rss_mb"] = PeakRssMb();
  WriteTextFileAtomically(record, out.dump(2) + "\n");
  return true;
}

}  // namespace

namespace {

// Whether the dense products stand as made under these options: false with
// *why when an option changed or a product was damaged since it was written
// (the stage reruns), true when done already.
bool DenseProductsCurrent(const PipelineOptions& o, std::string* why, bool* damaged_out) {
  const json recorded =
      fs::exists(o.workspace / "dense.json") ? ReadJson(o.workspace / "dense.json", "dense") : json::object();
  const std::string changed = FingerprintChanges(recorded.value("options", json()), DenseFingerprint(o));
  // A product whose size is not the one recorded when it was written has
  // been damaged since (truncated copy, disk error): rebuild, never read it.
  std::string damaged;
  const json file_bytes = recorded.value("file_bytes", json::object());  // items() needs it alive
  for (const auto& [name, bytes] : file_bytes.items()) {
    std::error_code ec;
    const auto size = fs::file_size(o.workspace / name, ec);
    if (ec || !bytes.is_number() || size != bytes.get<std::uintmax_t>()) {
      damaged += (damaged.empty() ? "" : ", ") + (o.workspace / name).string() + " (" +
                 (ec ? std::string("unreadable") : std::to_string(size)) + " bytes, " + bytes.dump() + " written)";
    }
  }
  *damaged_out = !damaged.empty();
  if (!damaged.empty()) {
    *why = damaged;
    return false;
  }
  *why = changed;
  return changed.empty();
}

// The cloud products' options: DSM, ground classes and the deliverable CRS.
CloudProductOptions CloudProductOptionsOf(const PipelineOptions& o, const GeoFrame& deliverable, bool classify) {
  CloudProductOptions products;
  products.dsm.fill_max_distance_m = o.dsm_fill_m;
  products.dsm.work_dir = o.workspace;  // GDAL work files stay in the workspace
  products.classify = classify;
  products.ground.cell_m = o.ground_cell_m;
  products.ground.max_window_m = o.ground_window_m;
  products.ground.slope = o.ground_slope;
  products.ground.elevation_threshold_m = o.ground_threshold_m;
  products.threads = Threads(o);
  products.las_wkt = deliverable.crs.WktV1();
  products.raster_wkt = deliverable.crs.Wkt();
  products.crs_name = deliverable.crs.Name();
  return products;
}

// The shares' fused points, in share order: the cloud one fusion gives.
void ReadFusedShares(const PipelineOptions& o, const ProgressCallback& dense_progress, DenseSummary* summary_out,
                     const std::function<void(const std::vector<Eigen::Vector3d>&,
                                              const std::vector<std::array<std::uint8_t, 3>>&, double)>& add) {
  DenseSummary& summary = *summary_out;
  const std::vector<json> depth = ShareRecords(o, "depth", "--depth-share");
  const std::vector<json> fused = ShareRecords(o, "fused", "--fuse-share");
  for (const json& r : depth) {
    summary.pairs += r.value("pairs", 0);
    summary.pairs_failed += r.value("pairs_failed", 0);
    summary.depth_points += r.value("depth_points", 0LL);
  }
  std::uint64_t total = 0;
  for (const json& r : fused) total += r.value("points", std::uint64_t{0});
  std::uint64_t read = 0;
  for (int k = 0; k < o.dense_shares; ++k) {
    const json& r = fused[k];
    summary.tiles += r.value("tiles", 0);
    summary.resolution_m = r.value("resolution_m", 0.0);
    const std::uint64_t n = r.value("points", std::uint64_t{0});
    ReadFusedPoints(ShareFile(o, "fused", k, ".pts"), n, std::size_t{1} << 20,
                    [&](const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::array<std::uint8_t, 3>>& rgb) {
                      add(xyz, rgb, summary.resolution_m);
                      read += xyz.size();
                      ReportProgress(ProgressPart(dense_progress, 0.0, 0.8),
                                     total > 0 ? static_cast<double>(read) / total : 1.0,
                                     "fused shares: " + std::to_string(read) + " of " + std::to_string(total) +
                                         " points");
                    });
    summary.fused_points += static_cast<long long>(n);
  }
}

// The DTM and contours from the ground points (where ground was classified),
// with their figures for dense.json.
void WriteTerrainProducts(const PipelineOptions& o, const CloudProducts& made, const CloudProductOptions& products,
                          const std::string& status, const std::string& heights, bool classify, json* dtm_info_out,
                          json* contour_info_out, json* ground_info_out) {
  const fs::path dtm = o.workspace / "dtm.tif", contours = o.workspace / "contours.gpkg";
  json& dtm_info = *dtm_info_out;
  json& contour_info = *contour_info_out;
  json& ground_info = *ground_info_out;
  const GroundFilterSummary& ground = made.ground;
  const GroundFilterOptions& gf = products.ground;
  if (made.has_dtm) {
    const DtmSummary& dtm_summary = made.dtm_summary;
    const Raster& dtm_raster = made.dtm;
    RasterWriteOptions w;
    w.cog = o.cog;
    if (!status.empty()) w.metadata["AEROTRI_SURVEY_STATUS"] = status;
    w.metadata["AEROTRI_HEIGHTS"] = heights;
    w.metadata["AEROTRI_SURFACE"] = "bare earth: ground points (SMRF), interpolated under objects";
    WriteRaster(dtm_raster, dtm, w);
    const double cells = static_cast<double>(dtm_raster.width) * dtm_raster.height;
    dtm_info = {{"file", "dtm.tif"},
                {"cells_ground", dtm_summary.cells_ground},
                {"cells_interpolated", dtm_summary.cells_interpolated},
                {"interpolated_fraction", cells > 0 ? dtm_summary.cells_interpolated / cells : 0.0}};
    ContourOptions co;
    co.interval_m = o.contour_interval_m;
    ContourSummary cs;
    WriteContours(dtm_raster, contours, co, &cs);
    contour_info = {{"file", "contours.gpkg"},     {"interval_m", cs.interval_m},
                    {"index_every", co.index_every}, {"smoothing_sigma_m", cs.smoothing_sigma_m},
                    {"lines", cs.lines},           {"dropped_short", cs.dropped_short}};
    ground_info = {{"method", "SMRF (Pingel et al. 2013)"},
                   {"cell_m", gf.cell_m},
                   {"window_m", gf.max_window_m},
                   {"slope", gf.slope},
                   {"threshold_m", gf.elevation_threshold_m},
                   {"ground", ground.ground},
                   {"above_ground", ground.above},
                   {"noise", ground.noise}};
  } else {
    for (const fs::path& stale : {dtm, contours}) fs::remove(stale);
    Log(o, classify ? "warning: dense: no ground points; no DTM or contours"
                    : "warning: dense: ground filtering needs a projected CRS; no DTM or contours");
  }
}

// What the cloud file holds, for dense.json and the report: its format and
// size, and the size of the same points as uncompressed LAS.
json CloudSummary(const PipelineOptions& o, const fs::path& file, std::uint64_t points) {
  const std::uintmax_t bytes = fs::file_size(file);
  const std::uint64_t las_bytes = 375 + 54 + 512 + 36 * points;  // header, CRS record, records (about)
  json c = {{"file", CloudFileName(o)}, {"format", o.cloud_format}, {"points", points}, {"bytes", bytes},
            {"uncompressed_las_bytes", las_bytes}};
  if (o.cloud_format != "las") c["compression_ratio"] = static_cast<double>(bytes) / static_cast<double>(las_bytes);
  return c;
}

// The cloud a finished dense stage wrote: as dense.json records it, else
// the file of this run's format, else whichever is there.
std::string CloudFileOf(const PipelineOptions& o, const json& dense) {
  const std::string recorded = dense.value("cloud", json::object()).value("file", "");
  if (!recorded.empty()) return recorded;
  if (fs::exists(o.workspace / CloudFileName(o))) return CloudFileName(o);
  for (const char* name : {"cloud.laz", "cloud.copc.laz", "cloud.las"}) {
    if (fs::exists(o.workspace / name)) return name;
  }
  return CloudFileName(o);
}

}  // namespace

bool RunDenseStage(const PipelineOptions& o) {
  if (o.dense_step == DenseStep::kDepthShare || o.dense_step == DenseStep::kFuseShare) return RunDenseShare(o);
  const fs::path las = o.workspace / CloudFileName(o), ply = o.workspace / "cloud.ply", dsm = o.workspace / "dsm.tif";
  const fs::path dtm = o.workspace / "dtm.tif", contours = o.workspace / "contours.gpkg";
  bool rerun = o.force;
  if (fs::exists(las) && fs::exists(ply) && fs::exists(dsm) && fs::exists(dtm) && fs::exists(contours) && !o.force) {
    std::string why;
    bool damaged = false;
    if (DenseProductsCurrent(o, &why, &damaged)) {
      Log(o, "dense: done already (" + las.string() + ")");
      RemoveDepthMaps(o);  // a run killed between the products and the removal
      return false;
    }
    Log(o, damaged ? "warning: dense: damaged since it was written: " + why + "; rebuilding the dense products"
                   : "dense: options changed (" + why + "): rerunning");
    rerun = true;
  }
  const auto start = BeginStage();
  const bool from_shares = o.dense_step == DenseStep::kFromShares;
  // The shares' depth maps are theirs (each share removes its own stale ones).
  if (rerun && !from_shares) fs::remove_all(o.workspace / "depth");
  const std::optional<json> georeferenced = DenseReport(o);
  if (!georeferenced) return false;
  const json& report = *georeferenced;
  const GeoFrame g = FrameOf(report);
  const DenseOptions d = DenseOptionsOf(o);
  DenseSummary summary;
  // The fused cloud goes to disk in tiles of the output CRS as it is fused
  // (never whole in memory: 300 million points at 1,000 photos), and the
  // files and rasters are made from the tiles (cloud_tiles.h).
  std::string heights;
  const GeoFrame deliverable{g.frame, DeliverableCrs(g, o, &heights)};
  const bool classify = !deliverable.crs.IsGeographic() && !deliverable.crs.IsGeocentric();
  CloudProductOptions products = CloudProductOptionsOf(o, deliverable, classify);
  const ProgressCallback dense_progress = StageProgress(o, "dense");  // one clock for the stage's phases
  std::unique_ptr<TiledCloud> tiles;  // made with the first fused tile, which gives the resolution
  FusedTileSink sink;
  sink.prepare = [&](DenseCloud* part) {
    const Crs crs = Crs::FromString(deliverable.crs.definition());  // one per thread: PROJ objects are not shared
    for (Eigen::Vector3d& p : part->positions) p = crs.FromGeodetic(deliverable.frame.GeodeticFromEnu(p));
  };
  auto add = [&](const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::array<std::uint8_t, 3>>& rgb,
                 double resolution_m) {
    if (!tiles) {
      products.dsm.resolution_m = DsmResolution(o, resolution_m);
      // About 3.6 million points a tile whatever the GSD (some 3.6 points
      // a voxel column): one tile per thread is ~0.3 GB at the most.
      const double tile_m = std::max(20.0, 1000.0 * resolution_m);
      tiles = std::make_unique<TiledCloud>(o.workspace / "dense_tiles", tile_m, CloudProductsHalo(products));
    }
    tiles->Add(xyz, rgb);
  };
  if (from_shares) {
    ReadFusedShares(o, dense_progress, &summary, add);
  } else {
    const IngestView ingest = LoadIngest(o);
    const SparseModel model = ReadSurveyModel(o, report);
    const fs::path images_dir = ingest.ImagesDir(o);
    const int max_dimension = ingest.record.working_max_dimension;
    sink.consume = [&](DenseCloud&& part) { add(part.positions, part.colours, part.resolution_m); };
    ComputeDenseCloud(
        model, [&](int i) { return LoadWorkingImage(images_dir / model.images[i].name, max_dimension); }, d,
        ProgressPart(dense_progress, 0.0, 0.8), sink, &summary);
  }
  if (tiles) tiles->Finish();
  // The shares' fused points, once the products are written (until then an
  // interrupted products step reads them again).
  const auto remove_fused_points = [&]() {
    if (!from_shares) return;
    for (int k = 0; k < o.dense_shares; ++k) fs::remove(ShareFile(o, "fused", k, ".pts"));
  };
  // Fused: the tiles hold the cloud now, and the depth maps (25 GB at 1,000
  // photos) need not share the disk with the LAS and PLY being written. An
  // interruption from here on recomputes them.
  RemoveDepthMaps(o);
  if (!tiles || tiles->count() == 0) {
    // The sparse survey stands; say why there is no cloud instead of failing the run.
    const std::string why = summary.pairs + summary.pairs_failed == 0
                                ? "no pair of photos suits rectified stereo (none side by side with enough "
                                  "shared points and parallax)"
                                : "no depth points agreed in " + std::to_string(d.min_views) +
                                      " depth maps (" + std::to_string(summary.pairs) + " pairs matched, " +
                                      std::to_string(summary.pairs_failed) + " failed)";
    Log(o, "warning: dense: " + why + "; no cloud or DSM written");
    for (const fs::path& stale : {las, ply, dsm, dtm, contours, o.workspace / "ortho.tif"}) {
      fs::remove(stale);  // of an earlier model
    }
    WriteTextFileAtomically(o.workspace / "dense.json",
                            json({{"points", 0}, {"pairs", summary.pairs}, {"skipped", why}}).dump(2) + "\n");
    if (tiles) tiles->Remove();
    remove_fused_points();
    RecordTiming(o, "dense", std::chrono::duration<double>(Clock::now() - start).count());
    return false;
  }
  const double cloud_resolution = summary.resolution_m;
  const std::uint64_t points = tiles->count();
  Log(o, "dense: " + std::to_string(points) + " points fused into " + std::to_string(tiles->num_tiles()) +
             " tiles of " + std::to_string(static_cast<int>(std::lround(tiles->tile_m()))) +
             " m; writing the cloud, DSM and ground classes");
  CloudProducts made = WriteCloudProducts(*tiles, las, ply, products, ProgressPart(dense_progress, 0.8, 1.0));
  tiles->Remove();
  tiles.reset();
  json dsm_info;
  const std::string status = report.value("status", "");
  WriteDsmRaster(made.dsm, made.dsm_summary, products.dsm.resolution_m, o, status, heights, dsm, &dsm_info);
  json dtm_info = json::object(), contour_info = json::object(), ground_info = json::object();
  WriteTerrainProducts(o, made, products, status, heights, classify, &dtm_info, &contour_info, &ground_info);
  // A cloud of another format, of an earlier run, is not this run's.
  for (const char* other : {"cloud.las", "cloud.laz", "cloud.copc.laz"}) {
    if (other != CloudFileName(o)) fs::remove(o.workspace / other);
  }
  json file_bytes = {{CloudFileName(o), fs::file_size(las)}, {"cloud.ply", fs::file_size(ply)},
                     {"dsm.tif", fs::file_size(dsm)}};
  if (fs::exists(dtm)) file_bytes["dtm.tif"] = fs::file_size(dtm);
  if (fs::exists(contours)) file_bytes["contours.gpkg"] = fs::file_size(contours);
  const json dense = {{"pairs", summary.pairs},
                      {"pairs_failed", summary.pairs_failed},
                      {"depth_points", summary.depth_points},
                      {"points", points},
                      {"resolution_m", cloud_resolution},
                      {"min_views", d.min_views},
                      {"tiles", summary.tiles},
                      {"crs", deliverable.crs.definition()},
                      {"heights", heights},
                      {"dsm", dsm_info},
                      {"dtm", dtm_info},
                      {"contours", contour_info},
                      {"ground", ground_info},
                      {"options", DenseFingerprint(o)},
                      {"file_bytes", file_bytes},
                      {"cloud", CloudSummary(o, las, points)}};
  WriteTextFileAtomically(o.workspace / "dense.json", dense.dump(2) + "\n");
  remove_fused_points();
  fs::remove(o.workspace / "report.html");  // its DSM figures are stale: the report stage reruns
  Log(o, "dense: " + std::to_string(points) + " points at " + std::to_string(cloud_resolution) +
             " m; DSM " + std::to_string(dsm_info["width"].get<int>()) + " x " +
             std::to_string(dsm_info["height"].get<int>()) + "; " + heights);
  RecordTiming(o, "dense", std::chrono::duration<double>(Clock::now() - start).count());
  return true;
}

bool RunReportStage(const PipelineOptions& o) {
  const fs::path html = o.workspace / "report.html";
  if (fs::exists(html) && !o.force) {
    Log(o, "report: done already (" + html.string() + ")");
    return false;
  }
  const auto start = BeginStage();
  json report = ReadJson(o.workspace / "report.json", "georeference");
  std::map<std::string, std::string> previews;
  if (fs::exists(o.workspace / "dense.json")) {
    const json dense = json::parse(ReadTextFile(o.workspace / "dense.json"));
    if (dense.contains("skipped")) report["dense"] = {{"points", 0}, {"skipped", dense["skipped"]}};
  }
  for (const char* key : {"dtm", "contours", "ground", "ortho", "heights"}) report.erase(key);
  if (fs::exists(o.workspace / "dsm.tif") && fs::exists(o.workspace / "dense.json")) {
    const json dense = json::parse(ReadTextFile(o.workspace / "dense.json"));
    const GeoFrame g = FrameOf(report);
    const GeoFrame deliverable = DeliverableFrame(report, dense);
    const Raster dsm = ReadRaster(o.workspace / "dsm.tif");
    report["dense"] = {{"points", dense["points"]}, {"resolution_m", dense["resolution_m"]},
                       {"pairs", dense["pairs"]}, {"files", {CloudFileOf(o, dense), "cloud.ply"}},
                       {"cloud", dense.value("cloud", json::object())},
                       {"options", dense.value("options", json::object())}};
    report["heights"] = {{"crs", deliverable.crs.definition()},
                         {"crs_name", deliverable.crs.Name()},
                         {"description", dense.value("heights", "as the output CRS defines them")}};
    report["dsm"] = dense["dsm"];
    report["dsm"]["check_points"] = DsmAtCheckPoints(report, dsm, g, deliverable);
    const SparseModel georeferenced = ReadColmapText(o.workspace / "georeferenced");
    report["coverage"] = Coverage(georeferenced, dsm, deliverable);
    report["dsm"]["footprint_coverage"] = FootprintCoverage(georeferenced, dsm, deliverable);
    DsmPreview preview = DsmPreviewPng(o.workspace / "dsm.tif", 900);
    if (!preview.png.empty()) {
      report["dsm"]["preview"] = preview.info;
      previews["dsm"] = preview.png;
    }
    if (dense.contains("ground") && !dense["ground"].empty()) report["ground"] = dense["ground"];
    if (dense.contains("contours") && !dense["contours"].empty()) report["contours"] = dense["contours"];
    if (fs::exists(o.workspace / "dtm.tif") && dense.contains("dtm") && !dense["dtm"].empty()) {
      report["dtm"] = dense["dtm"];
      const Raster dtm = ReadRaster(o.workspace / "dtm.tif");
      report["dtm"]["check_points"] = DsmAtCheckPoints(report, dtm, g, deliverable);
      DsmPreview p = DsmPreviewPng(o.workspace / "dtm.tif", 900);
      if (!p.png.empty()) {
        report["dtm"]["preview"] = p.info;
        previews["dtm"] = p.png;
      }
    }
    if (fs::exists(o.workspace / "ortho.tif") && fs::exists(o.workspace / "ortho.json")) {
      const json ortho = json::parse(ReadTextFile(o.workspace / "ortho.json"));
      report["ortho"] = ortho.value("ortho", json::object());
      report["ortho"]["check_points"] = OrthoAtCheckPoints(report, o.workspace / "ortho.tif", g, deliverable);
      DsmPreview p = OrthoPreviewPng(o.workspace / "ortho.tif", 900);
      if (!p.png.empty()) {
        report["ortho"]["preview"] = p.info;
        previews["ortho"] = p.png;
      }
    }
  }
  RecordTiming(o, "report", std::chrono::duration<double>(Clock::now() - start).count());
  report["timings"] = json::parse(ReadTextFile(o.workspace / "timings.json"));
  WriteTextFileAtomically(o.workspace / "report.json", report.dump(2) + "\n");
  WriteTextFileAtomically(html, RenderHtmlReport(report, previews));
  WriteReviewPage(o, report);
  return true;
}

namespace {

// A workflow's bands: OUTPUT/ortho_parts/band_K_of_N.tif and .json.
fs::path OrthoBandFile(const PipelineOptions& o, int k, const char* ext) {
  return o.workspace / "ortho_parts" / ("band_" + std::to_string(k + 1) + "_of_" + std::to_string(o.ortho_shares) + ext);
}

// A band's record when it was drawn from this surface and model under these options.
std::optional<json> CurrentOrthoBand(const PipelineOptions& o, int k, const json& fingerprint) {
  if (!fs::exists(OrthoBandFile(o, k, ".json"))) return std::nullopt;
  json r = ReadJson(OrthoBandFile(o, k, ".json"), "ortho");
  if (!FingerprintChanges(r.value("options", json()), fingerprint).empty()) return std::nullopt;
  return r;
}

// The orthomosaic's options: resolution (the cloud's, else asked), output
// format, and the survey's status in its metadata.
OrthoOptions OrthoOptionsOf(const PipelineOptions& o, const json& dense, const json& report,
                            const std::string& surface_name) {
  OrthoOptions oo;
  oo.resolution_m = o.ortho_resolution_m > 0 ? o.ortho_resolution_m
                                             : std::max(0.005, std::round(dense.value("resolution_m", 0.1) * 1000.0) / 1000.0);
  oo.compress = o.ortho_compress;
  oo.cog = o.ortho_cog;
  oo.num_threads = o.num_threads;
  oo.work_dir = o.workspace;
  oo.metadata["AEROTRI_SURFACE"] = surface_name;
  if (!report.value("status", "").empty()) oo.metadata["AEROTRI_SURVEY_STATUS"] = report.value("status", "");
  return oo;
}

// One band of the workflow's orthomosaic, with its record; the deliverable
// is the last job's.
void DrawOrthoBand(const PipelineOptions& o, const SparseModel& model, const std::function<cv::Mat(int)>& load,
                   const Raster& surface, const CrsToWorldFactory& to_world, OrthoOptions oo, const json& fingerprint,
                   Clock::time_point start) {
  const fs::path record = o.workspace / "ortho.json";
  OrthoSummary summary;
  fs::remove(record);
  fs::remove(o.workspace / "report.html");
  fs::create_directories(o.workspace / "ortho_parts");
  const int k = o.ortho_share;
  oo.share_index = k;
  oo.share_count = o.ortho_shares;
  fs::remove(OrthoBandFile(o, k, ".tif"));
  WriteOrthomosaic(model, load, surface, to_world, oo, OrthoBandFile(o, k, ".tif"), StageProgress(o, "ortho"),
                   &summary);
  json images = json::array();
  for (int i : summary.images) images.push_back(model.images[i].name);
  const json band = {{"share", k + 1},
                     {"shares", o.ortho_shares},
                     {"band", summary.band_height > 0},
                     {"band_y", summary.band_y},
                     {"band_height", summary.band_height},
                     {"width", summary.width},
                     {"height", summary.height},
                     {"images", images},
                     {"cells_with_surface", summary.cells_with_surface},
                     {"cells_filled", summary.cells_filled},
                     {"surface_cells_interpolated", summary.surface_cells_interpolated},
                     {"resolution_m", oo.resolution_m},
                     {"wall_s", std::chrono::duration<double>(Clock::now() - start).count()},
                     {"peak_rss_mb", PeakRssMb()},
                     {"options", fingerprint}};
  WriteTextFileAtomically(OrthoBandFile(o, k, ".json"), band.dump(2) + "\n");
  Log(o, "ortho: band " + std::to_string(k + 1) + " of " + std::to_string(o.ortho_shares) + ": " +
             std::to_string(summary.band_height) + " rows from " + std::to_string(summary.images.size()) +
             " photos");
}

// The bands, in order, joined into the deliverable; every one drawn from
// this surface and model.
void JoinOrthoBands(const PipelineOptions& o, const json& fingerprint, const OrthoOptions& oo, const fs::path& path,
                    OrthoSummary* summary_out) {
  OrthoSummary& summary = *summary_out;
  std::vector<fs::path> bands;
  std::set<std::string> images;
  for (int k = 0; k < o.ortho_shares; ++k) {
    const std::optional<json> r = CurrentOrthoBand(o, k, fingerprint);
    if (!r) {
      throw InvalidArgument(OrthoBandFile(o, k, ".json").string() +
                            (fs::exists(OrthoBandFile(o, k, ".json")) ? ": drawn from another surface, model or options"
                                                                      : ": missing") +
                            "; run aerotri ortho -o " + o.workspace.string() + " --band-share " +
                            std::to_string(k + 1) + "/" + std::to_string(o.ortho_shares) + " first");
    }
    if (r->value("band", false)) bands.push_back(OrthoBandFile(o, k, ".tif"));
    for (const auto& name : r->value("images", json::array())) images.insert(name.get<std::string>());
    summary.width = r->value("width", 0);
    summary.height = r->value("height", 0);
    summary.cells_with_surface += r->value("cells_with_surface", 0LL);
    summary.cells_filled += r->value("cells_filled", 0LL);
    summary.surface_cells_interpolated = r->value("surface_cells_interpolated", 0LL);
  }
  summary.images_used = static_cast<int>(images.size());
  summary.filled_fraction = summary.cells_with_surface > 0
                                ? static_cast<double>(summary.cells_filled) / summary.cells_with_surface
                                : 0.0;
  ReportProgress(StageProgress(o, "ortho"), 0.0, "orthomosaic: joining " + std::to_string(bands.size()) + " bands");
  AssembleOrthomosaic(bands, oo, path);
}

}  // namespace

bool RunOrthoStage(const PipelineOptions& o) {
  const fs::path path = o.workspace / "ortho.tif", record = o.workspace / "ortho.json";
  if (!o.ortho) {
    Log(o, "ortho: not asked for (--no-ortho)");
    return false;
  }
  const json dense = ReadJson(o.workspace / "dense.json", "dense");
  const std::string surface_name = o.ortho_surface == "dtm" ? "dtm.tif" : "dsm.tif";
  const fs::path surface_path = o.workspace / surface_name;
  if (dense.contains("skipped") || !fs::exists(surface_path)) {
    Log(o, "warning: ortho: no " + surface_name + " to project the photos through; no orthomosaic");
    fs::remove(path);
    return false;
  }
  // What the ortho depends on: its options and the surface it was drawn on.
  json fingerprint = OrthoFingerprint(o);
  fingerprint["surface"] = ContentHash(surface_path);
  fingerprint["sparse"] = ContentHash(o.workspace / "georeferenced" / "images.txt");
  // (A band is drawn when asked for: its record, not ortho.tif, says it is done.)
  if (fs::exists(path) && fs::exists(record) && !o.force && o.ortho_step != PipelineOptions::OrthoStep::kBandShare) {
    const json recorded = ReadJson(record, "ortho");
    const std::string changed = FingerprintChanges(recorded.value("options", json()), fingerprint);
    std::error_code ec;
    const auto bytes = fs::file_size(path, ec);
    if (!ec && recorded.value("file_bytes", json::object()).value("ortho.tif", std::uintmax_t{0}) == bytes &&
        changed.empty()) {
      Log(o, "ortho: done already (" + path.string() + ")");
      return false;
    }
    Log(o, "ortho: " + (changed.empty() ? std::string("ortho.tif damaged since it was written") : "inputs changed (" + changed + ")") + ": rerunning");
  }
  using OrthoStep = PipelineOptions::OrthoStep;
  const bool band_step = o.ortho_step == OrthoStep::kBandShare, from_shares = o.ortho_step == OrthoStep::kFromShares;
  if (band_step && !o.force && CurrentOrthoBand(o, o.ortho_share, fingerprint)) {
    Log(o, "ortho: band " + std::to_string(o.ortho_share + 1) + " of " + std::to_string(o.ortho_shares) +
               ": done already (" + OrthoBandFile(o, o.ortho_share, ".json").string() + ")");
    return false;
  }
  const auto start = BeginStage();
  const json report = ReadJson(o.workspace / "report.json", "georeference");
  if (report.value("status", "") == "failed" && !o.keep_going) {
    throw InvalidArgument((o.workspace / "report.json").string() +
                          ": the adjustment failed (see its errors); no orthomosaic is drawn from it "
                          "(--keep-going draws it, tagged as failed)");
  }
  const GeoFrame deliverable = DeliverableFrame(report, dense);
  IngestView ingest = LoadIngest(o);
  const SparseModel model = ReadSurveyModel(o, report);
  const fs::path images_dir = ingest.ImagesDir(o);
  const int max_dimension = ingest.record.working_max_dimension;
  const Raster surface = ReadRaster(surface_path);
  OrthoOptions oo = OrthoOptionsOf(o, dense, report, surface_name);
  const std::string definition = deliverable.crs.definition();
  const LocalFrame frame = deliverable.frame;
  const CrsToWorldFactory to_world = [definition, frame]() -> CrsToWorld {
    auto crs = std::make_shared<Crs>(Crs::FromString(definition));
    return [crs, frame](const Eigen::Vector3d& xyz) { return frame.EnuFromGeodetic(crs->ToGeodetic(xyz)); };
  };
  OrthoSummary summary;
  const std::function<cv::Mat(int)> load = [&](int i) {
    return LoadWorkingImage(images_dir / model.images[i].name, max_dimension);
  };
  if (band_step) {
    DrawOrthoBand(o, model, load, surface, to_world, oo, fingerprint, start);
    return true;
  }
  if (from_shares) {
    JoinOrthoBands(o, fingerprint, oo, path, &summary);
  } else {
    WriteOrthomosaic(model, load, surface, to_world, oo, path, StageProgress(o, "ortho"), &summary);
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  const json out = {{"ortho",
                     {{"file", "ortho.tif"},
                      {"resolution_m", oo.resolution_m},
                      {"width", summary.width},
                      {"height", summary.height},
                      {"surface", surface_name},
                      {"images_used", summary.images_used},
                      {"filled_fraction", summary.filled_fraction},
                      {"surface_holes_interpolated_fraction",
                       surface.values.empty() ? 0.0
                                              : static_cast<double>(summary.surface_cells_interpolated) /
                                                    static_cast<double>(surface.values.size())},
                      {"compress", oo.compress},
                      {"cog", oo.cog},
                      {"seconds", seconds}}},
                    {"options", fingerprint},
                    {"file_bytes", {{"ortho.tif", fs::file_size(path)}}}};
  WriteTextFileAtomically(record, out.dump(2) + "\n");
  if (from_shares) {
    for (int k = 0; k < o.ortho_shares; ++k) fs::remove(OrthoBandFile(o, k, ".tif"));  // in ortho.tif now
  }
  fs::remove(o.workspace / "report.html");  // the report shows the ortho: it reruns
  Log(o, "ortho: " + std::to_string(summary.width) + " x " + std::to_string(summary.height) + " at " +
             std::to_string(oo.resolution_m) + " m from " + std::to_string(summary.images_used) + " photos, " +
             std::to_string(100.0 * summary.filled_fraction).substr(0, 5) + " % of the surface filled");
  RecordTiming(o, "ortho", seconds);
  return true;
}

fs::path RebuildDsm(const PipelineOptions& o, fs::path path) {
  const json report = ReadJson(o.workspace / "report.json", "georeference");
  double resolution = o.dsm_resolution_m;
  if (!(resolution > 0)) {
    const json dense = ReadJson(o.workspace / "dense.json", "dense");
    const double spacing = dense.value("resolution_m", 0.0);
    if (!(spacing > 0)) {
      throw ParseError((o.workspace / "dense.json").string(), 0,
                       "no positive 'resolution_m' (the dense spacing) to choose the DSM resolution from; "
                       "give --dsm-resolution");
    }
    resolution = DsmResolution(o, spacing);
  }
  if (path.empty()) {
    char name[64];
    std::snprintf(name, sizeof(name), "dsm_%gm.tif", resolution);
    path = o.workspace / name;
  }
  const json dense = fs::exists(o.workspace / "dense.json") ? ReadJson(o.workspace / "dense.json", "dense") : json::object();
  const GeoFrame g = DeliverableFrame(report, dense);  // the cloud is in it
  const fs::path cloud = o.workspace / CloudFileOf(o, dense);
  // The cloud read in batches into CRS tiles, and the DSM made tile by
  // tile, as the dense stage makes it: never the whole cloud in memory.
  CloudProductOptions products;
  products.dsm.resolution_m = resolution;
  products.dsm.fill_max_distance_m = o.dsm_fill_m;
  products.dsm.work_dir = o.workspace;
  products.classify = false;
  products.threads = Threads(o);
  products.raster_wkt = g.crs.Wkt();
  const double spacing = dense.value("resolution_m", 0.0) > 0 ? dense.value("resolution_m", 0.0) : resolution / 2;
  TiledCloud tiles(o.workspace / (path.filename().string() + ".tiles"), std::max(20.0, 1000.0 * spacing),
                   CloudProductsHalo(products));
  ReadLasInBatches(cloud, [&](CrsCloud&& batch) { tiles.Add(batch.xyz, batch.rgb); });
  tiles.Finish();
  if (tiles.count() == 0) {
    tiles.Remove();
    throw InvalidArgument(cloud.string() + ": no points");
  }
  const CloudProducts made = WriteCloudProducts(tiles, {}, {}, products, StageProgress(o, "dem"));
  tiles.Remove();
  json info;
  WriteDsmRaster(made.dsm, made.dsm_summary, resolution, o, report.value("status", ""), dense.value("heights", ""),
                 path, &info);
  Log(o, "dem: " + path.string() + " " + std::to_string(info["width"].get<int>()) + " x " +
             std::to_string(info["height"].get<int>()) + " cells, " +
             std::to_string(100.0 * info["filled_fraction"].get<double>()) + " % with data");
  return path;
}

namespace {

// The check points of options.checkpoints triangulated from the adjusted
// cameras alone, into report.json's check_points and asprs.
void CheckPointsOnSurvey(const PipelineOptions& o, json* report_out) {
  json& report = *report_out;
  const GeoFrame g = FrameOf(report);
  IngestView ingest = LoadIngest(o);
  // Each mark seen from where its photo's camera was.
  SparseModel model = ReadSurveyModel(o, report);
  std::map<std::string, int> image_of, ingest_of;
  for (size_t i = 0; i < model.images.size(); ++i) image_of[model.images[i].name] = static_cast<int>(i);
  for (size_t i = 0; i < ingest.names.size(); ++i) ingest_of[ingest.names[i]] = static_cast<int>(i);
  const GcpFile checks = ReadGcpFile(o.checkpoints, o.gcp_pixel_origin);
  const Crs file_crs = Crs::FromString(checks.crs);
  std::vector<GroundPointResult> results;
  std::vector<Eigen::Vector3d> residuals;
  json warnings = json::array();  // of this check only: replaced on every check
  for (const GroundPoint& point : checks.points) {
    std::vector<View> views;
    for (const GcpMeasurement& m : point.measurements) {
      const auto it = image_of.find(m.image);
      const auto in = ingest_of.find(m.image);
      if (it == image_of.end() || in == ingest_of.end()) {
        warnings.push_back(checks.path + ":" + std::to_string(m.line) + ": image '" + m.image +
                           "' is not registered in the survey; measurement skipped");
        continue;
      }
      const Image& image = model.images[it->second];
      // Control files measure full-resolution pixels; the model is at the working resolution.
      const Eigen::Vector2d xy = (m.xy_px.array() + 0.5) / ingest.scale[in->second] - 0.5;
      const Camera& camera = model.cameras[image.camera];
      views.push_back({&camera, image.PoseAtRow(xy.y(), camera.height), xy});
    }
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    const GroundPointResult r = EvaluateGroundPoint(point.name, PointRole::kCheck, views,
                                                    file_crs.ToGeodetic(point.xyz), g.frame, g.crs, true, &position);
    if (r.solved) residuals.push_back(r.d_m);
    results.push_back(r);
  }
  GeoreferenceReport partial;
  partial.check = results;
  partial.check_stats = AccuracyStats::FromResiduals(residuals);
  partial.residuals_in_crs_units = !g.crs.IsGeographic();
  const json fresh = GeoreferenceReportJson(partial, model);
  report["check_points"] = fresh["check_points"];
  report["asprs"] = fresh["asprs"];
  report["check_warnings"] = warnings;
  report["check_points"]["file"] = fs::absolute(o.checkpoints).string();
}


// Leave-one-out over the control points of a finished survey: its
// adjustment again, from its reconstruction, with each control point in turn
// withheld. The options and inputs must be the survey's (its recorded
// fingerprint says which differ); the adjusted survey is left as it was.
void LeaveOneOutOnSurvey(const PipelineOptions& o, json* report) {
  if (o.gcp.empty()) throw InvalidArgument("check --leave-one-out: give the survey's control file (--gcp)");
  // The check points take part only inside the bundle; otherwise any (or
  // none) may be given to check with.
  const json& recorded = report->value("georeference_options", json::object());
  json now = GeoreferenceFingerprint(o);
  json was = recorded;
  for (const char* key : {"leave_one_out", "checkpoints"}) {
    if (key == std::string("checkpoints") && o.georef.bundle.check_points_in_bundle) continue;
    now.erase(key);
    was.erase(key);
  }
  const std::string changed = FingerprintChanges(was, now);
  if (!changed.empty()) {
    throw InvalidArgument("check --leave-one-out: the survey was adjusted with other options or inputs (" +
                          changed + "); give the ones it ran with (report.json provenance)");
  }
  IngestView ingest = LoadIngest(o);
  SparseModel model = ReadColmapText(o.workspace / "reconstruction");
  SurveyAdjustmentInputs inputs = GeoreferenceInputs(o, ingest);
  if (!o.georef.bundle.check_points_in_bundle) inputs.checkpoints.clear();
  GeoreferenceOptions go = GeoreferenceStageOptions(o, ingest);
  go.leave_one_out = true;
  go.posterior_precision = false;  // the survey's own figures stay as they are
  const GeoreferenceReport georef = AdjustSurvey(&model, inputs, go);
  const json fresh = GeoreferenceReportJson(georef, model);
  (*report)["leave_one_out"] = fresh.at("leave_one_out");
  (*report)["georeference_options"]["leave_one_out"] = true;
  if (report->contains("provenance") && (*report)["provenance"].contains("options")) {
    (*report)["provenance"]["options"]["georeference"]["leave_one_out"] = true;
  }
}

}  // namespace

void CheckSurvey(const PipelineOptions& o) {
  if (o.checkpoints.empty() && !o.georef.leave_one_out) {
    throw InvalidArgument("check: give --checkpoints, --leave-one-out on, or both");
  }
  json report = ReadJson(o.workspace / "report.json", "georeference");
  if (o.georef.leave_one_out) LeaveOneOutOnSurvey(o, &report);
  if (!o.checkpoints.empty()) CheckPointsOnSurvey(o, &report);
  // What checked it, beside what adjusted it (provenance's own fields).
  json checked = ProcessProvenance(o.software_version, o.command_line);
  checked["options"] = {{"checkpoints", ContentHash(o.checkpoints)}, {"leave_one_out", o.georef.leave_one_out}};
  report["provenance"]["check"] = checked;
  WriteTextFileAtomically(o.workspace / "report.json", report.dump(2) + "\n");
  PipelineOptions again = o;
  again.force = true;
  RunReportStage(again);
}

}  // namespace aerotri
