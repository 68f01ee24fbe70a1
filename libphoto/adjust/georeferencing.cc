// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/georeferencing.h"

#include <algorithm>
#include <functional>
#include <limits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include <Eigen/SVD>

#include "libphoto/base/error.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {

void GeoreferenceOptions::Check() const {
  CheckOption(gcp_sigma_h_m > 0.0 && std::isfinite(gcp_sigma_h_m), "--gcp-sigma-h", gcp_sigma_h_m,
              "a positive number of metres");
  CheckOption(gcp_sigma_v_m > 0.0 && std::isfinite(gcp_sigma_v_m), "--gcp-sigma-v", gcp_sigma_v_m,
              "a positive number of metres");
  CheckOption(helmert_inlier_m >= 0.0 && std::isfinite(helmert_inlier_m), "georeference helmert_inlier_m",
              helmert_inlier_m, "0 (automatic) or a positive number of metres");
  CheckOption(weak_focal_rel > 0.0 && weak_focal_rel < 1.0, "georeference weak_focal_rel", weak_focal_rel,
              "a fraction in (0, 1)");
  CheckOption(gates.max_rms_px > 0.0, "gates max_rms_px", gates.max_rms_px, "a positive number of pixels");
  CheckOption(gates.mark_family_alpha > 0.0 && gates.mark_family_alpha < 0.5, "gates mark_family_alpha",
              gates.mark_family_alpha, "a probability in (0, 0.5)");
  CheckOption(gates.max_gps_inconsistent_fraction > 0.0 && gates.max_gps_inconsistent_fraction <= 1.0,
              "gates max_gps_inconsistent_fraction", gates.max_gps_inconsistent_fraction, "a fraction in (0, 1]");
  std::string error;
  if (!bundle.Validate(&error)) throw InvalidArgument(error);
  if (!output_crs.empty()) Crs::FromString(output_crs);  // CrsError names it
}

BundleOptions SurveyBundleOptions() {
  BundleOptions o;
  o.loss = LossType::kHuber;
  o.loss_scale_px = 1.0;
  o.outlier_threshold_px = 4.0;
  o.min_images_to_refine_intrinsics = 3;
  // Huber finds the blunders, least squares estimates (BundleOptions): the
  // robust cost's re-weighting crawled along the block's weak directions
  // (36 iterations on the sample survey, 35 at 999 photos against 20 at
  // 513), while least squares on the screened observations converges in a
  // handful and is the estimator sigma0 and the covariances assume.
  o.least_squares_after_screening = true;
  // Closer to the optimum than Ceres' 1e-6, which along a strong omega-Y
  // correlation stops short by millimetres.
  o.function_tolerance = 1e-7;
  o.parameter_tolerance = 1e-8;
  o.gradient_tolerance = 1e-10;
  return o;
}
namespace {

struct SurveyedPoint {
  const GroundPoint* source = nullptr;
  Geodetic geodetic;
  PointRole role = PointRole::kControl;
  int point_index = -1;  // in the model, once added
  std::string excluded;  // why its measurements were left out, when they were
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

constexpr double kAttitudePriorSigmaDeg = 5.0;  // per photo (GpsDriftReport)
constexpr double kGpsOnlyGroundSlopeDeg = 20.0;  // GROUND_TILTED_BY_GPS
constexpr double kNoHeightSigmaM = 1e4;      // the vertical prior of a control point in plan only

std::string FormatDegrees(double deg) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f deg", deg);
  return text;
}

// Per camera group: whether a registered image uses it.
std::vector<char> CamerasInUse(const SparseModel& model) {
  std::vector<char> used(model.cameras.size(), 0);
  for (const Image& image : model.images) {
    if (image.registered) used[image.camera] = 1;
  }
  return used;
}

std::string FormatPercent(double fraction) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f %%", 100.0 * fraction);
  return text;
}

std::string FormatMetres(double m) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f m", m);
  return text;
}

// Where the GNSS antenna of an image is: its centre plus the lever arm
// turned into the world (BundleOptions::gnss_lever_arm_m).
Eigen::Vector3d AntennaOf(const Image& image, const Eigen::Vector3d& lever) {
  return image.pose.centre_in_world + image.pose.cam_from_world.conjugate() * lever;
}

// The rotation part of a conformal Jacobian (polar decomposition).
Eigen::Matrix3d RotationOf(const Eigen::Matrix3d& j) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(j, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) r = -r;
  return r;
}

// ω, φ, κ (radians) of R = Rx(ω) Ry(φ) Rz(κ).
Eigen::Vector3d OmegaPhiKappa(const Eigen::Matrix3d& r) {
  return {std::atan2(-r(1, 2), r(2, 2)), std::asin(std::clamp(r(0, 2), -1.0, 1.0)), std::atan2(-r(0, 1), r(0, 0))};
}

// Grid-from-photo rotation of a pose: photo axes are OpenCV's camera axes
// with y and z turned (x right, y up, z out of the lens).
Eigen::Matrix3d GridFromPhoto(const Eigen::Matrix3d& grid_from_enu, const Eigen::Quaterniond& cam_from_world) {
  return grid_from_enu * cam_from_world.conjugate().toRotationMatrix() * Eigen::Vector3d(1, -1, -1).asDiagonal();
}

// Angles wrapped into (-pi, pi] around a reference (for differences).
double WrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

void ApplySimilarity(const Similarity& s, SparseModel* model) {
  for (Image& image : model->images) {
    image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
  }
  for (Point& point : model->points) point.position = s.Apply(point.position);
}

// The adjustment's quality gates (findings.h): convergence, reprojection
// RMS, GPS and control residuals against their sigmas.
void ApplyQualityGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report) {
  const BundleSummary& b = report->bundle;
  auto fixed = [](double v, int digits) {
    char text[32];
    std::snprintf(text, sizeof text, "%.*f", digits, v);
    return std::string(text);
  };
  // Images whose own RMS is above the limit, worst first.
  std::vector<std::string> bad_images;
  {
    const std::vector<double> errors = ReprojectionErrors(model);
    std::vector<double> sum(model.images.size(), 0.0);
    std::vector<int> count(model.images.size(), 0);
    for (size_t k = 0; k < errors.size(); ++k) {
      const Observation& obs = model.observations[k];
      if (model.points[obs.point].role == PointRole::kCheck || !model.images[obs.image].registered) continue;
      const double e = std::isfinite(errors[k]) ? errors[k] : 1e6;
      sum[obs.image] += e * e;
      ++count[obs.image];
    }
    std::vector<std::pair<double, std::string>> rms;
    for (size_t i = 0; i < model.images.size(); ++i) {
      if (count[i] == 0) continue;
      const double r = std::sqrt(sum[i] / count[i]);
      if (r > gates.max_rms_px) rms.push_back({r, model.images[i].name});
    }
    std::sort(rms.rbegin(), rms.rend());
    for (const auto& [r, name] : rms) bad_images.push_back(name);
  }
  if (!b.converged) {
    report->findings.push_back(Finding::Warning(
        "ADJUSTMENT_NOT_CONVERGED", "the adjustment stopped before converging (" + b.termination + ")"));
  }
  if (b.final_rms_px > gates.max_rms_px) {
    report->findings.push_back(Finding::Error(
        "REPROJECTION_RMS_HIGH",
        "final reprojection RMS " + fixed(b.final_rms_px, 2) + " px is above " + fixed(gates.max_rms_px, 1) +
            " px: the model and its priors do not agree" +
            (bad_images.empty() ? std::string() : "; worst images: " + JoinNames(bad_images)),
        bad_images));
  } else if (b.final_rms_px > 1.0 && b.final_rms_px > gates.max_rms_growth * b.initial_rms_px) {
    report->findings.push_back(Finding::Error(
        "REPROJECTION_RMS_GREW",
        "the adjustment raised the reprojection RMS from " + fixed(b.initial_rms_px, 2) + " to " +
            fixed(b.final_rms_px, 2) + " px: the priors pull the model apart",
        bad_images));
  }
  // GPS residuals (after the estimated offset) against their sigmas.
  std::vector<std::string> gps_bad;
  int with_gps = 0;
  for (const CameraResult& c : report->cameras) {
    if (!c.has_prior || c.prior_rejected) continue;
    ++with_gps;
    const double h = c.d_enu_m.head<2>().norm() / c.sigma_h_m;
    const double v = std::abs(c.d_enu_m.z()) / c.sigma_v_m;
    if (h > gates.gps_sigma_multiple || v > gates.gps_sigma_multiple) gps_bad.push_back(c.name);
  }
  if (!gps_bad.empty()) {
    const std::string text = std::to_string(gps_bad.size()) + " of " + std::to_string(with_gps) +
                             " cameras end farther from their GPS than " + fixed(gates.gps_sigma_multiple, 0) +
                             " sigma: " + JoinNames(gps_bad);
    if (gps_bad.size() > gates.max_gps_inconsistent_fraction * with_gps) {
      report->findings.push_back(Finding::Error(
          "GPS_MOSTLY_INCONSISTENT",
          text + "; the GPS and the model disagree (wrong registration, GPS in another datum or "
                 "height reference, or wrong sigmas)",
          gps_bad));
    } else {
      report->findings.push_back(Finding::Warning("GPS_INCONSISTENT", text, gps_bad));
    }
  }
  // Control residuals against their sigmas.
  std::vector<std::string> control_bad;
  for (const GroundPointResult& r : report->control) {
    if (!r.solved) continue;
    const Point* point = nullptr;
    for (const Point& p : model.points) {
      if (p.role == PointRole::kControl && p.name == r.name) point = &p;
    }
    if (!point || !point->prior) continue;
    const double h = r.d_m.head<2>().norm() / point->prior->sigma_h_m;
    const double v = std::abs(r.d_m.z()) / point->prior->sigma_v_m;
    if (h > gates.control_sigma_multiple || v > gates.control_sigma_multiple) control_bad.push_back(r.name);
  }
  // Check points against what the datum allows: their own survey sigma and
  // the sigma of what holds the datum (control, else GPS), five times, at
  // least QualityGates::min_check_threshold_m. GPS and model can agree on a
  // wrong survey (a layout turned by 180 degrees fits a similarity exactly):
  // only independent points can tell.
  {
    const bool control_datum = report->datum_source.rfind("control", 0) == 0;
    double datum_h = 0.0, datum_v = 0.0;
    std::vector<double> gps_h, gps_v;
    for (const Point& p : model.points) {
      if (control_datum && p.role == PointRole::kControl && p.prior) {
        datum_h = std::max(datum_h, p.prior->sigma_h_m);
        datum_v = std::max(datum_v, p.prior->sigma_v_m);
      }
    }
    if (!control_datum) {
      for (const CameraResult& c : report->cameras) {
        if (!c.has_prior) continue;
        gps_h.push_back(c.sigma_h_m);
        gps_v.push_back(c.sigma_v_m);
      }
      if (!gps_h.empty()) {
        std::nth_element(gps_h.begin(), gps_h.begin() + gps_h.size() / 2, gps_h.end());
        std::nth_element(gps_v.begin(), gps_v.begin() + gps_v.size() / 2, gps_v.end());
        datum_h = gps_h[gps_h.size() / 2];
        datum_v = gps_v[gps_v.size() / 2];
      }
    }
    std::vector<std::string> far;
    int solved = 0;
    for (const GroundPointResult& r : report->check) {
      if (!r.solved) continue;
      ++solved;
      const Point* point = nullptr;
      for (const Point& p : model.points) {
        if (p.role == PointRole::kCheck && p.name == r.name) point = &p;
      }
      const double sh = point && point->prior ? point->prior->sigma_h_m : 0.0;
      const double sv = point && point->prior ? point->prior->sigma_v_m : 0.0;
      const double limit_h = std::max(gates.min_check_threshold_m, gates.check_sigma_multiple * std::hypot(sh, datum_h));
      const double limit_v = std::max(gates.min_check_threshold_m, gates.check_sigma_multiple * std::hypot(sv, datum_v));
      if (r.d_m.head<2>().norm() > limit_h || std::abs(r.d_m.z()) > limit_v) far.push_back(r.name);
    }
    if (!far.empty()) {
      const std::string text =
          std::to_string(far.size()) + " of " + std::to_string(solved) +
          " check points are farther from their survey than the datum allows (" +
          fixed(gates.check_sigma_multiple, 0) + " sigma of the check point and of the " +
          (control_datum ? "control" : "GPS") + "): " + JoinNames(far);
      if (2 * far.size() > static_cast<size_t>(solved)) {
        report->findings.push_back(Finding::Error(
            "CHECK_POINTS_FAR", text + "; the survey is misplaced (GPS in the wrong order or datum, "
                                       "wrong registration) or the check file is wrong",
            far));
      } else {
        report->findings.push_back(Finding::Warning("CHECK_POINTS_FAR", text + " (blunders?)", far));
      }
    }
  }
  // A dome (or bowl) across the block beyond 2 GSD.
  const DomeTest& dome = report->dome;
  if (dome.significant && report->geometry.gsd_m > 0.0 &&
      std::abs(dome.amplitude_m) > gates.max_dome_gsd * report->geometry.gsd_m) {
    report->findings.push_back(Finding::Warning(
        "DOME", "the vertical residuals of the " + dome.source + " form a " +
                    (dome.amplitude_m > 0 ? "bowl" : "dome") + " across the block: edge minus centre " +
                    fixed(dome.amplitude_m, 3) + " ± " + fixed(dome.amplitude_sigma_m, 3) + " m (" +
                    fixed(std::abs(dome.amplitude_m) / report->geometry.gsd_m, 1) +
                    " GSD); radial distortion is likely mis-estimated (a nadir block at one altitude: add "
                    "oblique photos or control across the block)" +
                    (dome.source == "GPS" ? std::string("; measured on GPS altitudes, which a drift over the flight "
                                                        "can shape too: check points would tell")
                                          : std::string())));
  }
  if (!control_bad.empty()) {
    report->findings.push_back(Finding::Warning(
        "CONTROL_RESIDUAL_HIGH",
        std::to_string(control_bad.size()) + " control points end farther from their survey than " +
            fixed(gates.control_sigma_multiple, 0) + " sigma (a blunder, a wrong mark, or sigmas "
            "too small): " + JoinNames(control_bad),
        control_bad));
  }
}

}  // namespace

Eigen::Matrix3d CrsFromEnuJacobian(const LocalFrame& frame, const Crs& crs, const Eigen::Vector3d& enu) {
  if (crs.IsGeographic() || crs.IsGeocentric()) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d j;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k);
    j.col(k) = 0.5 * (crs.FromGeodetic(frame.GeodeticFromEnu(enu + e)) -
                      crs.FromGeodetic(frame.GeodeticFromEnu(enu - e)));
  }
  return j;
}

std::vector<Finding> IntrinsicsCorrelationFindings(const std::vector<IntrinsicsPrecision>& precision,
                                                   double limit) {
  std::vector<Finding> out;
  const auto interior = [](const std::string& name) { return name == "f" || name == "cx" || name == "cy"; };
  for (const IntrinsicsPrecision& p : precision) {
    std::string pairs;
    std::vector<std::string> items;
    for (size_t a = 0; a < p.names.size(); ++a) {
      for (size_t b = a + 1; b < p.names.size(); ++b) {
        if (a >= p.correlation.size() || b >= p.correlation[a].size()) continue;
        const double rho = p.correlation[a][b];
        if (!(std::abs(rho) > limit) || !(interior(p.names[a]) || interior(p.names[b]))) continue;
        char text[96];
        std::snprintf(text, sizeof text, "%s-%s %.3f", p.names[a].c_str(), p.names[b].c_str(), rho);
        pairs += (pairs.empty() ? "" : ", ") + std::string(text);
        items.push_back(p.names[a] + "-" + p.names[b]);
      }
    }
    if (items.empty()) continue;
    char limit_text[32];
    std::snprintf(limit_text, sizeof limit_text, "%.2f", limit);
    out.push_back(Finding::Warning(
        "INTRINSICS_CORRELATED",
        "camera group " + std::to_string(p.camera + 1) + ": intrinsics correlated beyond " + limit_text + " (" +
            pairs + "): the block does not tell them apart (add oblique or cross strips, another flying height, "
            "or hold them at a calibration: --camera-file)",
        items));
  }
  return out;
}

double TwoSidedNormalCriticalValue(double alpha) {
  // P(|z| > c) = erfc(c / sqrt 2), decreasing in c: bisection to 1e-12.
  double lo = 0.0, hi = 40.0;
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double FamilyWiseCriticalValue(int tests, double family_alpha) {
  // 1 - (1 - a)^(1/n) without cancellation for small a.
  const double per_test = -std::expm1(std::log1p(-family_alpha) / std::max(tests, 1));
  return TwoSidedNormalCriticalValue(per_test);
}

int CountMarkTests(const std::vector<MarkResult>& marks) {
  int tests = 0;
  for (const MarkResult& m : marks) tests += (m.redundancy.array() > 1e-6).count();
  return tests;
}

std::vector<Finding> SnoopMarks(std::vector<MarkResult>* marks, double w_critical, double w_critical_family) {
  MarkResult* worst = nullptr;
  int suspects = 0;
  for (MarkResult& m : *marks) {
    const double w = m.w.cwiseAbs().maxCoeff();
    m.suspect = w > w_critical;
    m.rejected = false;
    suspects += m.suspect;
    if (!worst || w > worst->w.cwiseAbs().maxCoeff()) worst = &m;
  }
  if (!worst || !(worst->w.cwiseAbs().maxCoeff() > w_critical_family)) return {};
  worst->rejected = true;
  char more[160] = "";
  if (suspects > 1) {
    std::snprintf(more, sizeof more, "; %d more mark%s above %.2f, likely raised by this one", suspects - 1,
                  suspects > 2 ? "s" : "", w_critical);
  }
  char text[600];
  std::snprintf(text, sizeof text,
                "Baarda's w-test rejects the mark of '%s' on image '%s': w = %.1f (residual %.2f, %.2f px; "
                "critical value %.2f for the largest of the survey's %d mark tests)%s: measure it again and "
                "re-run",
                worst->point.c_str(), worst->image.c_str(),
                std::abs(worst->w.x()) > std::abs(worst->w.y()) ? worst->w.x() : worst->w.y(),
                worst->residual_px.x(), worst->residual_px.y(), w_critical_family, CountMarkTests(*marks), more);
  return {Finding::Warning("MARK_BLUNDER", text, {worst->point, worst->image})};
}

std::string ToString(GpsOffsetPolicy policy) {
  switch (policy) {
    case GpsOffsetPolicy::kNever: return "never";
    case GpsOffsetPolicy::kAuto: return "auto";
    case GpsOffsetPolicy::kAlways: return "always";
    case GpsOffsetPolicy::kPerFlight: return "per-flight";
  }
  return "?";
}

std::optional<GpsOffsetPolicy> ParseGpsOffsetPolicy(const std::string& text) {
  for (GpsOffsetPolicy p :
       {GpsOffsetPolicy::kNever, GpsOffsetPolicy::kAuto, GpsOffsetPolicy::kAlways, GpsOffsetPolicy::kPerFlight}) {
    if (ToString(p) == text) return p;
  }
  return std::nullopt;
}

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
  // Geographic and geocentric axes have no metres east / north / up: their
  // residuals are in local ENU metres.
  r.d_m = crs.IsGeographic() || crs.IsGeocentric()
              ? Eigen::Vector3d(*position_enu - frame.EnuFromGeodetic(surveyed))
              : Eigen::Vector3d(r.adjusted_crs - r.surveyed_crs);
  return r;
}

GeoreferenceReport GeoreferenceAndAdjust(SparseModel* model,
                                         const std::map<std::string, GpsFix>& gps_given,
                                         const GcpFile* control, const GcpFile* checks,
                                         const GeoreferenceOptions& options) {
  AEROTRI_CHECK(model != nullptr);
  // Camera positions in a local frame are placed in the control's below.
  std::map<std::string, GpsFix> gps = gps_given;
  model->Validate();
  GeoreferenceReport report;
  report.initial_cameras = model->cameras;
  ReportProgress(options.progress, 0.0, "reading control");
  // The start of every leave-one-out adjustment.
  std::optional<SparseModel> start;
  if (options.leave_one_out) start = *model;

  // One target labelled as two points: marks of different points within
  // 2 px of each other in one photo (a copy-paste in the control file). Said
  // with both names and the lines; the adjustment cannot tell which is right.
  {
    struct Mark {
      std::string point, file;
      int line;
      Eigen::Vector2d xy;
    };
    std::map<std::string, std::vector<Mark>> by_image;
    for (const GcpFile* f : {control, checks}) {
      if (!f) continue;
      for (const GroundPoint& p : f->points) {
        for (const GcpMeasurement& m : p.measurements) by_image[m.image].push_back({p.name, f->path, m.line, m.xy_px});
      }
    }
    std::vector<std::string> items, lines;
    for (const auto& [image, marks] : by_image) {
      for (size_t a = 0; a < marks.size(); ++a) {
        for (size_t b = a + 1; b < marks.size(); ++b) {
          if (marks[a].point == marks[b].point || (marks[a].xy - marks[b].xy).norm() > 2.0) continue;
          items.push_back(marks[a].point + "/" + marks[b].point + " in " + image);
          lines.push_back(marks[a].file + ":" + std::to_string(marks[a].line) + " and " + marks[b].file + ":" +
                          std::to_string(marks[b].line));
        }
      }
    }
    if (!items.empty()) {
      std::string text;
      for (size_t k = 0; k < items.size() && k < 5; ++k) text += (k ? "; " : "") + items[k] + " (" + lines[k] + ")";
      report.findings.push_back(Finding::Warning(
          "MARK_DUPLICATED",
          std::to_string(items.size()) + " target mark(s) labelled as two different points in one photo, within "
          "2 px of each other: " + text + (items.size() > 5 ? "; ..." : "") +
              "; one label is wrong (the w-test names the mark that fits worse)",
          items));
    }
  }

  // 1. Surveyed points in WGS84 (in a local frame: on its exact stand-in,
  // Crs::IsLocal()).
  std::vector<SurveyedPoint> surveyed;
  std::optional<Crs> control_crs, check_crs, requested_crs;
  if (control) control_crs = Crs::FromString(control->crs);
  if (checks) check_crs = Crs::FromString(checks->crs);
  if (!options.output_crs.empty()) requested_crs = Crs::FromString(options.output_crs);
  const bool local = (control_crs && control_crs->IsLocal()) || (check_crs && check_crs->IsLocal()) ||
                     (requested_crs && requested_crs->IsLocal());
  if (local) {
    const std::pair<const char*, std::optional<Crs>*> all[] = {
        {"the control file's", &control_crs}, {"the check file's", &check_crs}, {"--crs", &requested_crs}};
    std::optional<double> unit;
    for (const auto& [what, crs] : all) {
      if (!*crs) continue;
      if (!(*crs)->IsLocal()) {
        throw InvalidArgument(std::string(what) + " CRS '" + (*crs)->definition() +
                              "' is geodetic while another is a local engineering frame: a local frame has no "
                              "transformation to it; give the control, check points and --crs in one local frame");
      }
      if (unit && std::abs(*unit - (*crs)->LocalUnitMetres()) > 1e-12) {
        throw InvalidArgument("the control and check files' local frames have different length units");
      }
      unit = (*crs)->LocalUnitMetres();
    }
    for (const auto& [name, fix] : gps) {
      if (!fix.local_xyz) {
        throw InvalidArgument("GPS positions are geodetic (EXIF, or --gps-csv latitude / longitude) and the control "
                              "is in a local engineering frame, which has no geodetic link: adjust without GPS (no "
                              "--images / --gps-csv), give the camera positions in the same local frame (a geo.txt "
                              "whose first line is LOCAL), or give the control in a geodetic CRS");
      }
      if (unit && std::abs(*unit - fix.local_unit_m) > 1e-12) {
        throw InvalidArgument("the camera positions' local frame (image " + name +
                              ") has another length unit than the control's");
      }
    }
    // Coordinates about the control's centre keep the stand-in small.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int n = 0;
    for (const GcpFile* file : {control, checks}) {
      if (!file || (file == checks && n > 0)) continue;
      for (const GroundPoint& point : file->points) {
        if (point.horizontal_only) continue;
        mean += point.xyz;
        ++n;
      }
    }
    if (n > 0) mean /= n;
    report.local_origin = mean;
    for (const auto& [what, crs] : all) {
      if (*crs) *crs = (*crs)->LocalAt(mean);
    }
    // Camera positions on the same stand-in as the control.
    const Crs& frame_crs = control_crs ? *control_crs : check_crs ? *check_crs : *requested_crs;
    for (auto& [name, fix] : gps) fix.position = frame_crs.ToGeodetic(*fix.local_xyz);
  } else {
    for (const auto& [name, fix] : gps) {
      if (fix.local_xyz) {
        throw InvalidArgument("the camera position of " + name +
                              " is in a local engineering frame and the control is not: a local frame has no "
                              "transformation to a geodetic CRS; give both in one frame");
      }
    }
  }
  for (const GcpFile* file : {control, checks}) {
    if (!file) continue;
    const Crs& crs = file == control ? *control_crs : *check_crs;
    // A point without a surveyed height is converted at the median height of
    // the file's others (the horizontal position barely depends on it).
    std::vector<double> heights;
    for (const GroundPoint& point : file->points) {
      if (!point.horizontal_only) heights.push_back(point.xyz.z());
    }
    double fill_z = 0.0;
    if (!heights.empty()) {
      std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
      fill_z = heights[heights.size() / 2];
    }
    for (const GroundPoint& point : file->points) {
      SurveyedPoint s;
      s.source = &point;
      Eigen::Vector3d xyz = point.xyz;
      if (point.horizontal_only) xyz.z() = fill_z;
      s.geodetic = crs.ToGeodetic(xyz);
      s.role = file == control ? PointRole::kControl : PointRole::kCheck;
      if (point.horizontal_only && s.role == PointRole::kCheck) {
        s.excluded = "no surveyed height ('nan'): a check point needs all three coordinates";
      }
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
    report.enu_origin = options.enu_origin ? *options.enu_origin : Geodetic{lat / n, lon / n, h / n};
    // A local frame adjusts on its stand-in's own tangent plane: exactly the
    // file's Cartesian coordinates.
    if (local) report.enu_origin = Crs::LocalGeodeticOrigin();
  }
  const LocalFrame frame(report.enu_origin);

  // Output CRS.
  std::optional<Crs> out_crs;
  if (requested_crs) {
    out_crs = requested_crs;
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
  report.residuals_in_crs_units = !out_crs->IsGeographic() && !out_crs->IsGeocentric();
  report.axes = out_crs->IsLocal()        ? "x, y, z of the local engineering frame (its unit)"
                : out_crs->IsGeographic() ? "local east, north, up (metres; the CRS is geographic)"
                : out_crs->IsGeocentric() ? "local east, north, up (metres): the CRS is geocentric, whose X, Y, Z "
                                            "have no horizontal or vertical meaning"
                                          : "easting, northing, height of the CRS (its unit)";
  report.output_crs = out_crs;

  // 2. Priors on the cameras.
  int num_gps = 0;
  std::map<int, PositionPrior> rejected_gps;  // by image index, restored after the adjustment
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

  // Surveyed points that cannot belong to the survey: horizontally farther
  // from every GPS camera position than the photos can see (three flying
  // heights) plus five GPS sigmas and 50 m. A control file in another zone,
  // hemisphere or CRS, or with its axes swapped or negated, ends here; its
  // points must not pull the block.
  {
    std::vector<Eigen::Vector3d> cameras;
    std::vector<double> sigmas, heights;
    for (const Image& image : model->images) {
      if (!image.registered || !image.gps_prior) continue;
      cameras.push_back(image.gps_prior->position);
      sigmas.push_back(image.gps_prior->sigma_h_m);
      heights.push_back(image.gps_prior->position.z());
    }
    if (cameras.size() >= 3 && !local) {
      auto median = [](std::vector<double> v) {
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
      };
      std::vector<double> ground;
      for (const SurveyedPoint& s : surveyed) {
        if (!s.source->horizontal_only) ground.push_back(frame.EnuFromGeodetic(s.geodetic).z());
      }
      const double flying = ground.empty() ? 0.0 : std::abs(median(heights) - median(ground));
      const double limit = 3.0 * flying + 5.0 * median(sigmas) + 50.0;
      std::vector<std::string> far;
      for (SurveyedPoint& s : surveyed) {
        const Eigen::Vector3d p = frame.EnuFromGeodetic(s.geodetic);
        double nearest = std::numeric_limits<double>::infinity();
        for (const Eigen::Vector3d& c : cameras) nearest = std::min(nearest, (p - c).head<2>().norm());
        if (nearest <= limit) continue;
        char text[160];
        std::snprintf(text, sizeof text, "%.0f m from the nearest GPS camera position (the photos see %.0f m)",
                      nearest, limit);
        s.excluded = std::string("outside the survey: ") + text;
        far.push_back(s.source->name);
      }
      if (!far.empty()) {
        report.findings.push_back(Finding::Error(
            "CONTROL_OUTSIDE_SURVEY",
            std::to_string(far.size()) + " surveyed points lie outside the photographed area (farther from every GPS "
            "camera position than three flying heights and five GPS sigmas): " + JoinNames(far) +
            "; left out. A wrong CRS line, zone or hemisphere, swapped or negated axes, or another site's file?",
            far));
      }
    }
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
    if (s.source->sigma_xyz_m) {
      // Sigmas on the CRS's axes, turned onto the adjustment's: Σ = J⁻¹ D J⁻ᵀ.
      const Crs& crs = s.role == PointRole::kControl ? *control_crs : *check_crs;
      const Eigen::Matrix3d j_inv = CrsFromEnuJacobian(frame, crs, prior.position).inverse();
      const Eigen::Vector3d& sigma = *s.source->sigma_xyz_m;
      prior.covariance = j_inv * sigma.cwiseAbs2().asDiagonal() * j_inv.transpose();
      prior.sigma_h_m = std::max(sigma.x(), sigma.y());
      prior.sigma_v_m = sigma.z();
    }
    if (s.source->horizontal_only) {
      // In plan only: its height is the adjustment's (a prior of 10 km holds nothing).
      prior.sigma_v_m = kNoHeightSigmaM;
      prior.covariance.reset();
    }
    point.prior = prior;
    s.point_index = static_cast<int>(model->points.size());
    model->points.push_back(point);
    for (const GcpMeasurement& m : s.source->measurements) {
      if (!s.excluded.empty()) break;
      const auto it = image_by_name.find(m.image);
      if (it == image_by_name.end()) {
        report.findings.push_back(Finding::Warning(
            "INPUT", (s.role == PointRole::kControl ? control->path : checks->path) + ":" +
                         std::to_string(m.line) + ": image '" + m.image +
                         "' is not in the model; measurement skipped",
            {s.source->name}));
        continue;
      }
      const Camera& camera = model->cameras[model->images[it->second].camera];
      if (!(m.xy_px.x() >= -0.5 && m.xy_px.y() >= -0.5 && m.xy_px.x() <= camera.width - 0.5 &&
            m.xy_px.y() <= camera.height - 0.5)) {
        char text[200];
        std::snprintf(text, sizeof text, ": mark (%.1f, %.1f) px is outside image '%s' (%d x %d px); measurement "
                      "skipped", m.xy_px.x(), m.xy_px.y(), m.image.c_str(), camera.width, camera.height);
        report.findings.push_back(Finding::Warning(
            "INPUT", (s.role == PointRole::kControl ? control->path : checks->path) + ":" + std::to_string(m.line) + text,
            {s.source->name}));
        continue;
      }
      Observation obs;
      obs.image = it->second;
      obs.point = s.point_index;
      obs.xy = m.xy_px;
      obs.sigma_px = m.sigma_px.value_or(0.0);
      model->observations.push_back(obs);
    }
  }

  // 3. Robust similarity from the model frame onto the datum.
  ReportProgress(options.progress, 0.1, "initial similarity fit");
  std::vector<int> gps_images;  // registered images with GPS
  std::vector<Eigen::Vector3d> gps_from, gps_to;
  double gps_max_sigma = 0.0;
  for (size_t i = 0; i < model->images.size(); ++i) {
    const Image& image = model->images[i];
    if (!image.registered || !image.gps_prior) continue;
    gps_images.push_back(static_cast<int>(i));
    gps_from.push_back(image.pose.centre_in_world);
    gps_to.push_back(image.gps_prior->position);
    gps_max_sigma = std::max({gps_max_sigma, image.gps_prior->sigma_h_m, image.gps_prior->sigma_v_m});
  }
  std::vector<int> control_points;  // triangulated control, by model point index
  std::vector<Eigen::Vector3d> control_from, control_to;
  double control_max_sigma = 0.0;
  std::vector<char> triangulated(model->points.size(), 0);
  for (const SurveyedPoint& s : surveyed) {
    if (s.role != PointRole::kControl) continue;
    const auto t = TriangulatePoint(ViewsOf(*model, s.point_index));
    if (!t) continue;
    triangulated[s.point_index] = 1;
    model->points[s.point_index].position = t->position;
    if (s.source->horizontal_only) continue;  // no height: no part in a 3D similarity
    control_points.push_back(s.point_index);
    control_from.push_back(t->position);
    const PositionPrior& p = *model->points[s.point_index].prior;
    control_to.push_back(p.position);
    control_max_sigma = std::max({control_max_sigma, p.sigma_h_m, p.sigma_v_m});
  }
  auto threshold_for = [&](double max_sigma) {
    return options.helmert_inlier_m > 0.0 ? options.helmert_inlier_m : std::max(0.5, 5.0 * max_sigma);
  };

  // The block's viewing geometry in its own frame, and the GPS images'
  // capture times and flights (the GNSS drift model, gnss_drift.h).
  report.viewing = MeasureViewingGeometry(*model);
  std::vector<double> gps_times;
  for (int i : gps_images) gps_times.push_back(gps.at(model->images[i].name).time_s);
  const int num_timed = static_cast<int>(std::count_if(gps_times.begin(), gps_times.end(),
                                                       [](double t) { return std::isfinite(t); }));
  const FlightTimes flights = SplitFlights(gps_times);
  double median_sigma_h = 0.0, median_sigma_v = 0.0;
  {
    std::vector<double> h, v;
    for (int i : gps_images) {
      h.push_back(model->images[i].gps_prior->sigma_h_m);
      v.push_back(model->images[i].gps_prior->sigma_v_m);
    }
    if (!h.empty()) {
      std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      median_sigma_h = h[h.size() / 2];
      median_sigma_v = v[v.size() / 2];
    }
  }
  GpsDriftReport& drift = report.gps_drift;
  std::vector<Eigen::Vector3d> initial_drift_rates;
  auto record_trend = [&](const DriftTrend& trend) {
    drift.flights.clear();
    initial_drift_rates.clear();
    for (const DriftTrend::Flight& f : trend.flights) {
      GpsDriftReport::Flight out;
      out.images = f.images;
      out.duration_s = f.duration_s;
      out.trend_m_per_s = f.rate_m_per_s;
      out.trend_sigma = f.rate_sigma;
      drift.flights.push_back(out);
      Eigen::Vector3d start = Eigen::Vector3d::Zero();
      for (int a = 0; a < 3; ++a) start[a] = trend.significant_axes[a] ? f.rate_m_per_s[a] : 0.0;
      initial_drift_rates.push_back(start);
    }
  };
  // Each GPS prior learns its flight and time (only when the drift is estimated).
  auto attach_flights = [&]() {
    for (size_t k = 0; k < gps_images.size(); ++k) {
      PositionPrior& p = *model->images[gps_images[k]].gps_prior;
      p.flight = flights.flight[k];
      p.time_from_flight_s = flights.dt_s[k];
    }
  };

  // With three or more non-collinear control points the datum is theirs.
  std::optional<SimilarityFit> fit;
  if (control_from.size() >= 3) {
    double threshold = threshold_for(control_max_sigma);
    fit = FitSimilarityRobust(control_from, control_to, threshold, 1);
    // Control much noisier than its sigmas leaves few points within 5 sigma
    // of any fit (a handheld-GPS kite survey stated at 2 cm kept 3 of 8). The
    // data's own scatter then sets the threshold: 4 robust standard
    // deviations per axis (the 99.9 % point of a 3D error is 4.03 sigma)
    // about the current fit, refitted until it settles; a blunder far off
    // the others' scatter still falls out.
    const int n_control = static_cast<int>(control_from.size());
    for (int round = 0; round < 4 && fit && options.helmert_inlier_m <= 0.0 && n_control >= 4 &&
                        fit->num_inliers < n_control;
         ++round) {
      std::vector<double> r;
      for (int k = 0; k < n_control; ++k) r.push_back((fit->transform.Apply(control_from[k]) - control_to[k]).norm());
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      const double sigma_axis = r[r.size() / 2] / 1.538;  // median of a 3D Gaussian error's length
      const double adaptive = 4.03 * sigma_axis;
      if (!(adaptive > threshold * 1.01)) break;
      threshold = adaptive;
      auto wider = FitSimilarityRobust(control_from, control_to, threshold, 1);
      if (!wider || wider->num_inliers <= fit->num_inliers) break;
      fit = wider;
    }
    if (fit && fit->num_inliers >= 4) {
      // The scatter per axis over the inliers (7 parameters fitted), first
      // about the model as it came; that model is not yet adjusted (its
      // intrinsics may be rough), so a scatter beyond 3 times the stated
      // sigmas is confirmed on a free network: the block adjusted with the
      // control so loose that it only places it, then fitted again.
      std::vector<int> in;
      double stated2 = 0.0;
      for (int k = 0; k < n_control; ++k) {
        if (!fit->inliers[k]) continue;
        in.push_back(k);
        const PositionPrior& p = *model->points[control_points[k]].prior;
        stated2 += (2.0 * p.sigma_h_m * p.sigma_h_m + p.sigma_v_m * p.sigma_v_m) / 3.0;
      }
      const int n = static_cast<int>(in.size());
      auto scatter = [&](const std::vector<Eigen::Vector3d>& from) {
        std::vector<Eigen::Vector3d> a, b;
        for (int k : in) a.push_back(from[k]), b.push_back(control_to[k]);
        const auto s = FitSimilarity(a, b);
        if (!s) return std::numeric_limits<double>::infinity();
        double sum2 = 0.0;
        for (size_t k = 0; k < a.size(); ++k) sum2 += (s->Apply(a[k]) - b[k]).squaredNorm();
        return std::sqrt(sum2 / std::max(1, 3 * n - 7));
      };
      auto& cp = report.control_precision;
      cp.measured = true;
      cp.points = n;
      cp.stated_m = std::sqrt(stated2 / n);
      cp.estimated_m = scatter(control_from);
      if (cp.estimated_m > 3.0 * cp.stated_m) {
        ReportProgress(options.progress, 0.12, "control precision: free-network check");
        SparseModel free = *model;
        ApplySimilarity(fit->transform, &free);
        for (int k : control_points) {
          PositionPrior& p = *free.points[k].prior;
          p.sigma_h_m = p.sigma_v_m = std::max(1000.0 * cp.stated_m, 100.0);
          p.covariance.reset();
          free.points[k].position = p.position;
        }
        BundleOptions loose = options.bundle;
        if (options.auto_refine) loose.refine_intrinsics = IntrinsicsRefinement::kAll;
        loose.function_tolerance = std::max(loose.function_tolerance, 1e-6);
        loose.compute_precision = false;
        loose.check_points_in_bundle = false;  // they are not placed yet; they judge nothing here
        AdjustBundle(&free, loose);
        std::vector<Eigen::Vector3d> adjusted(control_from.size());
        for (size_t k = 0; k < control_points.size(); ++k) {
          const auto t = TriangulatePoint(ViewsOf(free, control_points[k]));
          adjusted[k] = t ? t->position : free.points[control_points[k]].position;
        }
        cp.estimated_m = scatter(adjusted);
      }
      if (cp.estimated_m > 3.0 * cp.stated_m && !options.keep_stated_control_sigmas) {
        // Weigh the control by what it shows: every control prior scaled alike.
        const double f = cp.estimated_m / cp.stated_m;
        for (int k : control_points) {
          PositionPrior& p = *model->points[k].prior;
          p.sigma_h_m *= f;
          p.sigma_v_m *= f;
          if (p.covariance) *p.covariance *= f * f;
        }
        cp.adopted = true;
      }
      if (cp.estimated_m > 3.0 * cp.stated_m) {
        report.findings.push_back(Finding::Warning(
            "CONTROL_WEAKER_THAN_STATED",
            "the control points scatter about the model by " + FormatMetres(cp.estimated_m) +
                " per axis (" + std::to_string(n) + " points), " +
                std::to_string(static_cast<int>(std::lround(cp.estimated_m / cp.stated_m))) + " times the " + FormatMetres(cp.stated_m) + " their sigmas state" +
                (cp.adopted ? std::string("; the adjustment weighs them by the estimate (state it with "
                                          "--gcp-sigma-h / --gcp-sigma-v, or keep the file's with "
                                          "--keep-control-sigmas)")
                            : std::string("; the file's sigmas were kept as asked: the block is bent to fit "
                                          "the control"))));
      }
    }
    if (fit && fit->num_inliers >= 3) {
      report.datum_source = "control points (" + std::to_string(fit->num_inliers) + " of " +
                            std::to_string(control_from.size()) + " in the initial similarity)";
      report.helmert_correspondences = static_cast<int>(control_from.size());
      if (fit->num_inliers < static_cast<int>(control_from.size())) {
        std::vector<std::string> names;
        for (size_t k = 0; k < control_points.size(); ++k) {
          if (!fit->inliers[k]) names.push_back(model->points[control_points[k]].name);
        }
        report.findings.push_back(Finding::Warning(
            "CONTROL_INCONSISTENT",
            std::to_string(names.size()) + " of " + std::to_string(control_from.size()) +
                " control points disagree with the others by more than " + FormatMetres(threshold) +
                " in the initial fit: " + JoinNames(names),
            names));
      }
    } else {
      fit.reset();
    }
  }

  const bool control_datum = fit.has_value();
  if (!fit) {
    // Too little control: GPS and control together.
    std::vector<Eigen::Vector3d> from = gps_from, to = gps_to;
    from.insert(from.end(), control_from.begin(), control_from.end());
    to.insert(to.end(), control_to.begin(), control_to.end());
    report.helmert_correspondences = static_cast<int>(from.size());
    const double threshold = threshold_for(std::max(gps_max_sigma, control_max_sigma));
    fit = FitSimilarityRobust(from, to, threshold, 1);
    if (!fit) {
      throw InvalidArgument(
          "cannot georeference: need GPS on 3 or more non-collinear images, or 3 or more control "
          "points measured in 2 or more images each (have " +
          std::to_string(num_gps) + " GPS positions and " + std::to_string(control_from.size()) +
          " triangulated control points)");
    }
    report.datum_source = control_from.empty() ? "GPS" : "GPS and control points";
    // GPS heights that drift in time would tilt a block (strips are flown
    // one after another): the block levelled by its own vertical — a nadir
    // block's mean optical axis, else the gimbal pitches' — shows the drift
    // as a trend in time of the GPS height residuals. A trend, or a GPS fit
    // that tilts the block by more than 10°, puts the attitude prior in
    // charge of the tilt, with the drift estimated.
    Eigen::Vector3d down_in_model = report.viewing.mean_axis;
    std::string vertical_note = report.viewing.reason;
    if (report.viewing.nadir) {
      drift.vertical_source = "nadir";
    } else if (!options.gimbal.empty() && !local) {
      report.gimbal_vertical = MeasureGimbalVertical(*model, options.gimbal);
      vertical_note = report.viewing.reason + "; " + report.gimbal_vertical.reason;
      if (report.gimbal_vertical.usable) {
        drift.vertical_source = "gimbal";
        down_in_model = report.gimbal_vertical.down_in_model;
      }
    }
    const char* block_kind = drift.vertical_source == "gimbal" ? "oblique" : "nadir";
    const char* levelled_by = drift.vertical_source == "gimbal" ? "its gimbal pitches" : "its mean optical axis";
    const Eigen::Vector3d down(0.0, 0.0, -1.0);
    const Eigen::Vector3d fit_axis = fit->transform.rotation * down_in_model;
    drift.gps_fit_tilt_deg = std::atan2(fit_axis.cross(down).norm(), fit_axis.dot(down)) * 180.0 / M_PI;
    if (drift.vertical_source.empty()) {
      drift.note = "not tested: " + vertical_note;
    } else if (gps_images.size() < 6) {
      drift.note = "not tested: fewer than 6 photos with GPS";
    } else if (const auto levelled = FitLevelledSimilarity(from, to, down_in_model, threshold)) {
      drift.tested = true;
      std::vector<Eigen::Vector3d> residuals(gps_images.size());
      FlightTimes inliers = flights;
      for (size_t k = 0; k < gps_images.size(); ++k) {
        residuals[k] = gps_to[k] - levelled->transform.Apply(gps_from[k]);
        if (!levelled->inliers[k]) inliers.flight[k] = -1;
      }
      const DriftTrend trend = FitDriftTrend(residuals, inliers, median_sigma_h, median_sigma_v);
      record_trend(trend);
      const bool drifting = num_timed >= 6 && trend.Significant();
      const bool tilted = drift.gps_fit_tilt_deg > 10.0;
      char text[280];
      if (drifting || tilted) {
        fit = levelled;
        drift.attitude_prior = true;
        drift.attitude_prior_sigma_deg = kAttitudePriorSigmaDeg;
        drift.estimated = drifting;
        if (drifting) {
          drift.axes = trend.significant_axes;
          attach_flights();
        }
        std::snprintf(text, sizeof text,
                      "the GPS alone would tilt this %s block by %.1f deg; levelled by %s "
                      "(attitude prior %.0f deg per photo)%s",
                      block_kind, drift.gps_fit_tilt_deg, levelled_by, kAttitudePriorSigmaDeg,
                      drifting ? ", the GPS drift estimated per flight" : "");
      } else if (num_timed < 6) {
        std::snprintf(text, sizeof text,
                      "no capture times: drift in time not tested; the GPS fit tilts the block %.1f deg from %s",
                      drift.gps_fit_tilt_deg, levelled_by);
      } else {
        std::snprintf(text, sizeof text,
                      "no significant trend in time of the GPS residuals; the GPS fit tilts the block %.1f deg "
                      "from %s",
                      drift.gps_fit_tilt_deg, levelled_by);
      }
      drift.note = text;
    } else {
      drift.note = "not tested: the levelled fit failed";
    }
    if (drift.vertical_source.empty()) {
      report.findings.push_back(Finding::Warning(
          "VERTICAL_FROM_GPS_ONLY",
          "the block's tilt rests on the GPS heights alone (" + vertical_note +
              "): a drift or error in them tilts the survey and nothing here can see it; add control points, or "
              "photos with gimbal angles"));
    }
    if (fit->num_inliers < static_cast<int>(from.size())) {
      std::vector<std::string> names;
      for (size_t k = 0; k < from.size(); ++k) {
        if (fit->inliers[k]) continue;
        names.push_back(k < gps_images.size() ? model->images[gps_images[k]].name
                                              : model->points[control_points[k - gps_images.size()]].name);
      }
      report.findings.push_back(Finding::Warning(
          "PRIORS_INCONSISTENT",
          std::to_string(names.size()) + " of " + std::to_string(from.size()) +
              " priors (GPS or control) disagree with the model by more than " + FormatMetres(threshold) +
              " in the initial fit: " + JoinNames(names),
          names));
    }
  }
  report.helmert_inliers = fit->num_inliers;
  report.helmert_rms_m = fit->rms_m;
  ApplySimilarity(fit->transform, model);
  report.check_points_in_bundle = options.bundle.check_points_in_bundle;
  for (const SurveyedPoint& s : surveyed) {
    Point& point = model->points[s.point_index];
    if (s.role == PointRole::kControl && !triangulated[s.point_index]) {
      point.position = point.prior->position;  // seen once: start at its survey
    }
    if (s.role == PointRole::kCheck && report.check_points_in_bundle) {
      // A free point of the bundle: starts where the similarity puts its rays.
      const auto t = TriangulatePoint(ViewsOf(*model, s.point_index));
      point.position = t ? t->position : point.prior->position;
    }
  }

  // The block's geometry (reported); what is refined is decided from the
  // intrinsics' precision after the adjustment (step 4).
  report.geometry = MeasureBlockGeometry(*model);
  report.refinement_auto = options.auto_refine;
  BundleOptions bundle = options.bundle;
  if (options.auto_refine) bundle.refine_intrinsics = IntrinsicsRefinement::kAll;
  // Except on nadir photos of flat ground at one altitude without control
  // heights: there f and the flying height are one unknown, which only the
  // GPS heights' metres hold, and a covariance sigma under 1 % is no
  // guarantee (0.94 % let f land 2.3 % off on a rendered crop-row field).
  // Held at its EXIF / certificate value from the outset; the rest refined.
  bool focal_held_flat = false;
  if (options.auto_refine && report.geometry.nadir_flat_single_altitude) {
    bool control_heights = false;
    for (const SurveyedPoint& s : surveyed) {
      control_heights |= s.role == PointRole::kControl && s.excluded.empty() && !s.source->horizontal_only;
    }
    const std::vector<char> used = CamerasInUse(*model);
    bool priors = true;
    for (size_t c = 0; c < used.size(); ++c) {
      if (used[c]) priors &= c < bundle.focal_prior_px.size() && bundle.focal_prior_px[c] > 0.0;
    }
    if (!control_heights && priors) {
      for (size_t c = 0; c < used.size(); ++c) {
        if (used[c]) model->cameras[c].params[model->cameras[c].info().focal_params.at(0)] = bundle.focal_prior_px[c];
      }
      bundle.refine_intrinsics = IntrinsicsRefinement::kList;
      bundle.refine_params = {"cx", "cy", "k1", "k2", "k3", "p1", "p2"};
      focal_held_flat = true;
    }
  }

  GpsVersusControl& versus = report.gps_vs_control;
  // Observations the adjustment on control alone rejected left the model
  // before the final solve: counted in its figure, never hidden.
  int outliers_before_final = 0;
  if (control_datum && !gps_images.empty()) {
    // GPS minus the camera centres of an adjustment held by the control
    // alone; a constant part is an offset (antenna, height reference), the
    // rest GPS noise or blunders. The similarity alone would not do: its
    // model still carries the reconstruction's intrinsics, and a focal
    // length 1 % off moves every camera height by 1 % of the flying height.
    ReportProgress(options.progress, 0.15, "adjustment on control alone: GPS against control");
    BundleOptions control_only = bundle;
    control_only.use_gps_priors = false;
    // A judge of the GPS, not a deliverable: Ceres' default tolerance
    // suffices (weakly held intrinsics converge slowly without the GPS).
    control_only.function_tolerance = std::max(bundle.function_tolerance, 1e-6);
    const BundleSummary control_summary = AdjustBundle(model, control_only);
    outliers_before_final = control_summary.outliers_removed;
    if (!control_summary.converged) {
      report.findings.push_back(Finding::Warning(
          "ADJUSTMENT_NOT_CONVERGED",
          "adjustment on control alone (to judge the GPS) did not converge: " + control_summary.termination));
    }
    versus.measured = true;
    versus.cameras = static_cast<int>(gps_images.size());
    std::vector<Eigen::Vector3d> d(gps_images.size());
    for (size_t k = 0; k < gps_images.size(); ++k) {
      d[k] = gps_to[k] - AntennaOf(model->images[gps_images[k]], bundle.gnss_lever_arm_m);
    }
    // A GNSS drift in time shows here directly (the control holds the
    // datum): estimated per flight, and the GPS judged after it.
    if (num_timed >= 6) {
      drift.tested = true;
      const DriftTrend trend = FitDriftTrend(d, flights, median_sigma_h, median_sigma_v);
      record_trend(trend);
      if (trend.Significant()) {
        drift.estimated = true;
        drift.axes = trend.significant_axes;
        attach_flights();
        for (size_t k = 0; k < gps_images.size(); ++k) {
          if (flights.flight[k] >= 0) d[k] -= initial_drift_rates[flights.flight[k]] * flights.dt_s[k];
        }
        drift.note = "GPS minus the control-only adjustment trends in time: drift estimated per flight";
      } else {
        drift.note = "no significant trend in time of GPS minus the control-only adjustment";
      }
    } else {
      drift.note = "not tested: capture times on fewer than 6 photos with GPS";
    }
    // The component-wise median of d over the images that `in` selects.
    auto median_of = [&](const std::function<bool(size_t)>& in) {
      Eigen::Vector3d median = Eigen::Vector3d::Zero();
      for (int c = 0; c < 3; ++c) {
        std::vector<double> v;
        for (size_t k = 0; k < d.size(); ++k) {
          if (in(k)) v.push_back(d[k][c]);
        }
        if (v.empty()) continue;
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        median[c] = v[v.size() / 2];
      }
      return median;
    };
    const Eigen::Vector3d median = median_of([](size_t) { return true; });
    // Per flight (--gps-offset per-flight): each flight judged about its own
    // offset, which may differ from the others' by more than the threshold.
    const bool per_flight = options.gps_offset == GpsOffsetPolicy::kPerFlight && flights.NumFlights() > 1;
    std::vector<Eigen::Vector3d> flight_median(flights.NumFlights(), median);
    if (per_flight) {
      for (int f = 0; f < flights.NumFlights(); ++f) {
        flight_median[f] = median_of([&](size_t k) { return flights.flight[k] == f; });
      }
    }
    auto centre_of = [&](size_t k) {
      return per_flight && flights.flight[k] >= 0 ? flight_median[flights.flight[k]] : median;
    };
    std::vector<char> consistent(gps_images.size(), 0);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sigma_sum = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> flight_sum(flights.NumFlights(), Eigen::Vector3d::Zero());
    std::vector<int> flight_count(flights.NumFlights(), 0);
    for (size_t k = 0; k < gps_images.size(); ++k) {
      const PositionPrior& prior = *model->images[gps_images[k]].gps_prior;
      const double threshold = threshold_for(std::max(prior.sigma_h_m, prior.sigma_v_m));
      if ((d[k] - centre_of(k)).norm() > threshold) continue;
      consistent[k] = 1;
      ++versus.consistent;
      sum += d[k];
      sigma_sum += Eigen::Vector3d(prior.sigma_h_m, prior.sigma_h_m, prior.sigma_v_m);
      if (flights.flight[k] >= 0) {
        flight_sum[flights.flight[k]] += d[k];
        ++flight_count[flights.flight[k]];
      }
    }
    if (per_flight) {
      for (int f = 0; f < flights.NumFlights(); ++f) {
        versus.flight_offsets_enu_m.push_back(flight_count[f] > 0 ? Eigen::Vector3d(flight_sum[f] / flight_count[f])
                                                                  : flight_median[f]);
      }
    }
    if (versus.consistent > 0) {
      const double n = versus.consistent;
      versus.offset_enu_m = sum / n;
      Eigen::Vector3d var = Eigen::Vector3d::Zero();
      for (size_t k = 0; k < gps_images.size(); ++k) {
        if (consistent[k]) var += (d[k] - versus.offset_enu_m).cwiseAbs2();
      }
      versus.rms_after_offset_m = (var / n).cwiseSqrt();
      versus.offset_sigma_m = n > 1 ? Eigen::Vector3d((var / (n - 1) / n).cwiseSqrt())
                                    : Eigen::Vector3d(sigma_sum / n);
      const Eigen::Vector3d prior_sigma = sigma_sum / n;
      for (int c = 0; c < 3; ++c) {
        versus.significant |= std::abs(versus.offset_enu_m[c]) > 3.0 * versus.offset_sigma_m[c] &&
                              std::abs(versus.offset_enu_m[c]) > prior_sigma[c];
      }
    }
    // GPS positions that disagree with the control datum leave the adjustment.
    for (size_t k = 0; k < gps_images.size(); ++k) {
      if (consistent[k]) continue;
      Image& image = model->images[gps_images[k]];
      versus.rejected.push_back(image.name);
      rejected_gps[gps_images[k]] = *image.gps_prior;
      image.gps_prior.reset();
    }
    const Eigen::Vector3d& o = versus.offset_enu_m;
    const Eigen::Vector3d& so = versus.offset_sigma_m;
    const std::string offset_text = "E " + FormatMetres(o.x()) + " ± " + FormatMetres(so.x()) + ", N " +
                                    FormatMetres(o.y()) + " ± " + FormatMetres(so.y()) + ", U " +
                                    FormatMetres(o.z()) + " ± " + FormatMetres(so.z());
    if (versus.significant) {
      const bool estimate = options.gps_offset != GpsOffsetPolicy::kNever;
      report.findings.push_back(Finding::Warning(
          "GPS_CONTROL_OFFSET",
          "GPS and control disagree by a constant offset (GPS minus control datum, " +
          std::to_string(versus.consistent) + " cameras): " + offset_text +
          (estimate ? "; estimated in the adjustment as a GPS offset (antenna or height "
                      "reference: check --gps-altitude)"
                    : "; not estimated (--gps-offset never): the GPS pulls against the control")));
    }
    if (!versus.rejected.empty()) {
      report.findings.push_back(Finding::Warning(
          "GPS_REJECTED",
          std::to_string(versus.rejected.size()) + " of " + std::to_string(versus.cameras) +
              " GPS positions disagree with the control datum after the offset; left out of the "
              "adjustment: " + JoinNames(versus.rejected),
          versus.rejected));
    }
  }

  const bool always = options.gps_offset == GpsOffsetPolicy::kAlways ||
                     options.gps_offset == GpsOffsetPolicy::kPerFlight;
  if (versus.measured && options.gps_offset != GpsOffsetPolicy::kNever && (versus.significant || always)) {
    bundle.estimate_gps_offset = true;
    bundle.initial_gps_offset_m = versus.offset_enu_m;
    if (!versus.flight_offsets_enu_m.empty()) {
      // One offset per flight: each GPS prior learns its flight.
      attach_flights();
      bundle.gps_offset_per_flight = true;
      bundle.initial_gps_flight_offsets_m = versus.flight_offsets_enu_m;
    }
  } else if (always && !gps_images.empty()) {
    report.findings.push_back(Finding::Warning(
        "GPS_OFFSET_NOT_ESTIMATED",
        "GPS offset not estimated: it needs 3 or more non-collinear control points measured in 2 "
        "or more images each to hold the datum"));
  }

  if (drift.estimated) {
    bundle.estimate_gps_drift = true;
    bundle.gps_drift_axes = drift.axes;
    bundle.initial_gps_drift_m_per_s = initial_drift_rates;
  }
  if (drift.attitude_prior) {
    bundle.attitude_prior_sigma_deg = drift.attitude_prior_sigma_deg;
    bundle.attitude_prior_down_in_camera.clear();
    if (drift.vertical_source == "gimbal") {
      // Each photo's own vertical; photos without gimbal angles go without.
      bundle.attitude_prior_down_in_camera.assign(model->images.size(), Eigen::Vector3d::Zero());
      for (size_t i = 0; i < model->images.size(); ++i) {
        const auto it = options.gimbal.find(model->images[i].name);
        if (it != options.gimbal.end()) bundle.attitude_prior_down_in_camera[i] = DownInCamera(it->second);
      }
    }
  }

  // 4. Bundle adjustment with priors.
  ReportProgress(options.progress, 0.2, "bundle adjustment with GPS and control priors");
  bundle.compute_intrinsics_covariance = true;
  bundle.compute_precision = options.posterior_precision;
  const SparseModel before_final = *model;
  report.bundle = AdjustBundle(model, bundle);
  report.refined = report.bundle.refined_intrinsics;
  report.refinement_reason = options.auto_refine ? "every intrinsic refined: the block determines them"
                                                 : "as asked (--refine)";
  if (focal_held_flat) {
    report.refinement_reason =
        "focal length held at its EXIF / certificate value: nadir photos of flat ground at one altitude (depths "
        "within " + FormatPercent(report.geometry.roughness_ratio) + " of a plane in each photo) and no control "
        "heights, so f and the flying height are one unknown; the rest refined";
    report.findings.push_back(Finding::Warning("FOCAL_HELD", report.refinement_reason));
  }
  // A focal length the block does not determine: held at its prior (auto),
  // or flagged.
  {
    std::vector<std::string> weak;
    std::string detail;
    bool all_have_priors = true;
    for (const IntrinsicsPrecision& p : report.bundle.intrinsics_precision) {
      const Camera& camera = model->cameras[p.camera];
      const std::string f_name = camera.info().param_names[camera.info().focal_params.at(0)];
      const auto it = std::find(p.names.begin(), p.names.end(), f_name);
      if (it == p.names.end()) continue;
      const size_t k = static_cast<size_t>(it - p.names.begin());
      const double rel = p.sigmas[k] / p.values[k];
      if (rel <= options.weak_focal_rel) continue;
      weak.push_back("camera " + std::to_string(camera.id));
      char text[160];
      std::snprintf(text, sizeof text, "sigma f %.2f %% of f, correlation with the camera heights %.2f (median)",
                    100.0 * rel, p.focal_height_correlation_median);
      detail = text;
      const bool has_prior = static_cast<size_t>(p.camera) < bundle.focal_prior_px.size() &&
                             bundle.focal_prior_px[p.camera] > 0.0;
      all_have_priors &= has_prior;
    }
    // No covariance (report.bundle.covariance_note says why): whether the
    // block determines f is not measured, and its geometry decides. Nadir
    // photos of flat ground at one altitude cannot (f and the flying height
    // are one unknown): held as if measured weak. Otherwise said.
    if (options.auto_refine && !focal_held_flat && report.bundle.intrinsics_precision.empty() &&
        !report.bundle.covariance_note.empty()) {
      if (report.geometry.nadir_flat_single_altitude) {
        const std::vector<char> used = CamerasInUse(*model);
        for (size_t c = 0; c < used.size(); ++c) {
          if (!used[c]) continue;
          weak.push_back("camera " + std::to_string(model->cameras[c].id));
          all_have_priors &= c < bundle.focal_prior_px.size() && bundle.focal_prior_px[c] > 0.0;
        }
        detail = "its precision could not be computed: " + report.bundle.covariance_note;
      } else {
        report.refinement_reason += " (their precision could not be computed: " + report.bundle.covariance_note +
                                    "; the block is not nadir photos of flat ground at one altitude)";
      }
    }
    const std::string flat = report.geometry.nadir_flat_single_altitude
                                 ? " (nadir photos of flat ground at one altitude: f and the flying height are one "
                                   "unknown)"
                                 : "";
    if (!weak.empty() && options.auto_refine && all_have_priors) {
      // Hold f at the prior of every group and solve again from the same start.
      *model = before_final;
      for (size_t c = 0; c < model->cameras.size() && c < bundle.focal_prior_px.size(); ++c) {
        if (bundle.focal_prior_px[c] > 0.0) {
          model->cameras[c].params[model->cameras[c].info().focal_params.at(0)] = bundle.focal_prior_px[c];
        }
      }
      bundle.refine_intrinsics = IntrinsicsRefinement::kList;
      bundle.refine_params = {"cx", "cy", "k1", "k2", "k3", "p1", "p2"};
      report.bundle = AdjustBundle(model, bundle);
      report.refined = report.bundle.refined_intrinsics;
      report.refinement_reason = "focal length held at its EXIF / certificate value: the block does not determine "
                                 "it (" + detail + ")" + flat + "; the rest refined";
      report.findings.push_back(Finding::Warning("FOCAL_HELD", report.refinement_reason, weak));
    } else if (!weak.empty()) {
      report.refinement_reason += "; the focal length is weakly determined (" + detail + ")" + flat;
      report.findings.push_back(Finding::Warning(
          "FOCAL_WEAKLY_DETERMINED",
          "the focal length is refined but the block does not determine it (" + detail + ")" + flat +
              (options.auto_refine ? "; no EXIF or certificate focal length to hold it at"
                                   : "; --refine auto holds it at its EXIF value") +
              ": camera heights and the DSM's scale follow it",
          weak));
    }
  }
  report.bundle.outliers_removed += outliers_before_final;
  for (Finding& f : IntrinsicsCorrelationFindings(report.bundle.intrinsics_precision)) {
    report.findings.push_back(std::move(f));
  }
  for (auto& [index, prior] : rejected_gps) model->images[index].gps_prior = prior;
  // What the receiver should have read for an image, as adjusted: its
  // antenna, plus the GPS offset and the flight's drift where estimated.
  auto gps_as_adjusted = [&](const Image& image) {
    Eigen::Vector3d at = AntennaOf(image, options.bundle.gnss_lever_arm_m) + report.bundle.GpsOffsetOf(*image.gps_prior);
    const PositionPrior& p = *image.gps_prior;
    if (report.bundle.gps_drift_estimated && p.flight >= 0 &&
        p.flight < static_cast<int>(report.bundle.gps_drift_m_per_s.size())) {
      at += report.bundle.gps_drift_m_per_s[p.flight] * p.time_from_flight_s;
    }
    return at;
  };

  // The drift as estimated, and the cameras' attitude against the flight type.
  if (drift.estimated) {
    const BundlePrecision& precision = report.bundle.precision;
    // The rates rest on the GPS alone: their sigma is scaled by the GPS
    // priors' own variance factor (their standardised residuals after the
    // drift), not by the adjustment's, which the tie points dominate.
    double gps_sum2 = 0.0;
    int gps_rows = 0;
    for (const Image& image : model->images) {
      if (!image.registered || !image.gps_prior) continue;
      if (rejected_gps.count(static_cast<int>(&image - model->images.data()))) continue;
      const Eigen::Vector3d r = gps_as_adjusted(image) - image.gps_prior->position;
      const Eigen::Vector3d sigma(image.gps_prior->sigma_h_m, image.gps_prior->sigma_h_m, image.gps_prior->sigma_v_m);
      gps_sum2 += r.cwiseQuotient(sigma).squaredNorm();
      gps_rows += 3;
    }
    int drift_params = 0;
    for (int a = 0; a < 3; ++a) drift_params += drift.axes[a] ? static_cast<int>(drift.flights.size()) : 0;
    const double gps_variance_factor =
        gps_rows > drift_params + 3 ? gps_sum2 / (gps_rows - drift_params - 3) : 1.0;
    std::string text;
    for (size_t f = 0; f < drift.flights.size() && f < report.bundle.gps_drift_m_per_s.size(); ++f) {
      GpsDriftReport::Flight& flight = drift.flights[f];
      flight.rate_m_per_s = report.bundle.gps_drift_m_per_s[f];
      if (precision.computed && f < precision.gps_drift_cov.size() && precision.variance_factor > 0.0) {
        flight.rate_sigma = (precision.gps_drift_cov[f].diagonal() / precision.variance_factor * gps_variance_factor)
                                .cwiseMax(0.0)
                                .cwiseSqrt();
      }
      const char* axis_names[3] = {"E", "N", "U"};
      for (int a = 0; a < 3; ++a) {
        if (!drift.axes[a]) continue;
        char part[200];
        std::snprintf(part, sizeof part, "%sflight %zu %s %+.3f m/s ± %.3f (%+.1f m over %.0f s)",
                      text.empty() ? "" : "; ", f + 1, axis_names[a], flight.rate_m_per_s[a], flight.rate_sigma[a],
                      flight.rate_m_per_s[a] * flight.duration_s, flight.duration_s);
        text += part;
      }
    }
    report.findings.push_back(Finding::Warning(
        "GPS_DRIFT",
        "the GPS positions drift in time (" + text + "): estimated in the adjustment as a GNSS drift per flight" +
            (drift.attitude_prior ? std::string("; the block's tilt held by the photos' ") +
                                        (drift.vertical_source == "gimbal" ? "gimbal pitches" : "nadir attitude") +
                                        " (the GPS alone would tilt it " +
                                     FormatDegrees(drift.gps_fit_tilt_deg) + "); without control the heights carry "
                                     "the GPS's mean error"
                               : std::string("; the control holds the datum"))));
  } else if (drift.attitude_prior) {
    const bool gimbal = drift.vertical_source == "gimbal";
    report.findings.push_back(Finding::Warning(
        "GPS_TILT_REJECTED",
        std::string("the GPS heights would tilt this ") + (gimbal ? "oblique" : "nadir") + " block by " +
            FormatDegrees(drift.gps_fit_tilt_deg) + " without any trend in time; the block is levelled by the photos' " +
            (gimbal ? "gimbal pitches" : "nadir attitude") + " instead: check the GPS altitudes"));
  }
  report.tilt = MeasureTilt(*model);
  if (report.viewing.nadir && report.tilt.mean_axis_tilt_deg > 10.0) {
    report.findings.push_back(Finding::Error(
        "CAMERA_ATTITUDE_IMPLAUSIBLE",
        "the adjusted block of nadir photos looks " + FormatDegrees(report.tilt.mean_axis_tilt_deg) +
            " off vertical (mean optical axis; median photo " + FormatDegrees(report.tilt.median_deg) +
            "): the datum is tilted. GPS heights drifting or wrong, or control in a wrong CRS?"));
  }
  // Nothing but the GPS heights set the block's tilt (no nadir axis, no
  // gimbal, no control): a ground that slopes more than 20° over the whole
  // block is what a drifting GPS altitude makes of a level one.
  if (!control_datum && drift.vertical_source.empty() && !local &&
      report.tilt.ground_slope_deg > kGpsOnlyGroundSlopeDeg) {
    report.findings.push_back(Finding::Error(
        "GROUND_TILTED_BY_GPS",
        "the adjusted ground slopes " + FormatDegrees(report.tilt.ground_slope_deg) + " across the whole block (plane "
            "through " + std::to_string(report.tilt.ground_points) + " tie points) and only the GPS heights set the "
            "block's tilt (" + report.viewing.reason + ", no gimbal angles, no control): a drifting or wrong GPS "
            "altitude tilts a survey this way. Add control points or photos with gimbal angles, or run with "
            "--keep-going if the ground truly slopes so"));
  }

  // 5. Check points from the adjusted cameras alone; residuals in the output CRS.
  ReportProgress(options.progress, 0.9, "check points");
  std::vector<Eigen::Vector3d> control_d, check_d;
  for (const SurveyedPoint& s : surveyed) {
    Point& point = model->points[s.point_index];
    GroundPointResult r =
        EvaluateGroundPoint(s.source->name, s.role, ViewsOf(*model, s.point_index), s.geodetic, frame,
                            *out_crs, /*triangulate=*/s.role == PointRole::kCheck && !report.check_points_in_bundle,
                            &point.position);
    if (!s.excluded.empty()) {
      r.solved = false;
      r.why_not = s.excluded;
    }
    if (s.source->horizontal_only && s.role == PointRole::kControl) {
      // Its height is the adjustment's own: no vertical residual, and no
      // part in the 3D statistics (which count the points they rest on).
      r.horizontal_only = true;
      r.d_m.z() = std::numeric_limits<double>::quiet_NaN();
      r.surveyed_crs.z() = std::numeric_limits<double>::quiet_NaN();
    } else if (r.solved) {
      (s.role == PointRole::kControl ? control_d : check_d).push_back(r.d_m);
    }
    const PointPrecision* precision = report.bundle.precision.ForPoint(s.point_index);
    if (r.solved && precision) {
      const Eigen::Matrix3d j = CrsFromEnuJacobian(frame, *out_crs, point.position);
      r.has_precision = true;
      r.sigma_m = (j * precision->cov * j.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
    }
    (s.role == PointRole::kControl ? report.control : report.check).push_back(r);
  }
  report.control_stats = AccuracyStats::FromResiduals(control_d);
  report.check_stats = AccuracyStats::FromResiduals(check_d);

  // Dome test: check points' vertical residuals, else the cameras' against GPS.
  {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    int n = 0;
    for (const Image& image : model->images) {
      if (!image.registered) continue;
      centre += image.pose.centre_in_world.head<2>();
      ++n;
    }
    if (n > 0) centre /= n;
    double radius = 0.0;
    for (const Image& image : model->images) {
      if (image.registered) radius = std::max(radius, (image.pose.centre_in_world.head<2>() - centre).norm());
    }
    std::vector<Eigen::Vector2d> xy;
    std::vector<double> dz;
    for (size_t k = 0; k < report.check.size(); ++k) {
      if (!report.check[k].solved) continue;
      for (const SurveyedPoint& s : surveyed) {
        if (s.role == PointRole::kCheck && s.source->name == report.check[k].name) {
          xy.push_back(model->points[s.point_index].position.head<2>());
          dz.push_back(report.check[k].d_m.z());
        }
      }
    }
    std::string source = "check points";
    if (xy.size() < 4) {
      xy.clear();
      dz.clear();
      source = "GPS";
      for (const Image& image : model->images) {
        if (!image.registered || !image.gps_prior || rejected_gps.count(static_cast<int>(&image - model->images.data()))) {
          continue;
        }
        xy.push_back(image.pose.centre_in_world.head<2>());
        dz.push_back((gps_as_adjusted(image) - image.gps_prior->position).z());
      }
    }
    report.dome = FitDome(xy, dz, centre, radius, source);
  }

  const BundlePrecision& precision = report.bundle.precision;
  report.precision_note = precision.computed ? "" : precision.note;
  for (size_t index = 0; index < model->images.size(); ++index) {
    const Image& image = model->images[index];
    if (!image.registered) continue;
    CameraResult c;
    c.name = image.name;
    {
      const Eigen::Vector3d& centre = image.pose.centre_in_world;
      c.position_crs = out_crs->FromGeodetic(frame.GeodeticFromEnu(centre));
      const Eigen::Matrix3d j = CrsFromEnuJacobian(frame, *out_crs, centre);
      const Eigen::Matrix3d grid = RotationOf(j);
      const Eigen::Vector3d opk = OmegaPhiKappa(GridFromPhoto(grid, image.pose.cam_from_world));
      c.opk_deg = opk * 180.0 / M_PI;
      if (const ImagePrecision* ip = precision.ForImage(static_cast<int>(index))) {
        c.has_precision = true;
        c.sigma_position_m = (j * ip->centre_cov * j.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt();
        // d(ω, φ, κ)/dθ of Exp(θ) R_cw, by central differences.
        Eigen::Matrix3d d;
        const double eps = 1e-6;
        for (int k = 0; k < 3; ++k) {
          const Eigen::Quaterniond turn(Eigen::AngleAxisd(eps, Eigen::Vector3d::Unit(k)));
          const Eigen::Vector3d plus = OmegaPhiKappa(GridFromPhoto(grid, turn * image.pose.cam_from_world));
          const Eigen::Vector3d minus =
              OmegaPhiKappa(GridFromPhoto(grid, turn.conjugate() * image.pose.cam_from_world));
          for (int a = 0; a < 3; ++a) d(a, k) = WrapAngle(plus[a] - minus[a]) / (2.0 * eps);
        }
        c.sigma_opk_deg =
            (d * ip->rotation_cov * d.transpose()).diagonal().cwiseMax(0.0).cwiseSqrt() * 180.0 / M_PI;
      }
    }
    if (image.gps_prior) {
      c.has_prior = true;
      c.prior_rejected = rejected_gps.count(static_cast<int>(&image - model->images.data())) > 0;
      c.d_enu_m = gps_as_adjusted(image) - image.gps_prior->position;
      c.sigma_h_m = image.gps_prior->sigma_h_m;
      c.sigma_v_m = image.gps_prior->sigma_v_m;
      c.flight = image.gps_prior->flight;
    }
    report.cameras.push_back(c);
  }
  if (options.posterior_precision && !precision.computed) {
    report.findings.push_back(Finding::Warning(
        "PRECISION_NOT_COMPUTED", "posterior standard deviations and the marks' w-test are missing: " + precision.note));
  }
  // Observation groups whose data scatter several times their stated sigmas
  // (control has its own finding, CONTROL_WEAKER_THAN_STATED).
  for (const VarianceComponent& vc : report.bundle.variance_components) {
    if (vc.group == ObservationGroup::kControl || !(vc.stated_sigma > 0.0)) continue;
    const double factor = vc.EstimatedSigma() / vc.stated_sigma;
    if (!(factor > 3.0)) continue;
    const bool px = vc.group == ObservationGroup::kTies || vc.group == ObservationGroup::kMarks;
    char text[400];
    std::snprintf(text, sizeof text,
                  "%s scatter %.1f times their stated sigma: %.3g %s against %.3g %s (variance component, "
                  "redundancy %.0f)%s",
                  vc.group == ObservationGroup::kTies            ? "tie-point measurements"
                  : vc.group == ObservationGroup::kMarks         ? "target marks"
                  : vc.group == ObservationGroup::kGpsHorizontal ? "GPS positions horizontally"
                                                                 : "GPS heights",
                  factor, vc.EstimatedSigma(), px ? "px" : "m", vc.stated_sigma, px ? "px" : "m", vc.redundancy,
                  vc.estimated ? "; the adjustment weighs them by the estimate"
                               : "; state the estimate, or let it be used (--variance-components estimate)");
    report.findings.push_back(Finding::Warning("SIGMAS_OPTIMISTIC", text, {ToString(vc.group)}));
  }
  // Data snooping on the marks (SnoopMarks).
  for (const MarkTest& t : precision.marks) {
    MarkResult m;
    m.point = model->points[t.point].name;
    m.image = model->images[t.image].name;
    m.role = model->points[t.point].role;
    m.residual_px = t.residual_px;
    m.redundancy = t.redundancy;
    m.w = t.w;
    report.marks.push_back(m);
  }
  report.mark_tests = CountMarkTests(report.marks);
  report.mark_family_alpha = options.gates.mark_family_alpha;
  report.w_critical_family = FamilyWiseCriticalValue(std::max(report.mark_tests, 1), report.mark_family_alpha);
  for (Finding& f : SnoopMarks(&report.marks, report.w_critical, report.w_critical_family)) {
    report.findings.push_back(std::move(f));
  }
  ApplyQualityGates(*model, options.gates, &report);
  if (options.leave_one_out) {
    LeaveOneOut& loo = report.leave_one_out;
    const auto loo_start = std::chrono::steady_clock::now();
    const int n = control ? static_cast<int>(control->points.size()) : 0;
    if (n < 4) {
      loo.note = "needs 4 or more control points (have " + std::to_string(n) + "): 3 must hold the datum";
    } else {
      GeoreferenceOptions once = options;
      once.leave_one_out = false;
      once.progress = nullptr;
      once.posterior_precision = false;
      // The weights the survey's own adjustment arrived at.
      for (const VarianceComponent& vc : report.bundle.variance_components) {
        once.bundle.sigma_scale[static_cast<int>(vc.group)] = vc.scale;
      }
      once.bundle.estimate_variance_components = false;
      std::vector<Eigen::Vector3d> d;
      for (int k = 0; k < n; ++k) {
        ReportProgress(options.progress, 0.9 + 0.1 * k / n,
                       "leave-one-out: without " + control->points[k].name);
        GcpFile without = *control;
        without.points.erase(without.points.begin() + k);
        GcpFile alone = *control;
        alone.points = {control->points[k]};
        SparseModel copy = *start;
        const GeoreferenceReport r = GeoreferenceAndAdjust(&copy, gps, &without, &alone, once);
        GroundPointResult p = r.check.at(0);
        p.role = PointRole::kControl;
        if (p.solved) d.push_back(p.d_m);
        loo.points.push_back(p);
        ++loo.adjustments;
      }
      loo.stats = AccuracyStats::FromResiduals(d);
      loo.computed = true;
    }
    loo.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - loo_start).count();
  }
  ReportProgress(options.progress, 1.0, "georeferenced");
  return report;
}

}  // namespace aerotri
