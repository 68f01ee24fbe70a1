// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/georeferencing.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "libphoto/base/error.h"
#include "libphoto/sfm/triangulation.h"

namespace aerotri {
namespace {

struct SurveyedPoint {
  const GroundPoint* source = nullptr;
  Geodetic geodetic;
  PointRole role = PointRole::kControl;
  int point_index = -1;  // in the model, once added
};

std::vector<View> ViewsOf(const SparseModel& model, int point_index) {
  std::vector<View> views;
  for (const Observation& obs : model.observations) {
    if (obs.point != point_index) continue;
    const Image& image = model.images[obs.image];
    if (!image.registered) continue;
    views.push_back({&model.cameras[image.camera], image.pose, obs.xy});
  }
  return views;
}

void ApplySimilarity(const Similarity& s, SparseModel* model) {
  for (Image& image : model->images) {
    image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
  }
  for (Point& point : model->points) point.position = s.Apply(point.position);
}

}  // namespace

GroundPointResult EvaluateGroundPoint(const std::string& name, PointRole role,
                                      const std::vector<View>& views, const Geodetic& surveyed,
                                      const LocalFrame& frame, const Crs& crs, bool triangulate,
                                      Eigen::Vector3d* position_enu) {
  GroundPointResult r;
  r.name = name;
  r.role = role;
  r.num_images = static_cast<int>(views.size());
  if (triangulate) {
    const auto t = TriangulatePoint(views);
    if (!t) {
      r.why_not = views.size() < 2 ? "measured in fewer than 2 images of the model"
                                   : "rays too parallel or behind a camera";
      return r;
    }
    *position_enu = t->position;
  } else if (views.empty()) {
    r.why_not = "not measured in any image of the model";
    return r;
  }
  r.solved = true;
  double sum = 0.0;
  for (const View& v : views) {
    sum += (v.camera->ImageFromCamera(v.pose.CamFromWorld(*position_enu)) - v.xy).squaredNorm();
  }
  r.reprojection_rms_px = views.empty() ? 0.0 : std::sqrt(sum / views.size());
  r.surveyed_crs = crs.FromGeodetic(surveyed);
  r.adjusted_crs = crs.FromGeodetic(frame.GeodeticFromEnu(*position_enu));
  r.d_m = crs.IsGeographic() ? Eigen::Vector3d(*position_enu - frame.EnuFromGeodetic(surveyed))
                             : Eigen::Vector3d(r.adjusted_crs - r.surveyed_crs);
  return r;
}

GeoreferenceReport GeoreferenceAndAdjust(SparseModel* model,
                                         const std::map<std::string, GpsFix>& gps,
                                         const GcpFile* control, const GcpFile* checks,
                                         const GeoreferenceOptions& options) {
  AEROTRI_CHECK(model != nullptr);
  model->Validate();
  GeoreferenceReport report;
  ReportProgress(options.progress, 0.0, "reading control");

  // 1. Surveyed points in WGS84.
  std::vector<SurveyedPoint> surveyed;
  std::optional<Crs> control_crs;
  for (const GcpFile* file : {control, checks}) {
    if (!file) continue;
    const Crs crs = Crs::FromString(file->crs);
    if (file == control) control_crs = crs;
    for (const GroundPoint& point : file->points) {
      SurveyedPoint s;
      s.source = &point;
      s.geodetic = crs.ToGeodetic(point.xyz);
      s.role = file == control ? PointRole::kControl : PointRole::kCheck;
      surveyed.push_back(s);
    }
  }

  std::unordered_map<std::string, int> image_by_name;
  for (size_t i = 0; i < model->images.size(); ++i) {
    image_by_name[model->images[i].name] = static_cast<int>(i);
  }

  // ENU origin: mean GPS of the model's images, else mean control point.
  {
    double lat = 0, lon = 0, h = 0;
    int n = 0;
    for (const auto& [name, fix] : gps) {
      const auto it = image_by_name.find(name);
      if (it == image_by_name.end() || !model->images[it->second].registered) continue;
      lat += fix.position.lat_deg;
      lon += fix.position.lon_deg;
      h += fix.position.h_m;
      ++n;
    }
    if (n == 0) {
      for (const SurveyedPoint& s : surveyed) {
        if (s.role != PointRole::kControl) continue;
        lat += s.geodetic.lat_deg;
        lon += s.geodetic.lon_deg;
        h += s.geodetic.h_m;
        ++n;
      }
    }
    if (n == 0) {
      throw InvalidArgument("nothing to georeference with: no GPS position for any image of "
                            "the model and no control points (give --gcp, or images with "
                            "EXIF GPS, or --gps-csv)");
    }
    report.enu_origin = {lat / n, lon / n, h / n};
  }
  const LocalFrame frame(report.enu_origin);

  // Output CRS.
  std::optional<Crs> out_crs;
  if (!options.output_crs.empty()) {
    out_crs = Crs::FromString(options.output_crs);
    report.crs_source = "--crs";
  } else if (control_crs) {
    out_crs = control_crs;
    report.crs_source = "control file";
  } else {
    out_crs = Crs::UtmFor(report.enu_origin);
    report.crs_source = "UTM zone of the survey centre";
  }
  report.crs = out_crs->definition();
  report.crs_name = out_crs->Name();
  report.residuals_in_crs_units = !out_crs->IsGeographic();

  // 2. Priors on the cameras.
  int num_gps = 0;
  for (Image& image : model->images) image.gps_prior.reset();
  for (const auto& [name, fix] : gps) {
    const auto it = image_by_name.find(name);
    if (it == image_by_name.end()) continue;
    Image& image = model->images[it->second];
    PositionPrior prior;
    prior.position = frame.EnuFromGeodetic(fix.position);
    prior.sigma_h_m = fix.sigma_h_m;
    prior.sigma_v_m = fix.sigma_v_m;
    image.gps_prior = prior;
    ++num_gps;
  }

  // Control and check points with their observations.
  for (SurveyedPoint& s : surveyed) {
    Point point;
    point.id = static_cast<int>(model->points.size()) + 1000000;
    point.name = s.source->name;
    point.role = s.role;
    point.color = s.role == PointRole::kControl ? std::array<std::uint8_t, 3>{255, 0, 0}
                                                : std::array<std::uint8_t, 3>{0, 0, 255};
    PositionPrior prior;
    prior.position = frame.EnuFromGeodetic(s.geodetic);
    prior.sigma_h_m = s.source->sigma_h_m.value_or(options.gcp_sigma_h_m);
    prior.sigma_v_m = s.source->sigma_v_m.value_or(options.gcp_sigma_v_m);
    point.prior = prior;
    s.point_index = static_cast<int>(model->points.size());
    model->points.push_back(point);
    for (const GcpMeasurement& m : s.source->measurements) {
      const auto it = image_by_name.find(m.image);
      if (it == image_by_name.end()) {
        report.warnings.push_back(
            (s.role == PointRole::kControl ? control->path : checks->path) + ":" +
            std::to_string(m.line) + ": image '" + m.image + "' is not in the model; measurement skipped");
        continue;
      }
      Observation obs;
      obs.image = it->second;
      obs.point = s.point_index;
      obs.xy = m.xy_px;
      model->observations.push_back(obs);
    }
  }

  // 3. Robust similarity from the model frame onto the priors.
  ReportProgress(options.progress, 0.1, "initial similarity fit");
  std::vector<Eigen::Vector3d> from, to;
  double max_sigma = 0.0;
  for (const Image& image : model->images) {
    if (!image.registered || !image.gps_prior) continue;
    from.push_back(image.pose.centre_in_world);
    to.push_back(image.gps_prior->position);
    max_sigma = std::max({max_sigma, image.gps_prior->sigma_h_m, image.gps_prior->sigma_v_m});
  }
  std::vector<char> triangulated(model->points.size(), 0);
  for (const SurveyedPoint& s : surveyed) {
    if (s.role != PointRole::kControl) continue;
    const auto t = TriangulatePoint(ViewsOf(*model, s.point_index));
    if (!t) continue;
    triangulated[s.point_index] = 1;
    model->points[s.point_index].position = t->position;
    from.push_back(t->position);
    to.push_back(model->points[s.point_index].prior->position);
    const PositionPrior& p = *model->points[s.point_index].prior;
    max_sigma = std::max({max_sigma, p.sigma_h_m, p.sigma_v_m});
  }
  report.helmert_correspondences = static_cast<int>(from.size());
  const double threshold =
      options.helmert_inlier_m > 0.0 ? options.helmert_inlier_m : std::max(0.5, 5.0 * max_sigma);
  const auto fit = FitSimilarityRobust(from, to, threshold, 1);
  if (!fit) {
    throw InvalidArgument(
        "cannot georeference: need GPS on 3 or more non-collinear images, or 3 or more control "
        "points measured in 2 or more images each (have " +
        std::to_string(num_gps) + " GPS positions and " +
        std::to_string(from.size() - std::min<size_t>(from.size(), num_gps)) +
        " triangulated control points)");
  }
  report.helmert_inliers = fit->num_inliers;
  report.helmert_rms_m = fit->rms_m;
  if (fit->num_inliers < static_cast<int>(from.size())) {
    report.warnings.push_back(std::to_string(from.size() - fit->num_inliers) + " of " +
                              std::to_string(from.size()) +
                              " priors disagree with the model by more than " +
                              std::to_string(threshold) + " m in the initial fit");
  }
  ApplySimilarity(fit->transform, model);
  for (const SurveyedPoint& s : surveyed) {
    Point& point = model->points[s.point_index];
    if (s.role == PointRole::kControl && !triangulated[s.point_index]) {
      point.position = point.prior->position;  // seen once: start at its survey
    }
  }

  // 4. Bundle adjustment with priors.
  ReportProgress(options.progress, 0.2, "bundle adjustment with GPS and control priors");
  report.bundle = AdjustBundle(model, options.bundle);

  // 5. Check points from the adjusted cameras alone; residuals in the output CRS.
  ReportProgress(options.progress, 0.9, "check points");
  std::vector<Eigen::Vector3d> control_d, check_d;
  for (const SurveyedPoint& s : surveyed) {
    Point& point = model->points[s.point_index];
    const GroundPointResult r =
        EvaluateGroundPoint(s.source->name, s.role, ViewsOf(*model, s.point_index), s.geodetic, frame,
                            *out_crs, /*triangulate=*/s.role == PointRole::kCheck, &point.position);
    if (r.solved) (s.role == PointRole::kControl ? control_d : check_d).push_back(r.d_m);
    (s.role == PointRole::kControl ? report.control : report.check).push_back(r);
  }
  report.control_stats = AccuracyStats::FromResiduals(control_d);
  report.check_stats = AccuracyStats::FromResiduals(check_d);

  for (const Image& image : model->images) {
    if (!image.registered) continue;
    CameraResult c;
    c.name = image.name;
    if (image.gps_prior) {
      c.has_prior = true;
      c.d_enu_m = image.pose.centre_in_world - image.gps_prior->position;
      c.sigma_h_m = image.gps_prior->sigma_h_m;
      c.sigma_v_m = image.gps_prior->sigma_v_m;
    }
    report.cameras.push_back(c);
  }
  ReportProgress(options.progress, 1.0, "georeferenced");
  return report;
}

}  // namespace aerotri
