// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/georeferencing.h"

#include <algorithm>
#include <functional>
#include <map>
#include <set>
#include <limits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <unordered_map>

#include <Eigen/SVD>

#include "libphoto/base/error.h"
#include "libphoto/base/memory.h"
#include "libphoto/geometry/triangulation.h"
#include "libphoto/survey/quality_gates.h"
#include "libphoto/survey/survey_phases.h"

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
  // The optimum, not near it: a relative function tolerance (Ceres' 1e-6,
  // this project's earlier 1e-7) stops short along a weak block's omega-Y
  // valley by tenths of a millimetre at the check points and millimetres at
  // the cameras (DBAT's five-frame block), and so does a parameter
  // tolerance relative to coordinates of a million metres. The solves stop
  // when a step gains less than 1e-6 of the whitened cost, about a
  // thousandth of a sigma (BundleOptions::cost_change_tolerance).
  o.cost_change_tolerance = 1e-6;
  o.function_tolerance = 1e-12;
  o.parameter_tolerance = 1e-12;
  o.gradient_tolerance = 1e-10;
  return o;
}

// ---- Helpers shared by the phases (survey_phases.h).

std::vector<View> ViewsOf(const SparseModel& model, int point_index) {
  std::vector<View> views;
  for (const Observation& obs : model.observations) {
    if (obs.point != point_index) continue;
    const Image& image = model.images[obs.image];
    if (!image.registered) continue;
    const Camera& camera = model.cameras[image.camera];
    views.push_back({&camera, image.PoseAtRow(obs.xy.y(), camera.height), obs.xy});  // a rolling shutter's row
  }
  return views;
}

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

std::string FormatMilliseconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f ms", 1000.0 * s);
  return text;
}

// Where the GNSS antenna of an image is: its centre plus the lever arm
// turned into the world (BundleOptions::gnss_lever_arm_m).
Eigen::Vector3d AntennaOf(const Image& image, const Eigen::Vector3d& lever) {
  return image.pose.centre_in_world + image.pose.cam_from_world.conjugate() * lever;
}

void ApplySimilarity(const Similarity& s, SparseModel* model) {
  for (Image& image : model->images) {
    image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
    image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
  }
  for (Point& point : model->points) point.position = s.Apply(point.position);
}

double HelmertThreshold(const GeoreferenceOptions& options, double max_sigma) {
  return options.helmert_inlier_m > 0.0 ? options.helmert_inlier_m : std::max(0.5, 5.0 * max_sigma);
}

Eigen::Vector3d GpsAsAdjusted(const SurveyState& s, const Image& image) {
  const BundleSummary& b = s.report.bundle;
  Eigen::Vector3d at = AntennaOf(image, s.Options().bundle.gnss_lever_arm_m) + b.GpsOffsetOf(*image.gps_prior);
  const PositionPrior& p = *image.gps_prior;
  if (b.gps_drift_estimated && p.flight >= 0 && p.flight < static_cast<int>(b.gps_drift_m_per_s.size())) {
    at += b.gps_drift_m_per_s[p.flight] * p.time_from_flight_s;
  }
  return at;
}

// ---- Public functions (georeferencing.h).

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

std::vector<MarkOffset> FindMarkOffsets(const std::vector<MarkResult>& marks, double family_alpha) {
  // The groups: every mark (an offset of the whole survey's marks against
  // its ties), the marks of each image, and of each point, three or more.
  std::map<std::pair<int, std::string>, std::vector<int>> groups;
  for (size_t k = 0; k < marks.size(); ++k) {
    if (!(marks[k].redundancy.array() > 1e-6).all() || !marks[k].w.allFinite()) continue;
    groups[{0, ""}].push_back(static_cast<int>(k));
    groups[{1, marks[k].image}].push_back(static_cast<int>(k));
    groups[{2, marks[k].point}].push_back(static_cast<int>(k));
  }
  int tests = 0;
  for (const auto& [key, members] : groups) tests += members.size() >= 3 ? 2 : 0;
  const double critical = FamilyWiseCriticalValue(std::max(tests, 1), family_alpha);
  std::vector<MarkOffset> found;
  // Where every mark shares an offset, the images' and points' groups are
  // tested about it.
  Eigen::Vector2d common_w = Eigen::Vector2d::Zero(), common_px = Eigen::Vector2d::Zero();
  for (const auto& [key, members] : groups) {
    const int k = static_cast<int>(members.size());
    if (k < 3) continue;
    for (int axis = 0; axis < 2; ++axis) {
      // The marks' mean w, scaled to unit variance under no offset; it must
      // hold without its largest |w| (one blunder is not an offset), and two
      // thirds of the marks must share its sign.
      double sum = 0.0, largest = 0.0, residual = 0.0;
      for (int m : members) {
        const double w = marks[m].w[axis] - common_w[axis];
        sum += w;
        residual += marks[m].residual_px[axis] - common_px[axis];
        if (std::abs(w) > std::abs(largest)) largest = w;
      }
      const double z = sum / std::sqrt(k);
      const double z_without = (sum - largest) / std::sqrt(k - 1);
      int same_sign = 0;
      for (int m : members) same_sign += (marks[m].w[axis] - common_w[axis] > 0) == (sum > 0);
      if (!(std::abs(z) > critical && std::abs(z_without) > critical && 3 * same_sign >= 2 * k)) continue;
      if (key.first == 0) {
        common_w[axis] = sum / k;
        common_px[axis] = residual / k;
      }
      MarkOffset o;
      o.all = key.first == 0;
      o.per_image = key.first == 1;
      o.name = key.second;
      o.axis = axis;
      o.marks = k;
      o.same_sign = same_sign;
      o.mean_residual_px = residual / k;
      o.z = z;
      o.critical_value = critical;
      for (int m : members) o.members.push_back(m);
      found.push_back(o);
    }
  }
  std::stable_sort(found.begin(), found.end(), [](const MarkOffset& a, const MarkOffset& b) {
    return a.all != b.all ? a.all : std::abs(a.z) > std::abs(b.z);
  });
  return found;
}

std::vector<Finding> SnoopMarks(std::vector<MarkResult>* marks, double w_critical, double w_critical_family,
                                double family_alpha) {
  MarkResult* worst = nullptr;
  int suspects = 0;
  for (MarkResult& m : *marks) {
    const double w = m.w.cwiseAbs().maxCoeff();
    m.suspect = w > w_critical;
    m.rejected = false;
    suspects += m.suspect;
    if (!worst || w > worst->w.cwiseAbs().maxCoeff()) worst = &m;
  }
  std::vector<Finding> findings;
  // A photo's (or a point's) marks sharing one offset: a systematic error
  // of that photo's or point's marking, said as such rather than as the
  // one blunder it would otherwise look like.
  const std::vector<MarkOffset> offsets = FindMarkOffsets(*marks, family_alpha);
  std::set<std::pair<int, std::string>> said;
  bool worst_explained = false;
  for (const MarkOffset& o : offsets) {
    if (!said.insert({o.all ? 0 : o.per_image ? 1 : 2, o.name}).second) continue;
    const auto worst_index = worst ? static_cast<int>(worst - marks->data()) : -1;
    worst_explained |=
        !o.all && std::find(o.members.begin(), o.members.end(), worst_index) != o.members.end();
    char text[600];
    if (o.all) {
      std::snprintf(text, sizeof text,
                    "all %d target marks share an offset of %.2f px in %s against the tie points (%d of them on "
                    "its side; their mean w %.1f, critical value %.2f): the targets were measured in another "
                    "pixel convention or program than the ties%s",
                    o.marks, o.mean_residual_px, o.axis == 0 ? "x" : "y", o.same_sign, o.z, o.critical_value,
                    offsets.size() > 1 ? "; the photos and points below are tested about it" : "");
      findings.push_back(Finding::Warning("MARKS_OFFSET", text, {"all marks"}));
      continue;
    }
    std::snprintf(text, sizeof text,
                  "the %d marks %s '%s' share an offset of %.2f px in %s (%d of them on its side; their mean w "
                  "%.1f, critical value %.2f)%s: a systematic error of %s, not one blunder: %s",
                  o.marks, o.per_image ? "on image" : "of point", o.name.c_str(), o.mean_residual_px,
                  o.axis == 0 ? "x" : "y", o.same_sign, o.z, o.critical_value,
                  offsets.front().all ? " beyond the marks' common offset" : "",
                  o.per_image ? "that photo's marking (another measuring session or program, a pixel "
                                "convention, a resampled or cropped image)"
                              : "that point's marking (the marks set on another feature of the target, or "
                                "its coordinates wrong)",
                  o.per_image ? "check and re-measure the photo's marks" : "check the target's marks and survey");
    findings.push_back(Finding::Warning("MARKS_OFFSET", text, {o.name}));
  }
  if (!worst || !(worst->w.cwiseAbs().maxCoeff() > w_critical_family) || worst_explained) return findings;
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
  findings.push_back(Finding::Warning("MARK_BLUNDER", text, {worst->point, worst->image}));
  return findings;
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


namespace {

// Runs the stage's phases one by one, each timed into the report: wall and
// CPU time, and its resident peak (a span of its own inside the stage's).
class PhaseTimer {
 public:
  explicit PhaseTimer(GeoreferenceReport* report) : report_(report) {}
  template <typename Phase>
  void operator()(const char* name, Phase&& phase) {
    const auto wall = std::chrono::steady_clock::now();
    const std::clock_t cpu = std::clock();
    GeoreferenceReport::Phase& record = report_->phases.emplace_back();
    record.name = name;
    const PeakRssSpan span;
    phase();
    record.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
    record.cpu_s = static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC;
    record.peak_rss_mb = span.PeakMb();
  }

 private:
  GeoreferenceReport* report_;
};

}  // namespace

GeoreferenceReport GeoreferenceAndAdjust(SparseModel* model, const std::map<std::string, GpsFix>& gps,
                                         const GcpFile* control, const GcpFile* checks,
                                         const GeoreferenceOptions& options) {
  SurveyState s = StartSurvey(model, gps, control, checks, options);
  PhaseTimer timed(&s.report);
  ReportProgress(options.progress, 0.0, "reading control");
  timed("inputs, frame and priors", [&] {
    if (auto duplicated = CheckDuplicatedMarks(control, checks)) s.report.findings.push_back(std::move(*duplicated));
    ChooseFrameAndDatum(&s);
    AttachPriors(&s);
  });
  ReportProgress(options.progress, 0.1, "initial similarity fit");
  timed("initial similarity", [&] { FitInitialSimilarity(&s); });
  timed("GNSS model", [&] {
    ChooseRefinement(&s);
    ModelGnss(&s);
  });
  ReportProgress(options.progress, 0.2, "bundle adjustment with GPS and control priors");
  timed("adjustment", [&] { AdjustBlock(&s); });
  timed("weak focal", [&] { HoldWeakFocal(&s); });
  timed("GNSS, attitude and shutter", [&] {
    ReportReadouts(&s);
    ReportGnssAndAttitude(&s);
  });
  ReportProgress(options.progress, 0.9, "check points");
  timed("check points", [&] {
    EvaluateGroundPoints(&s);
    TestDome(&s);
  });
  timed("statistics", [&] {
    ReportCameras(&s);
    ReportVarianceComponents(&s);
    SnoopTargetMarks(&s);
    ApplyQualityGates(*s.model, options.gates, &s.report);
  });
  timed("leave-one-out", [&] { LeaveControlOut(&s); });
  ReportProgress(options.progress, 1.0, "georeferenced");
  return std::move(s.report);
}

}  // namespace aerotri
