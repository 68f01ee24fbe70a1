// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/pipeline/survey_adjustment.h"

#include <cstdio>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "georef/crs.h"
#include "georef/local_frame.h"
#include "libphoto/adjust/camera_file.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/export/contours.h"
#include "libphoto/report/report_json.h"

namespace aerotri {
namespace fs = std::filesystem;

namespace {

// A gimbal holds its pitch to about a degree, and a photo's own jitter of one
// or two averages out of the block's mean axis.
constexpr double kGimbalPitchWarningDeg = 3.0;
constexpr double kGimbalPitchErrorDeg = 10.0;

double FullFromModel(const SurveyAdjustmentInputs& inputs, const std::string& image) {
  const auto it = inputs.full_from_model.find(image);
  return it == inputs.full_from_model.end() ? 1.0 : it->second;
}

// A control or check file, its pixels brought to the model's.
std::optional<GcpFile> ReadMarks(const fs::path& path, const SurveyAdjustmentInputs& inputs) {
  if (path.empty()) return std::nullopt;
  GcpFile file = ReadGcpFile(path, inputs.gcp_pixel_origin);
  CheckGcpFileCrs(file);  // before any adjustment, naming file and line
  for (GroundPoint& p : file.points) {
    for (GcpMeasurement& m : p.measurements) {
      const double scale = FullFromModel(inputs, m.image);
      if (scale == 1.0) continue;
      m.xy_px = (m.xy_px.array() + 0.5) / scale - 0.5;
      if (m.sigma_px) *m.sigma_px /= scale;
    }
  }
  return file;
}

}  // namespace

GeoreferenceReport AdjustSurvey(SparseModel* model, const SurveyAdjustmentInputs& inputs,
                                GeoreferenceOptions options) {
  const std::optional<GcpFile> control = ReadMarks(inputs.gcp, inputs);
  const std::optional<GcpFile> checks = ReadMarks(inputs.checkpoints, inputs);
  if (control && checks) CheckChecksIndependent(*control, *checks, options.gcp_sigma_h_m, options.gcp_sigma_v_m);
  if (!inputs.camera_file.empty()) {
    // The certificate is in full-resolution pixels; each camera group's
    // images share a scale.
    std::vector<double> full_from_model(model->cameras.size(), 1.0);
    for (const Image& image : model->images) full_from_model[image.camera] = FullFromModel(inputs, image.name);
    ApplyCameraFile(ReadCameraFile(inputs.camera_file), model, &options.bundle, full_from_model);
  }
  if (options.gimbal.empty()) options.gimbal = inputs.gimbal;  // an oblique block's vertical
  GeoreferenceReport report = GeoreferenceAndAdjust(model, inputs.gps, control ? &*control : nullptr,
                                                    checks ? &*checks : nullptr, options);
  if (!inputs.gimbal.empty() && !(report.output_crs && report.output_crs->IsLocal())) {
    report.gimbal = CompareWithGimbal(*model, inputs.gimbal);
    const GimbalAgreement& g = report.gimbal;
    if (g.images > 0 && g.block_tilt_deg > kGimbalPitchWarningDeg) {
      char message[480];
      std::snprintf(message, sizeof message,
                    "the adjusted block looks %.1f deg away from where its gimbals point (mean optical axes of %d "
                    "photos; per photo median %.1f deg, %.1f deg at %s): the block is tilted (GPS heights "
                    "drifting or wrong, or control too weak to level it); see report.json adjustment.attitude",
                    g.block_tilt_deg, g.images, g.pitch_median_deg, g.pitch_max_deg, g.pitch_worst_image.c_str());
      report.findings.push_back(g.block_tilt_deg > kGimbalPitchErrorDeg
                                    ? Finding::Error("GIMBAL_ATTITUDE_DISAGREES", message)
                                    : Finding::Warning("GIMBAL_ATTITUDE_DISAGREES", message));
    }
  }
  for (auto w = inputs.input_warnings.rbegin(); w != inputs.input_warnings.rend(); ++w) {
    report.findings.insert(report.findings.begin(), Finding::Warning("INPUT", *w));
  }
  return report;
}

void WriteCameraProducts(const GeoreferenceReport& report, const SparseModel& model, const fs::path& folder) {
  const LocalFrame frame(report.enu_origin);
  const Crs& crs = *report.output_crs;
  std::ostringstream csv;
  // The z column's name says what it is (GDAL / QGIS read x, y by name).
  const std::string z_name = crs.IsGeocentric()       ? "z_geocentric_m"
                             : crs.IsLocal()          ? "z"
                             : crs.HasVerticalDatum() ? "z_vertical_datum_m"
                                                      : "z_ellipsoidal_m";
  csv << std::setprecision(12) << "name,x,y," << z_name << ",lat_deg,lon_deg,h_ellipsoidal_m,gps_de_m,gps_dn_m,gps_du_m\n";
  for (const Image& image : model.images) {
    const Geodetic g = frame.GeodeticFromEnu(image.pose.centre_in_world);
    const Eigen::Vector3d xyz = crs.FromGeodetic(g);
    csv << image.name << "," << xyz.x() << "," << xyz.y() << "," << xyz.z() << "," << g.lat_deg << "," << g.lon_deg
        << "," << g.h_m;
    const auto result = std::find_if(report.cameras.begin(), report.cameras.end(),
                                     [&](const CameraResult& c) { return c.name == image.name; });
    if (result != report.cameras.end() && result->has_prior) {
      const Eigen::Vector3d& d = result->d_enu_m;  // after the estimated GPS offset, if any
      csv << "," << d.x() << "," << d.y() << "," << d.z();
    } else {
      csv << ",,,";
    }
    csv << "\n";
  }
  WriteTextFileAtomically(folder / "cameras.csv", csv.str());
  WriteTextFileAtomically(folder / "exterior_orientation.csv", ExteriorOrientationCsv(report));
  WriteCamerasGpkg(report, folder / "cameras.gpkg");
  WriteTiePointsCsv(report, model, folder / "tie_points.csv");
}

void WriteTiePointsCsv(const GeoreferenceReport& report, const SparseModel& model, const fs::path& path) {
  const LocalFrame frame(report.enu_origin);
  const Crs& crs = *report.output_crs;
  // Sigmas onto the CRS's axes through one Jacobian at the block's centre:
  // the grid's rotation from ENU (meridian convergence) and its scale barely
  // change across a survey.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int n = 0;
  for (const Point& p : model.points) {
    if (p.role != PointRole::kTie) continue;
    centre += p.position;
    ++n;
  }
  if (n > 0) centre /= n;
  const Eigen::Matrix3d j = CrsFromEnuJacobian(frame, crs, centre);
  std::vector<const Eigen::Matrix3d*> cov(model.points.size(), nullptr);
  for (const PointPrecision& p : report.bundle.precision.points) {
    if (p.point >= 0 && p.point < static_cast<int>(cov.size())) cov[p.point] = &p.cov;
  }
  const std::vector<int> views = model.ObservationsPerPoint();
  std::ostringstream csv;
  csv << "# adjusted tie points, aerotri\n"
      << "# crs: " << report.crs << " (" << report.crs_name << ")\n"
      << "# sigma_*: posterior standard deviations (m) on " << report.axes
      << "; empty when not computed\n"
      << "id,name,x,y,z,images,sigma_x_m,sigma_y_m,sigma_z_m\n"
      << std::setprecision(12);
  for (size_t k = 0; k < model.points.size(); ++k) {
    const Point& p = model.points[k];
    if (p.role != PointRole::kTie || views[k] < 2) continue;
    const Eigen::Vector3d xyz = crs.FromGeodetic(frame.GeodeticFromEnu(p.position));
    csv << p.id << "," << p.name << "," << xyz.x() << "," << xyz.y() << "," << xyz.z() << "," << views[k];
    if (cov[k]) {
      const Eigen::Vector3d sigma = (j * *cov[k] * j.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
      csv << std::setprecision(4) << "," << sigma.x() << "," << sigma.y() << "," << sigma.z() << std::setprecision(12);
    } else {
      csv << ",,,";
    }
    csv << "\n";
  }
  WriteTextFileAtomically(path, csv.str());
}

void WriteCamerasGpkg(const GeoreferenceReport& r, const fs::path& path) {
  Crs crs = Crs::FromString(r.crs);
  if (crs.IsLocal() && r.local_origin) crs = crs.LocalAt(*r.local_origin);
  const std::string z = crs.IsGeocentric()       ? "geocentric Z"
                        : crs.IsLocal()          ? "the local frame's z"
                        : crs.HasVerticalDatum() ? "heights of the vertical datum of " + crs.Name()
                                                 : "WGS84 ellipsoidal heights";
  std::vector<GpkgPoint> points;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const CameraResult& c : r.cameras) {
    GpkgPoint p;
    p.xyz = c.position_crs;
    p.text = {c.name};
    p.numbers = {c.opk_deg.x(), c.opk_deg.y(), c.opk_deg.z()};
    for (int k = 0; k < 3; ++k) p.numbers.push_back(c.has_precision ? c.sigma_position_m[k] : nan);
    for (int k = 0; k < 3; ++k) p.numbers.push_back(c.has_precision ? c.sigma_opk_deg[k] : nan);
    for (int k = 0; k < 3; ++k) p.numbers.push_back(c.has_prior ? c.d_enu_m[k] : nan);
    points.push_back(p);
  }
  WritePointsGpkg(path, "cameras", crs.Wkt(),
                  "aerotri camera centres in " + crs.Name() + "; z: " + z +
                      "; omega, phi, kappa as in exterior_orientation.csv; gps_d*: adjusted minus GPS (east, "
                      "north, up, m)",
                  {"name"},
                  {"omega_deg", "phi_deg", "kappa_deg", "sigma_x_m", "sigma_y_m", "sigma_z_m", "sigma_omega_deg",
                   "sigma_phi_deg", "sigma_kappa_deg", "gps_de_m", "gps_dn_m", "gps_du_m"},
                  points);
}

}  // namespace aerotri
