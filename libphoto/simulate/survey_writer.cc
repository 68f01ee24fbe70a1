// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/simulate/survey_writer.h"

#include <gdal_priv.h>

#include <cmath>
#include <ctime>
#include <iomanip>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "georef/crs.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"
#include "libphoto/export/raster.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/io/image_writer.h"
#include "libphoto/model/gimbal_attitude.h"
#include "libphoto/simulate/render.h"

namespace aerotri {
namespace fs = std::filesystem;

namespace {

// Height of the terrain in the CRS at CRS position (x, y).
double TerrainInCrs(const Crs& crs, const LocalFrame& frame, double x, double y, double relief) {
  double z = frame.origin().h_m;
  for (int it = 0; it < 3; ++it) {
    const Eigen::Vector3d enu = frame.EnuFromGeodetic(crs.ToGeodetic({x, y, z}));
    const Eigen::Vector3d ground(enu.x(), enu.y(), TerrainHeight(enu.x(), enu.y(), relief));
    z = crs.FromGeodetic(frame.GeodeticFromEnu(ground)).z();
  }
  return z;
}

// Buildings, clear of every target by 3 m and of each other by 4 m.
std::vector<BoxBuilding> PlaceBuildings(const SimulationOptions& options, const SparseModel& truth) {
  std::vector<BoxBuilding> buildings;
  std::mt19937 place(options.survey.seed + 977);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int attempt = 0; attempt < 2000 && static_cast<int>(buildings.size()) < options.num_buildings; ++attempt) {
    BoxBuilding b;
    b.half_size = {3.0 + 4.0 * u(place), 3.0 + 3.0 * u(place)};
    b.height_m = 4.0 + 4.0 * u(place);
    b.centre = {(u(place) - 0.5) * (options.survey.area_width_m - 2 * b.half_size.x() - 4.0),
                (u(place) - 0.5) * (options.survey.area_height_m - 2 * b.half_size.y() - 4.0)};
    bool clear = true;
    for (const Point& p : truth.points) {
      if (p.role == PointRole::kTie) continue;
      clear = clear && (std::abs(p.position.x() - b.centre.x()) > b.half_size.x() + 3.0 ||
                        std::abs(p.position.y() - b.centre.y()) > b.half_size.y() + 3.0);
    }
    for (const BoxBuilding& o : buildings) {
      clear = clear && (std::abs(o.centre.x() - b.centre.x()) > o.half_size.x() + b.half_size.x() + 4.0 ||
                        std::abs(o.centre.y() - b.centre.y()) > o.half_size.y() + b.half_size.y() + 4.0);
    }
    if (clear) buildings.push_back(b);
  }
  if (static_cast<int>(buildings.size()) < options.num_buildings) {
    throw InvalidArgument("simulate: room for only " + std::to_string(buildings.size()) + " of " +
                          std::to_string(options.num_buildings) + " buildings clear of the targets");
  }
  return buildings;
}

// The control and check points as a surveyor brings them from the field
// (coordinates only: `aerotri mark` finds the targets), and the targets'
// exact centres in every photo (truth/marks.txt, control and checks).
void WriteCoordinateFilesAndTrueMarks(const SyntheticGeoref& scene, const SparseModel& truth, const fs::path& dir) {
  GcpFile marks;
  for (const auto& [file, name] : {std::pair{&scene.control, "gcp_coordinates.txt"},
                                   std::pair{&scene.checks, "check_coordinates.txt"}}) {
    if (file->points.empty()) continue;
    WriteFileAtomically(dir / name, [&](std::ostream& out) {
      out << file->crs << "\n" << std::setprecision(12);
      for (const GroundPoint& p : file->points) {
        out << p.name << " " << p.xyz.x() << " " << p.xyz.y() << " " << p.xyz.z();
        if (p.sigma_h_m) out << " sigma_h=" << *p.sigma_h_m;
        if (p.sigma_v_m) out << " sigma_v=" << *p.sigma_v_m;
        out << "\n";
      }
    });
    marks.crs = file->crs;
    for (GroundPoint p : file->points) {
      for (GcpMeasurement& m : p.measurements) {
        for (const Observation& obs : truth.observations) {
          if (truth.points[obs.point].name == p.name && truth.images[obs.image].name == m.image) m.xy_px = obs.xy;
        }
      }
      marks.points.push_back(p);
    }
  }
  if (!marks.points.empty()) WriteGcpFile(marks, dir / "truth" / "marks.txt");
}

// GCP files: measurements are the true target centres plus clicking noise.
void MarkTargets(const SimulationOptions& options, const SparseModel& truth, SyntheticGeoref* scene) {
  std::mt19937 rng(options.survey.seed + 101);
  std::normal_distribution<double> g(0.0, 1.0);
  for (GcpFile* file : {&scene->control, &scene->checks}) {
    for (GroundPoint& point : file->points) {
      for (GcpMeasurement& m : point.measurements) {
        for (const Observation& obs : truth.observations) {
          const Point& p = truth.points[obs.point];
          if (p.name == point.name && truth.images[obs.image].name == m.image) {
            m.xy_px = obs.xy + options.click_noise_px * Eigen::Vector2d(g(rng), g(rng));
          }
        }
      }
    }
  }
}

// GPS as EGM96 altitudes (what EXIF calls "above sea level") in gps.csv,
// and the same fixes as OpenDroneMap's geo.txt; returns the altitudes.
std::map<std::string, double> WriteGpsFiles(const SimulationOptions& options, const SyntheticGeoref& scene,
                                            const Crs& crs, const fs::path& dir) {
  std::ostringstream csv;
  csv << "name,lat,lon,alt_egm96_m\n" << std::setprecision(12);
  std::map<std::string, double> egm_altitude;
  for (const auto& [name, fix] : scene.gps) {
    const double alt = fix.position.h_m - Egm96Undulation(fix.position.lat_deg, fix.position.lon_deg);
    egm_altitude[name] = alt;
    csv << name << "," << fix.position.lat_deg << "," << fix.position.lon_deg << ","
        << std::setprecision(8) << alt << std::setprecision(12) << "\n";
  }
  WriteTextFileAtomically(dir / "gps.csv", csv.str());
  // The same fixes as OpenDroneMap's geo.txt, in the output CRS: x y and the
  // EGM96 altitude (a 2D CRS), no angles, the fixes' sigmas as accuracies.
  {
    std::ostringstream geo;
    geo << options.georef.crs << "\n" << std::fixed << std::setprecision(4);
    for (const auto& [name, fix] : scene.gps) {
      const Eigen::Vector3d xy = crs.FromGeodetic(fix.position);
      const double z = crs.HasVerticalDatum() ? xy.z() : egm_altitude[name];
      geo << name << " " << xy.x() << " " << xy.y() << " " << z << " 0 0 0 " << fix.sigma_h_m << " "
          << fix.sigma_v_m << "\n";
    }
    WriteTextFileAtomically(dir / "geo.txt", geo.str());
  }

  return egm_altitude;
}

// The tie-point model in an arbitrary frame (what another tool exports),
// the same tie points as image measurements and the camera as a calibration
// certificate: a classic aerial triangulation's inputs (aerotri adjust).
void WriteAdjustInputs(const SimulationOptions& options, const SyntheticGeoref& scene, const fs::path& dir) {
  // The tie-point model in an arbitrary frame: what another tool exports.
  {
    SparseModel model = scene.tie_model;
    const double s = 0.05;
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 0.3, 0.9).normalized()));
    const Eigen::Vector3d t(3.0, -2.0, 1.0);
    for (Image& image : model.images) {
      image.pose.centre_in_world = s * (q * image.pose.centre_in_world) + t;
      image.pose.cam_from_world = (image.pose.cam_from_world * q.conjugate()).normalized();
    }
    for (Point& point : model.points) point.position = s * (q * point.position) + t;
    WriteColmapText(model, dir / "model");
  }
  // The same tie points as image measurements (but for marks off the
  // image), and the camera as a
  // calibration certificate: a classic aerial triangulation's inputs
  // (aerotri adjust --measurements, camera_file.h).
  {
    const SparseModel& model = scene.tie_model;
    std::ostringstream ties;
    ties << "# image point im_x im_y (px, centre of the top-left pixel at 0, 0)\n" << std::setprecision(10);
    for (const Observation& obs : model.observations) {
      // A mark pushed off the image by its noise is one nobody could measure.
      const Camera& c = model.cameras[model.images[obs.image].camera];
      if (obs.xy.x() < -0.5 || obs.xy.y() < -0.5 || obs.xy.x() > c.width - 0.5 || obs.xy.y() > c.height - 0.5) {
        continue;
      }
      ties << model.images[obs.image].name << " t" << model.points[obs.point].id << " " << obs.xy.x() << " "
           << obs.xy.y() << "\n";
    }
    WriteTextFileAtomically(dir / "measurements.txt", ties.str());
    const CameraModelInfo& info = GetCameraModelInfo(CameraModelId::kBrown);
    std::ostringstream cam;
    cam << "# calibration certificate of the simulated camera (pixels)\nunits px\nwidth " << options.survey.width
        << "\nheight " << options.survey.height << "\n" << std::setprecision(12);
    for (size_t k = 0; k < info.param_names.size() && k < options.survey.brown_params.size(); ++k) {
      const std::string& name = info.param_names[k];
      cam << name << " " << options.survey.brown_params[k] << "\n";
    }
    WriteTextFileAtomically(dir / "camera.txt", cam.str());
  }
}

// Truth DEM in the output CRS over the area (with a margin), and the DSM
// with the buildings.
void WriteTruthDems(const SimulationOptions& options, const std::vector<BoxBuilding>& buildings,
                    const LocalFrame& frame, const Crs& crs, const fs::path& dir) {
  const double margin = 10.0;
  const double w = options.survey.area_width_m + 2 * margin;
  const double h = options.survey.area_height_m + 2 * margin;
  const Eigen::Vector3d sw = crs.FromGeodetic(frame.GeodeticFromEnu({-w / 2, -h / 2, 0}));
  const Eigen::Vector3d ne = crs.FromGeodetic(frame.GeodeticFromEnu({w / 2, h / 2, 0}));
  const double res = options.dem_resolution_m;
  Raster dem;
  dem.width = static_cast<int>(std::ceil((ne.x() - sw.x()) / res));
  dem.height = static_cast<int>(std::ceil((ne.y() - sw.y()) / res));
  dem.geotransform = {std::floor(sw.x()), res, 0.0, std::ceil(ne.y()), 0.0, -res};
  dem.wkt = crs.Wkt();
  dem.values.resize(static_cast<size_t>(dem.width) * dem.height);
  for (int y = 0; y < dem.height; ++y) {
    for (int x = 0; x < dem.width; ++x) {
      dem.at(x, y) = static_cast<float>(
          TerrainInCrs(crs, frame, dem.X(x), dem.Y(y), options.survey.relief_m));
    }
  }
  fs::create_directories(dir / "truth");
  WriteRaster(dem, dir / "truth" / "dem.tif");
  if (!buildings.empty()) {
    Raster dsm = dem;
    for (int y = 0; y < dsm.height; ++y) {
      for (int x = 0; x < dsm.width; ++x) {
        const Eigen::Vector3d enu = frame.EnuFromGeodetic(crs.ToGeodetic({dsm.X(x), dsm.Y(y), dem.at(x, y)}));
        for (const BoxBuilding& b : buildings) {
          if (!b.Contains(enu.x(), enu.y())) continue;
          const Eigen::Vector3d roof(enu.x(), enu.y(), b.RoofHeight(options.survey.relief_m));
          dsm.at(x, y) = static_cast<float>(crs.FromGeodetic(frame.GeodeticFromEnu(roof)).z());
        }
      }
    }
    WriteRaster(dsm, dir / "truth" / "dsm.tif");
  }
}

// Truth orthoimage: the ground's albedo (targets included) over the same
// area, on a grid aligned to multiples of its cell, 3 x 3 supersampled.
void WriteTruthOrtho(const SimulationOptions& options, const SyntheticGeoref& scene,
                     const std::vector<BoxBuilding>& buildings, const LocalFrame& frame, const Crs& crs,
                     const fs::path& dir) {
  const SparseModel& truth = scene.survey.truth;
  std::vector<GroundTarget> targets;
  for (const Point& p : truth.points) {
    if (p.role != PointRole::kTie) targets.push_back({p.position.head<2>(), 1.0, options.target_pattern});
  }
  const double margin = 10.0;
  const double w = options.survey.area_width_m + 2 * margin;
  const double h = options.survey.area_height_m + 2 * margin;
  const Eigen::Vector3d sw = crs.FromGeodetic(frame.GeodeticFromEnu({-w / 2, -h / 2, 0}));
  const Eigen::Vector3d ne = crs.FromGeodetic(frame.GeodeticFromEnu({w / 2, h / 2, 0}));
  const double res = options.truth_ortho_resolution_m > 0
                         ? options.truth_ortho_resolution_m
                         : std::max(0.001, std::round(scene.survey.gsd_m * 1000.0) / 1000.0);
  const double x0 = std::floor(sw.x() / res) * res, y0 = std::ceil(ne.y() / res) * res;
  const int width = static_cast<int>(std::ceil((ne.x() - x0) / res));
  const int height = static_cast<int>(std::ceil((y0 - sw.y()) / res));
  cv::Mat rgb(height, width, CV_8UC3);
  const unsigned threads = ThreadCount(0);
  ParallelFor(threads, threads, [&](size_t t) {
    const Crs local = Crs::FromString(options.georef.crs);
    for (int y = static_cast<int>(t); y < height; y += static_cast<int>(threads)) {
      for (int x = 0; x < width; ++x) {
        const Eigen::Vector3d enu = frame.EnuFromGeodetic(
            local.ToGeodetic({x0 + (x + 0.5) * res, y0 - (y + 0.5) * res, frame.origin().h_m}));
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int sy = -1; sy <= 1; ++sy) {
          for (int sx = -1; sx <= 1; ++sx) {
            sum += SceneAlbedoFromAbove(enu.x() + sx * res / 3.0, enu.y() + sy * res / 3.0, targets, buildings,
                                        options.ground_cover);
          }
        }
        for (int k = 0; k < 3; ++k) rgb.at<cv::Vec3b>(y, x)[k] = cv::saturate_cast<std::uint8_t>(255.0 * sum[k] / 9.0);
      }
    }
  });
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> ds(mem->Create("", width, height, 3, GDT_Byte, nullptr));
  double gt[6] = {x0, res, 0.0, y0, 0.0, -res};
  ds->SetGeoTransform(gt);
  ds->SetProjection(crs.Wkt().c_str());
  int bands[3] = {1, 2, 3};
  if (ds->RasterIO(GF_Write, 0, 0, width, height, rgb.data, width, height, GDT_Byte, 3, bands, 3,
                   static_cast<GSpacing>(rgb.step), 1, nullptr) != CE_None) {
    throw IoError((dir / "truth" / "ortho.tif").string(), "cannot fill the in-memory raster");
  }
  const fs::path tmp = TemporaryPathFor(dir / "truth" / "ortho.tif");
  const char* opts[] = {"TILED=YES", "COMPRESS=DEFLATE", "PHOTOMETRIC=RGB", nullptr};
  GDALDataset* out = GetGDALDriverManager()->GetDriverByName("GTiff")->CreateCopy(
      tmp.string().c_str(), ds.get(), FALSE, const_cast<char**>(opts), nullptr, nullptr);
  if (!out) throw IoError(tmp.string(), std::string("cannot write: ") + CPLGetLastErrorMsg());
  GDALClose(out);
  fs::rename(tmp, dir / "truth" / "ortho.tif");
}

// truth/truth.json: what the survey was made with.
void WriteTruthJson(const SimulationOptions& options, const SyntheticGeoref& scene,
                    const std::vector<BoxBuilding>& buildings, const fs::path& dir) {
  const SparseModel& truth = scene.survey.truth;
  nlohmann::json info;
  info["origin"] = {{"lat_deg", options.georef.origin.lat_deg},
                    {"lon_deg", options.georef.origin.lon_deg},
                    {"h_m", options.georef.origin.h_m}};
  info["crs"] = options.georef.crs;
  info["gsd_m"] = scene.survey.gsd_m;
  info["images"] = truth.images.size();
  info["camera"] = {{"model", "BROWN"}, {"width", options.survey.width},
                    {"height", options.survey.height}, {"params", options.survey.brown_params},
                    {"param_names", GetCameraModelInfo(CameraModelId::kBrown).param_names},
                    {"pixel_origin", "centre of the top-left pixel is (0, 0)"}};
  info["gps_sigma_h_m"] = options.georef.gps_sigma_h_m;
  info["gps_sigma_v_m"] = options.georef.gps_sigma_v_m;
  info["gcp_noise_m"] = options.georef.gcp_noise_m;
  info["seconds_per_photo"] = options.georef.seconds_per_photo;
  const Eigen::Vector3d& drift = options.georef.gps_drift_m;
  info["gps_drift_m"] = {drift.x(), drift.y(), drift.z()};
  if (truth.images.size() > 1) {
    const double duration = options.georef.seconds_per_photo * static_cast<double>(truth.images.size() - 1);
    info["gps_drift_m_per_s"] = {drift.x() / duration, drift.y() / duration, drift.z() / duration};
  }
  info["click_noise_px"] = options.click_noise_px;
  info["target_pattern"] = options.target_pattern == TargetPattern::kCross      ? "cross"
                           : options.target_pattern == TargetPattern::kBullseye ? "circle"
                                                                                : "checker";
  info["tie_point_noise_px"] = options.survey.pixel_noise_px;
  info["relief_m"] = options.survey.relief_m;
  info["seed"] = options.survey.seed;
  info["ground"] = options.ground_cover == GroundCover::kCropRows ? "crop-rows" : "mixed";
  info["buildings"] = nlohmann::json::array();
  for (const BoxBuilding& b : buildings) {
    info["buildings"].push_back({{"centre_enu_m", {b.centre.x(), b.centre.y()}},
                                 {"half_size_m", {b.half_size.x(), b.half_size.y()}},
                                 {"height_m", b.height_m},
                                 {"roof_up_m", b.RoofHeight(options.survey.relief_m)}});
  }
  WriteTextFileAtomically(dir / "truth" / "truth.json", info.dump(2) + "\n");

}

// The EXIF of a rendered photo: its GPS (EGM96 altitude), focal length,
// capture time and sensor.
std::map<std::string, std::string> ExifOf(const SimulationOptions& options, const Camera& camera,
                                          const GpsFix& fix, double alt) {
  const double focal_mm = camera.params[0] * options.sensor_width_mm / camera.width;
  std::map<std::string, std::string> exif;
  exif["EXIF_Make"] = "aerotri";
  exif["EXIF_Model"] = "simulated Brown camera";
  exif["EXIF_GPSLatitude"] = ExifDms(fix.position.lat_deg);
  exif["EXIF_GPSLatitudeRef"] = fix.position.lat_deg >= 0 ? "N" : "S";
  exif["EXIF_GPSLongitude"] = ExifDms(fix.position.lon_deg);
  exif["EXIF_GPSLongitudeRef"] = fix.position.lon_deg >= 0 ? "E" : "W";
  exif["EXIF_GPSAltitude"] = "(" + std::to_string(std::abs(alt)) + ")";
  exif["EXIF_GPSAltitudeRef"] = alt >= 0 ? "0x00" : "0x01";
  exif["EXIF_FocalLength"] = "(" + std::to_string(focal_mm) + ")";
  if (std::isfinite(fix.time_s)) {
    const auto t = static_cast<std::time_t>(std::floor(fix.time_s));
    std::tm utc{};
    gmtime_r(&t, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y:%m:%d %H:%M:%S", &utc);
    exif["EXIF_DateTimeOriginal"] = stamp;
    exif["EXIF_SubSecTimeOriginal"] =
        std::to_string(static_cast<int>(std::lround(100.0 * (fix.time_s - std::floor(fix.time_s)))) % 100);
  }
  exif["EXIF_FocalPlaneXResolution"] = "(" + std::to_string(camera.width / (options.sensor_width_mm / 10.0)) + ")";
  exif["EXIF_FocalPlaneYResolution"] = exif["EXIF_FocalPlaneXResolution"];
  exif["EXIF_FocalPlaneResolutionUnit"] = "3";  // centimetres
  exif["EXIF_PixelXDimension"] = std::to_string(camera.width);
  exif["EXIF_PixelYDimension"] = std::to_string(camera.height);
  exif["EXIF_FocalLengthIn35mmFilm"] =
      std::to_string(static_cast<int>(std::lround(focal_mm * 36.0 / options.sensor_width_mm)));
  return exif;
}

// The photos, rendered with their EXIF (and DJI gimbal XMP); photos already
// there are kept (an interrupted simulation resumes).
void RenderPhotos(const SimulationOptions& options, const SyntheticGeoref& scene,
                  const std::vector<BoxBuilding>& buildings, const std::map<std::string, double>& egm_altitude,
                  const fs::path& dir) {
  const SparseModel& truth = scene.survey.truth;
  fs::create_directories(dir / "images");
  RenderOptions render;
  render.relief_m = options.survey.relief_m;
  render.seed = options.survey.seed;
  render.buildings = buildings;
  render.cover = options.ground_cover;
  for (const Point& p : truth.points) {
    if (p.role != PointRole::kTie) render.targets.push_back({p.position.head<2>(), 1.0, options.target_pattern});
  }
  const Camera& camera = truth.cameras[0];
  for (size_t i = 0; i < truth.images.size(); ++i) {
    const Image& image = truth.images[i];
    const fs::path path = dir / "images" / image.name;
    if (fs::exists(path)) continue;  // resume an interrupted simulation
    ReportProgress(options.progress, static_cast<double>(i) / truth.images.size(),
                   "rendering " + image.name);
    render.seed = options.survey.seed * 1000 + static_cast<std::uint32_t>(i);
    render.rolling_shutter = image.rolling_shutter;
    const cv::Mat pixels = RenderImage(camera, image.pose, render);
    const std::map<std::string, std::string> exif =
        ExifOf(options, camera, scene.gps.at(image.name), egm_altitude.at(image.name));
    std::string xmp;
    if (options.write_gimbal_xmp) {
      // Per image, so that a resumed simulation writes the same angles.
      std::mt19937 gimbal_rng(options.survey.seed * 7919u + static_cast<std::uint32_t>(i));
      std::normal_distribution<double> noise(0.0, options.gimbal_noise_deg);
      const GimbalAttitude a = AttitudeOf(image.pose);
      const double pitch = a.pitch_deg + noise(gimbal_rng), yaw = a.yaw_deg + noise(gimbal_rng);
      xmp = DjiGimbalXmp(pitch, std::remainder(yaw, 360.0), GimbalRollOf(image.pose) + noise(gimbal_rng));
    } else if (image.rolling_shutter) {
      xmp = RollingShutterXmp(image.rolling_shutter->readout_time_s, image.rolling_shutter->velocity);
    }
    WriteJpegWithExif(path, pixels, exif, options.jpeg_quality, xmp);
  }
  ReportProgress(options.progress, 1.0, "simulated " + std::to_string(truth.images.size()) + " images");
}

}  // namespace

void WriteSyntheticSurvey(const SimulationOptions& options, const fs::path& dir) {
  if (options.write_gimbal_xmp && options.survey.readout_time_s > 0.0) {
    throw InvalidArgument("simulate: DJI gimbal XMP and a rolling shutter's Pix4D camera tags cannot both be written "
                          "(one XMP packet per photo)");
  }
  fs::create_directories(dir);
  ReportProgress(options.progress, 0.0, "simulating the survey");
  SyntheticGeoref scene = MakeSyntheticGeoref(options.survey, options.georef);
  const SparseModel& truth = scene.survey.truth;
  const LocalFrame frame(options.georef.origin);
  const Crs crs = Crs::FromString(options.georef.crs);
  const std::vector<BoxBuilding> buildings = PlaceBuildings(options, truth);
  MarkTargets(options, truth, &scene);
  // A file without points would be refused as input: none is written.
  if (!scene.control.points.empty()) WriteGcpFile(scene.control, dir / "gcp_list.txt");
  if (!scene.checks.points.empty()) WriteGcpFile(scene.checks, dir / "checkpoints.txt");
  fs::create_directories(dir / "truth");
  WriteCoordinateFilesAndTrueMarks(scene, truth, dir);
  const std::map<std::string, double> egm_altitude = WriteGpsFiles(options, scene, crs, dir);
  WriteAdjustInputs(options, scene, dir);
  WriteColmapText(truth, dir / "truth" / "model");
  WriteTruthDems(options, buildings, frame, crs, dir);
  if (options.render_images) WriteTruthOrtho(options, scene, buildings, frame, crs, dir);
  WriteTruthJson(options, scene, buildings, dir);
  if (options.render_images) RenderPhotos(options, scene, buildings, egm_altitude, dir);
}

}  // namespace aerotri
