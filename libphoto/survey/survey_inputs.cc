// SPDX-License-Identifier: BSD-3-Clause
// The survey's first phases: inputs checked, frame and datum chosen, priors
// attached (survey_phases.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "libphoto/base/error.h"
#include "libphoto/survey/survey_phases.h"

namespace aerotri {
namespace {

constexpr double kNoHeightSigmaM = 1e4;  // the vertical prior of a control point in plan only

// A local engineering frame: every CRS given must be one, in one unit, and
// the camera positions too; the frame is re-centred on the control's mean
// (its stand-in stays small) and the camera positions placed on it.
void PlaceLocalFrame(SurveyState* s) {
  const std::pair<const char*, std::optional<Crs>*> all[] = {
      {"the control file's", &s->control_crs}, {"the check file's", &s->check_crs}, {"--crs", &s->requested_crs}};
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
  for (const auto& [name, fix] : s->gps) {
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
  for (const GcpFile* file : {s->control, s->checks}) {
    if (!file || (file == s->checks && n > 0)) continue;
    for (const GroundPoint& point : file->points) {
      if (point.horizontal_only) continue;
      mean += point.xyz;
      ++n;
    }
  }
  if (n > 0) mean /= n;
  s->report.local_origin = mean;
  for (const auto& [what, crs] : all) {
    if (*crs) *crs = (*crs)->LocalAt(mean);
  }
  // Camera positions on the same stand-in as the control.
  const Crs& frame_crs = s->control_crs ? *s->control_crs : s->check_crs ? *s->check_crs : *s->requested_crs;
  for (auto& [name, fix] : s->gps) fix.position = frame_crs.ToGeodetic(*fix.local_xyz);
}

// Control whose heights are all exactly zero, three points or more: a
// file's way of saying "unknown" (OpenDroneMap's documentation suggests it,
// and hand-held GNSS lists do it). Fitted to that plane the block would tilt
// and sink to it; the points are used in plan only instead, and said.
void TakeZeroHeightsAsUnknown(SurveyState* s) {
  if (!s->control || s->Options().zero_heights_are_heights) return;
  int with_height = 0;
  for (const GroundPoint& p : s->control->points) {
    if (p.horizontal_only) continue;
    if (p.xyz.z() != 0.0) return;
    ++with_height;
  }
  if (with_height < 3) return;
  s->control_in_plan = *s->control;
  for (GroundPoint& p : s->control_in_plan->points) {
    p.horizontal_only = true;
    p.xyz.z() = std::numeric_limits<double>::quiet_NaN();
  }
  s->control = &*s->control_in_plan;
  s->report.findings.push_back(Finding::Warning(
      "CONTROL_HEIGHTS_ZERO",
      "all " + std::to_string(with_height) + " control points of " + s->control->path +
          " have a height of exactly 0, which files use for an unknown height: they are used in plan only, their "
          "heights left to the adjustment (the vertical datum comes from the GPS); if 0 is their surveyed height, "
          "say so with --zero-heights-are-heights"));
}

// The control and check points in WGS84. A point without a surveyed height
// is converted at the median height of the file's others (the horizontal
// position barely depends on it).
void ReadSurveyedPoints(SurveyState* s) {
  for (const GcpFile* file : {s->control, s->checks}) {
    if (!file) continue;
    const Crs& crs = file == s->control ? *s->control_crs : *s->check_crs;
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
      SurveyedPoint p;
      p.source = &point;
      Eigen::Vector3d xyz = point.xyz;
      if (point.horizontal_only) xyz.z() = fill_z;
      p.geodetic = crs.ToGeodetic(xyz);
      p.role = file == s->control ? PointRole::kControl : PointRole::kCheck;
      if (point.horizontal_only && p.role == PointRole::kCheck) {
        p.excluded = "no surveyed height ('nan'): a check point needs all three coordinates";
      }
      s->surveyed.push_back(p);
    }
  }
}

// ENU origin: the caller's, else the mean GPS of the model's images, else
// the mean control point; a local frame adjusts on its stand-in's own
// tangent plane (exactly the file's Cartesian coordinates).
void ChooseEnuOrigin(SurveyState* s) {
  const SparseModel& model = *s->model;
  double lat = 0, lon = 0, h = 0;
  int n = 0;
  for (const auto& [name, fix] : s->gps) {
    const auto it = s->image_by_name.find(name);
    if (it == s->image_by_name.end() || !model.images[it->second].registered) continue;
    lat += fix.position.lat_deg;
    lon += fix.position.lon_deg;
    h += fix.position.h_m;
    ++n;
  }
  if (n == 0) {
    for (const SurveyedPoint& p : s->surveyed) {
      if (p.role != PointRole::kControl) continue;
      lat += p.geodetic.lat_deg;
      lon += p.geodetic.lon_deg;
      h += p.geodetic.h_m;
      ++n;
    }
  }
  if (n == 0) {
    throw InvalidArgument("nothing to georeference with: no GPS position for any image of "
                          "the model and no control points (give --gcp, or images with "
                          "EXIF GPS, or --gps-csv)");
  }
  GeoreferenceReport& report = s->report;
  report.enu_origin = s->Options().enu_origin ? *s->Options().enu_origin : Geodetic{lat / n, lon / n, h / n};
  if (s->local) report.enu_origin = Crs::LocalGeodeticOrigin();
  s->frame.emplace(report.enu_origin);
}

// The output CRS: --crs, else the control file's, else the UTM zone of the
// survey's centre; with the axes its residuals are given on.
void ChooseOutputCrs(SurveyState* s) {
  GeoreferenceReport& report = s->report;
  if (s->requested_crs) {
    s->out_crs = s->requested_crs;
    report.crs_source = "--crs";
  } else if (s->control_crs) {
    s->out_crs = s->control_crs;
    report.crs_source = "control file";
  } else {
    s->out_crs = Crs::UtmFor(report.enu_origin);
    report.crs_source = "UTM zone of the survey centre";
  }
  const Crs& out = *s->out_crs;
  report.crs = out.definition();
  report.crs_name = out.Name();
  report.residuals_in_crs_units = !out.IsGeographic() && !out.IsGeocentric();
  report.axes = out.IsLocal()        ? "x, y, z of the local engineering frame (its unit)"
                : out.IsGeographic() ? "local east, north, up (metres; the CRS is geographic)"
                : out.IsGeocentric() ? "local east, north, up (metres): the CRS is geocentric, whose X, Y, Z "
                                       "have no horizontal or vertical meaning"
                                     : "easting, northing, height of the CRS (its unit)";
  report.output_crs = s->out_crs;
}

void AttachGpsPriors(SurveyState* s) {
  for (Image& image : s->model->images) image.gps_prior.reset();
  for (const auto& [name, fix] : s->gps) {
    const auto it = s->image_by_name.find(name);
    if (it == s->image_by_name.end()) continue;
    Image& image = s->model->images[it->second];
    PositionPrior prior;
    prior.position = s->Frame().EnuFromGeodetic(fix.position);
    prior.sigma_h_m = fix.sigma_h_m;
    prior.sigma_v_m = fix.sigma_v_m;
    image.gps_prior = prior;
    ++s->num_gps;
  }
}

// Surveyed points that cannot belong to the survey: horizontally farther
// from every GPS camera position than the photos can see (three flying
// heights) plus five GPS sigmas and 50 m. A control file in another zone,
// hemisphere or CRS, or with its axes swapped or negated, ends here; its
// points must not pull the block. The flying height is taken from geodetic
// heights (cameras' GPS against the surveyed points'), which a point
// thousands of kilometres off leaves as they are, where its height in the
// survey's tangent plane would sink by the earth's curvature and widen the
// limit until it let the point in.
struct OutsideTest {
  std::vector<Eigen::Vector3d> cameras;  // ENU
  double limit_m = 0.0;
  bool usable = false;
  // Horizontal distance to the nearest camera position.
  double Nearest(const Eigen::Vector3d& enu) const {
    double nearest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& c : cameras) nearest = std::min(nearest, (enu - c).head<2>().norm());
    return nearest;
  }
};

double MedianOf(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

OutsideTest MakeOutsideTest(const SurveyState& s) {
  OutsideTest t;
  std::vector<double> sigmas, heights;
  for (const Image& image : s.model->images) {
    if (!image.registered || !image.gps_prior) continue;
    t.cameras.push_back(image.gps_prior->position);
    sigmas.push_back(image.gps_prior->sigma_h_m);
    heights.push_back(s.gps.at(image.name).position.h_m);
  }
  if (t.cameras.size() < 3 || s.local) return t;
  std::vector<double> ground;
  for (const SurveyedPoint& p : s.surveyed) {
    if (!p.source->horizontal_only) ground.push_back(p.geodetic.h_m);
  }
  const double flying = ground.empty() ? 0.0 : std::abs(MedianOf(heights) - MedianOf(ground));
  t.limit_m = 3.0 * flying + 5.0 * MedianOf(sigmas) + 50.0;
  t.usable = true;
  return t;
}

// What would put every far point inside the survey: its first two
// coordinates swapped, or one or both of them negated; "" when none does.
std::string AxisDiagnosis(const SurveyState& s, const OutsideTest& test, const std::vector<const SurveyedPoint*>& far) {
  struct Reading {
    const char* what;
    double sx, sy;
    bool swap;
  };
  const Reading readings[] = {{"the first two columns swapped", 1, 1, true},
                              {"the first column negated", -1, 1, false},
                              {"the second column negated", 1, -1, false},
                              {"both columns negated", -1, -1, false},
                              {"the columns swapped and the first negated", -1, 1, true},
                              {"the columns swapped and the second negated", 1, -1, true}};
  for (const Reading& r : readings) {
    bool all_inside = true;
    for (const SurveyedPoint* p : far) {
      const Crs& crs = p->role == PointRole::kControl ? *s.control_crs : *s.check_crs;
      Eigen::Vector3d xyz = p->source->xyz;
      if (p->source->horizontal_only) xyz.z() = p->geodetic.h_m;
      if (r.swap) std::swap(xyz.x(), xyz.y());
      xyz.x() *= r.sx;
      xyz.y() *= r.sy;
      try {
        all_inside = all_inside && test.Nearest(s.Frame().EnuFromGeodetic(crs.ToGeodetic(xyz))) <= test.limit_m;
      } catch (const Error&) {
        all_inside = false;  // not a position at all read so
      }
      if (!all_inside) break;
    }
    if (!all_inside) continue;
    const Crs& crs = far.front()->role == PointRole::kControl ? *s.control_crs : *s.check_crs;
    return std::string(" Read with ") + r.what + ", every one of them lies inside the survey: the file's axes are " +
           (r.swap ? "swapped" : "negated") +
           (crs.IsGeographic() ? " (a geographic CRS's coordinates are longitude, latitude in aerotri's files, the "
                                 "normalised axis order; west and south negative)"
                               : " (easting first, then northing)") +
           ".";
  }
  return "";
}

void ExcludeControlOutsideSurvey(SurveyState* s) {
  const OutsideTest test = MakeOutsideTest(*s);
  if (!test.usable) return;
  std::vector<std::string> far;
  std::vector<const SurveyedPoint*> far_points;
  for (SurveyedPoint& p : s->surveyed) {
    const double nearest = test.Nearest(s->Frame().EnuFromGeodetic(p.geodetic));
    if (nearest <= test.limit_m) continue;
    char text[160];
    std::snprintf(text, sizeof text, "%.0f m from the nearest GPS camera position (the photos see %.0f m)",
                  nearest, test.limit_m);
    p.excluded = std::string("outside the survey: ") + text;
    far.push_back(p.source->name);
    far_points.push_back(&p);
  }
  if (far.empty()) return;
  const std::string diagnosis = AxisDiagnosis(*s, test, far_points);
  s->report.findings.push_back(Finding::Error(
      "CONTROL_OUTSIDE_SURVEY",
      std::to_string(far.size()) + " surveyed points lie outside the photographed area (farther from every GPS "
      "camera position than three flying heights and five GPS sigmas): " + JoinNames(far) + "; left out." +
          (diagnosis.empty() ? " A wrong CRS line, zone or hemisphere, swapped or negated axes, or another site's file?"
                             : diagnosis),
      far));
}

// The prior of a surveyed point in the adjustment frame: its file's sigmas
// (per axis turned onto the frame's, Σ = J⁻¹ D J⁻ᵀ), or the defaults; a
// point in plan only holds no height.
PositionPrior SurveyedPrior(const SurveyState& s, const SurveyedPoint& p) {
  const GeoreferenceOptions& options = s.Options();
  PositionPrior prior;
  prior.position = s.Frame().EnuFromGeodetic(p.geodetic);
  prior.sigma_h_m = p.source->sigma_h_m.value_or(options.gcp_sigma_h_m);
  prior.sigma_v_m = p.source->sigma_v_m.value_or(options.gcp_sigma_v_m);
  if (p.source->sigma_xyz_m) {
    const Crs& crs = p.role == PointRole::kControl ? *s.control_crs : *s.check_crs;
    const Eigen::Matrix3d j_inv = CrsFromEnuJacobian(s.Frame(), crs, prior.position).inverse();
    const Eigen::Vector3d& sigma = *p.source->sigma_xyz_m;
    prior.covariance = j_inv * sigma.cwiseAbs2().asDiagonal() * j_inv.transpose();
    prior.sigma_h_m = std::max(sigma.x(), sigma.y());
    prior.sigma_v_m = sigma.z();
  }
  if (p.source->horizontal_only) {
    prior.sigma_v_m = kNoHeightSigmaM;
    prior.covariance.reset();
  }
  return prior;
}

// A surveyed point's marks as observations of the model; marks on images
// outside the model or outside the photo are skipped with a warning.
void AddMarks(SurveyState* s, const SurveyedPoint& p) {
  SparseModel* model = s->model;
  const std::string& path = p.role == PointRole::kControl ? s->control->path : s->checks->path;
  for (const GcpMeasurement& m : p.source->measurements) {
    if (!p.excluded.empty()) break;
    const auto it = s->image_by_name.find(m.image);
    if (it == s->image_by_name.end()) {
      s->report.findings.push_back(Finding::Warning(
          "INPUT", path + ":" + std::to_string(m.line) + ": image '" + m.image + "' is not in the model; "
                   "measurement skipped",
          {p.source->name}));
      continue;
    }
    const Camera& camera = model->cameras[model->images[it->second].camera];
    if (!(m.xy_px.x() >= -0.5 && m.xy_px.y() >= -0.5 && m.xy_px.x() <= camera.width - 0.5 &&
          m.xy_px.y() <= camera.height - 0.5)) {
      char text[200];
      std::snprintf(text, sizeof text, ": mark (%.1f, %.1f) px is outside image '%s' (%d x %d px); measurement "
                    "skipped", m.xy_px.x(), m.xy_px.y(), m.image.c_str(), camera.width, camera.height);
      s->report.findings.push_back(
          Finding::Warning("INPUT", path + ":" + std::to_string(m.line) + text, {p.source->name}));
      continue;
    }
    Observation obs;
    obs.image = it->second;
    obs.point = p.point_index;
    obs.xy = m.xy_px;
    obs.sigma_px = m.sigma_px.value_or(0.0);
    model->observations.push_back(obs);
  }
}

// Control and check points appended to the model with their observations.
void AddSurveyedPoints(SurveyState* s) {
  for (SurveyedPoint& p : s->surveyed) {
    Point point;
    point.id = static_cast<int>(s->model->points.size()) + 1000000;
    point.name = p.source->name;
    point.role = p.role;
    point.color = p.role == PointRole::kControl ? std::array<std::uint8_t, 3>{255, 0, 0}
                                                : std::array<std::uint8_t, 3>{0, 0, 255};
    point.prior = SurveyedPrior(*s, p);
    p.point_index = static_cast<int>(s->model->points.size());
    s->model->points.push_back(point);
    AddMarks(s, p);
  }
}

}  // namespace

SurveyState StartSurvey(SparseModel* model, const std::map<std::string, GpsFix>& gps, const GcpFile* control,
                        const GcpFile* checks, const GeoreferenceOptions& options) {
  AEROTRI_CHECK(model != nullptr);
  SurveyState s;
  s.model = model;
  s.gps = gps;
  s.control = control;
  s.checks = checks;
  s.options = &options;
  model->Validate();
  s.report.initial_cameras = model->cameras;
  if (options.leave_one_out) s.start = *model;
  return s;
}

std::optional<Finding> CheckDuplicatedMarks(const GcpFile* control, const GcpFile* checks) {
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
  if (items.empty()) return std::nullopt;
  std::string text;
  for (size_t k = 0; k < items.size() && k < 5; ++k) text += (k ? "; " : "") + items[k] + " (" + lines[k] + ")";
  return Finding::Warning(
      "MARK_DUPLICATED",
      std::to_string(items.size()) + " target mark(s) labelled as two different points in one photo, within "
      "2 px of each other: " + text + (items.size() > 5 ? "; ..." : "") +
          "; one label is wrong (the w-test names the mark that fits worse)",
      items);
}

void ChooseFrameAndDatum(SurveyState* s) {
  TakeZeroHeightsAsUnknown(s);
  if (s->control) s->control_crs = Crs::FromString(s->control->crs);
  if (s->checks) s->check_crs = Crs::FromString(s->checks->crs);
  if (!s->Options().output_crs.empty()) s->requested_crs = Crs::FromString(s->Options().output_crs);
  s->local = (s->control_crs && s->control_crs->IsLocal()) || (s->check_crs && s->check_crs->IsLocal()) ||
             (s->requested_crs && s->requested_crs->IsLocal());
  if (s->local) {
    PlaceLocalFrame(s);
  } else {
    for (const auto& [name, fix] : s->gps) {
      if (fix.local_xyz) {
        throw InvalidArgument("the camera position of " + name +
                              " is in a local engineering frame and the control is not: a local frame has no "
                              "transformation to a geodetic CRS; give both in one frame");
      }
    }
  }
  ReadSurveyedPoints(s);
  for (size_t i = 0; i < s->model->images.size(); ++i) {
    s->image_by_name[s->model->images[i].name] = static_cast<int>(i);
  }
  ChooseEnuOrigin(s);
  ChooseOutputCrs(s);
}

// Each rolling-shutter photo's motion (ENU, the adjustment frame), and per
// camera group what is modelled, for the report.
std::map<std::string, Eigen::Vector3d> VelocitiesFromTrack(std::vector<TrackFix> fixes, double max_gap_s) {
  std::sort(fixes.begin(), fixes.end(), [](const TrackFix& a, const TrackFix& b) { return a.time_s < b.time_s; });
  std::map<std::string, Eigen::Vector3d> out;
  const int n = static_cast<int>(fixes.size());
  auto one_sided = [&](int from, int to) -> std::optional<Eigen::Vector3d> {
    if (to < 0 || to >= n) return std::nullopt;
    const double dt = fixes[to].time_s - fixes[from].time_s;
    if (!(std::abs(dt) > 1e-3 && std::abs(dt) <= max_gap_s)) return std::nullopt;
    return Eigen::Vector3d((fixes[to].position - fixes[from].position) / dt);
  };
  for (int k = 0; k < n; ++k) {
    const auto before = one_sided(k, k - 1), after = one_sided(k, k + 1);
    if (before && after) {
      const double sb = before->norm(), sa = after->norm();
      const bool agree = sb > 0.0 && sa > 0.0 && before->dot(*after) / (sb * sa) > std::cos(20.0 * M_PI / 180.0) &&
                         std::abs(sb - sa) <= 0.25 * std::max(sb, sa);
      if (agree) {
        out[fixes[k].name] =
            (fixes[k + 1].position - fixes[k - 1].position) / (fixes[k + 1].time_s - fixes[k - 1].time_s);
      }
    } else if (before || after) {
      out[fixes[k].name] = before ? *before : *after;
    }
  }
  return out;
}

// The largest time between photos whose positions give a velocity: a
// drone's strip is straight and steady for longer, and a turn between the
// two is caught by the one-sided velocities' disagreement.
constexpr double kTrackMaxGapS = 10.0;

// Photos that state no motion, when the readout is estimated: their
// velocity from the GPS track (photos at most 10 s apart), by name.
std::map<std::string, Eigen::Vector3d> TrackVelocities(const SurveyState& s) {
  std::vector<TrackFix> fixes;
  for (const Image& image : s.model->images) {
    const auto it = s.gps.find(image.name);
    if (!image.gps_prior || it == s.gps.end() || !std::isfinite(it->second.time_s)) continue;
    fixes.push_back({image.name, image.gps_prior->position, it->second.time_s});
  }
  return VelocitiesFromTrack(fixes, kTrackMaxGapS);
}

void AttachRollingShutters(SurveyState* s) {
  const GeoreferenceOptions& o = s->Options();
  // With the readout estimated, photos that state no motion move as their
  // GPS track does.
  std::map<std::string, Eigen::Vector3d> track;
  if (o.estimate_readout && o.model_rolling_shutter && !s->local) track = TrackVelocities(*s);
  std::vector<int> from_track(s->model->cameras.size(), 0);
  std::vector<GeoreferenceReport::Shutter> shutters(s->model->cameras.size());
  std::vector<std::vector<double>> readouts(shutters.size());
  for (size_t c = 0; c < shutters.size(); ++c) shutters[c].camera = s->model->cameras[c].id;
  for (Image& image : s->model->images) {
    image.rolling_shutter.reset();
    auto it = o.rolling_shutter.find(image.name);
    if (it == o.rolling_shutter.end() && image.registered && track.count(image.name)) {
      image.rolling_shutter = RollingShutterMotion{0.0, track.at(image.name)};
      GeoreferenceReport::Shutter& group = shutters[image.camera];
      ++group.images;
      ++from_track[image.camera];
      group.mean_speed_mps += image.rolling_shutter->velocity.norm();
      continue;
    }
    if (s->local || !o.model_rolling_shutter || it == o.rolling_shutter.end() || !image.registered ||
        (it->second.readout_time_s <= 0.0 && !o.estimate_readout) || it->second.velocity.isZero()) {
      continue;
    }
    image.rolling_shutter = it->second;
    GeoreferenceReport::Shutter& group = shutters[image.camera];
    ++group.images;
    group.mean_speed_mps += it->second.velocity.norm();
    readouts[image.camera].push_back(it->second.readout_time_s);
  }
  for (size_t c = 0; c < shutters.size(); ++c) {
    GeoreferenceReport::Shutter& group = shutters[c];
    if (group.images > 0) {
      std::vector<double>& r = readouts[c];
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      group.model = "rolling";
      group.readout_time_s = r.empty() ? 0.0 : r[r.size() / 2];
      group.readout_stated_s = group.readout_time_s;
      group.mean_speed_mps /= group.images;
      group.source = o.rolling_shutter_source;
      if (from_track[c] > 0) {
        group.source = (group.source.empty() ? std::string() : group.source + "; ") + std::to_string(from_track[c]) +
                       " photos' velocities from their GPS track (photos at most 10 s apart)";
      }
      group.readout_estimated = o.estimate_readout;
    } else {
      group.source = o.estimate_readout && o.model_rolling_shutter && !s->local
                         ? "assumed: no photo of the group states its velocity, and no GPS track with capture times "
                           "(photos at most 10 s apart) gives one"
                     : o.rolling_shutter.empty() ? "assumed: no photo states a readout time and its velocity"
                     : !o.model_rolling_shutter ? "the photos state a rolling shutter; not modelled (--rolling-shutter off)"
                     : s->local                 ? "the photos state a rolling shutter; not modelled in a LOCAL frame"
                                                : "assumed: no photo of the group states a readout time and its velocity";
    }
  }
  s->report.shutters = shutters;
}

void AttachPriors(SurveyState* s) {
  AttachGpsPriors(s);
  AttachRollingShutters(s);
  ExcludeControlOutsideSurvey(s);
  AddSurveyedPoints(s);
}

}  // namespace aerotri
