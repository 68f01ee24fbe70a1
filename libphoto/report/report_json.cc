// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/report/report_json.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace aerotri {
namespace {

nlohmann::json PointsJson(const std::vector<GroundPointResult>& points, const AccuracyStats& s,
                          bool crs_units) {
  nlohmann::json j;
  j["count"] = s.count;
  j["rmse_x_m"] = s.rmse_x_m;
  j["rmse_y_m"] = s.rmse_y_m;
  j["rmse_z_m"] = s.rmse_z_m;
  j["rmse_h_m"] = s.rmse_h_m;
  j["rmse_3d_m"] = s.rmse_3d_m;
  j["mean_x_m"] = s.mean_x_m;
  j["mean_y_m"] = s.mean_y_m;
  j["mean_z_m"] = s.mean_z_m;
  j["max_h_m"] = s.max_h_m;
  j["max_abs_z_m"] = s.max_abs_z_m;
  j["residuals_frame"] = crs_units ? "output CRS (adjusted - surveyed)"
                                   : "local ENU metres (adjusted - surveyed); the CRS is geographic or geocentric";
  j["points"] = nlohmann::json::array();
  for (const GroundPointResult& p : points) {
    nlohmann::json pj;
    pj["name"] = p.name;
    pj["images"] = p.num_images;
    pj["solved"] = p.solved;
    if (p.horizontal_only) pj["horizontal_only"] = true;  // dz_m and the surveyed height are null
    if (p.solved) {
      pj["dx_m"] = p.d_m.x();
      pj["dy_m"] = p.d_m.y();
      pj["dz_m"] = p.d_m.z();
      pj["reprojection_rms_px"] = p.reprojection_rms_px;
      pj["surveyed"] = {p.surveyed_crs.x(), p.surveyed_crs.y(), p.surveyed_crs.z()};
      pj["adjusted"] = {p.adjusted_crs.x(), p.adjusted_crs.y(), p.adjusted_crs.z()};
      if (p.has_precision) {
        pj["sigma_x_m"] = p.sigma_m.x();
        pj["sigma_y_m"] = p.sigma_m.y();
        pj["sigma_z_m"] = p.sigma_m.z();
      }
      if (p.tested) {
        pj["predicted_sigma_m"] = {p.predicted_sigma_m.x(), p.predicted_sigma_m.y(), p.predicted_sigma_m.z()};
        pj["w"] = {p.w.x(), p.w.y(), p.w.z()};
        pj["rejected"] = p.rejected;
      }
    } else {
      pj["why_not"] = p.why_not;
    }
    j["points"].push_back(pj);
  }
  return j;
}

// The lens distortion along the image diagonal: for radii from the
// principal point to the farthest corner, the radial and tangential
// displacement (px) of a distorted point from its ideal pinhole position.
nlohmann::json DistortionCurve(const Camera& camera) {
  nlohmann::json curve = {{"note", "displacement of the distorted image point from the ideal pinhole point along "
                                   "the diagonal from the principal point to the farthest corner (px)"},
                          {"radius_px", nlohmann::json::array()},
                          {"radial_px", nlohmann::json::array()},
                          {"tangential_px", nlohmann::json::array()}};
  const double f = camera.focal_px();
  const Eigen::Vector2d pp = camera.principal_point_px();
  if (!(f > 0.0) || camera.width <= 0 || camera.height <= 0) return curve;
  Eigen::Vector2d corner(0.0, 0.0);
  for (const Eigen::Vector2d& c : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(camera.width - 0.5, -0.5),
                                  Eigen::Vector2d(-0.5, camera.height - 0.5),
                                  Eigen::Vector2d(camera.width - 0.5, camera.height - 0.5)}) {
    if ((c - pp).norm() > corner.norm()) corner = c - pp;
  }
  const Eigen::Vector2d dir = corner.normalized();
  const Eigen::Vector2d across(-dir.y(), dir.x());
  const int steps = 24;
  for (int k = 0; k <= steps; ++k) {
    const double radius = corner.norm() * k / steps;
    const Eigen::Vector2d ideal = pp + radius * dir;
    const Eigen::Vector2d shift = camera.ImageFromNormalized(radius / f * dir) - ideal;
    curve["radius_px"].push_back(radius);
    curve["radial_px"].push_back(shift.dot(dir));
    curve["tangential_px"].push_back(shift.dot(across));
  }
  return curve;
}

// Tie points by track length (the number of images measuring them).
nlohmann::json TrackStatistics(const SparseModel& model) {
  const std::vector<int> per_point = model.ObservationsPerPoint();
  std::vector<int> lengths;
  for (size_t p = 0; p < model.points.size(); ++p) {
    if (model.points[p].role == PointRole::kTie && per_point[p] >= 2) lengths.push_back(per_point[p]);
  }
  nlohmann::json j = {{"tie_points", lengths.size()}};
  if (lengths.empty()) return j;
  std::sort(lengths.begin(), lengths.end());
  double sum = 0.0;
  for (int n : lengths) sum += n;
  j["mean_length"] = sum / lengths.size();
  j["median_length"] = lengths[lengths.size() / 2];
  j["max_length"] = lengths.back();
  nlohmann::json histogram = nlohmann::json::object();
  for (int n : lengths) {
    const std::string key = n >= 10 ? "10+" : std::to_string(n);
    histogram[key] = histogram.value(key, 0) + 1;
  }
  j["by_length"] = histogram;
  return j;
}

}  // namespace

nlohmann::json BundleSummaryJson(const BundleSummary& s, const SparseModel& model) {
  nlohmann::json j;
  j["images"] = s.num_images;
  j["points"] = s.num_points;
  j["observations"] = s.num_observations;
  j["gps_priors"] = s.num_gps_priors;
  j["gcp_priors"] = s.num_gcp_priors;
  j["initial_cost"] = s.initial_cost;
  j["final_cost"] = s.final_cost;
  j["initial_rms_px"] = s.initial_rms_px;
  j["final_rms_px"] = s.final_rms_px;
  j["iterations"] = s.iterations;
  j["termination"] = s.termination;
  nlohmann::json solves = nlohmann::json::array();
  for (const BundleSummary::Solve& solve : s.solves) {
    solves.push_back({{"kind", solve.kind},
                      {"iterations", solve.iterations},
                      {"initial_cost", solve.initial_cost},
                      {"final_cost", solve.final_cost},
                      {"time_s", solve.time_s},
                      {"termination", solve.termination}});
  }
  j["solves"] = solves;
  j["converged"] = s.converged;
  j["linear_solver"] = s.linear_solver;
  // The stochastic model's check: r sigma0^2 follows chi^2(r) when the stated
  // sigmas hold; z is its normal approximation.
  // With variance components estimated, the test is of the stated sigmas
  // (the first solve's sigma0), and sigma0 is that of the final weights.
  j["sigma0"] = s.sigma0;
  j["redundancy"] = s.redundancy;
  const bool reweighted = s.variance_component_iterations > 0;
  const double s0 = reweighted ? s.sigma0_stated : s.sigma0;
  const int r = reweighted ? s.redundancy_stated : s.redundancy;
  const double z = r > 0 ? (s0 * s0 - 1.0) * std::sqrt(r / 2.0) : 0.0;
  j["chi2_test"] = {{"z", z},
                    {"sigma0", s0},
                    {"consistent", std::abs(z) < 3.0},
                    {"note", "r sigma0^2 ~ chi^2(r) under the stated sigmas; |z| >= 3: the sigmas (image, GPS, "
                             "control) do not describe the data (sigma0 < 1: pessimistic, > 1: optimistic)"}};
  if (!s.variance_components.empty()) {
    nlohmann::json vc;
    vc["estimated"] = std::any_of(s.variance_components.begin(), s.variance_components.end(),
                                  [](const VarianceComponent& c) { return c.estimated; });
    vc["iterations"] = s.variance_component_iterations;
    vc["sigma0_stated"] = s.sigma0_stated;
    vc["note"] = "per observation group: sigma0 = sqrt(v'Pv / r_g), r_g the group's share of the redundancy "
                 "(Foerstner); estimated_sigma = stated_sigma * scale * sigma0 is what the data show. Estimated: "
                 "each group weighed by its own estimate (scale) and the block solved again until every sigma0 "
                 "is 1, so the posterior sigmas are honest; held_as_stated: a group whose every sigma the survey's "
                 "files state, kept at them; stated: the stated sigmas kept and every covariance "
                 "scaled by the one sigma0^2";
    nlohmann::json groups = nlohmann::json::array();
    for (const VarianceComponent& c : s.variance_components) {
      const bool px = c.group == ObservationGroup::kTies || c.group == ObservationGroup::kMarks;
      groups.push_back({{"group", ToString(c.group)},
                        {"unit", px ? "px" : "m"},
                        {"rows", c.rows},
                        {"redundancy", c.redundancy},
                        {"stated_sigma", c.stated_sigma},
                        {"sigma0", std::isfinite(c.sigma0) ? nlohmann::json(c.sigma0) : nlohmann::json(nullptr)},
                        {"scale", c.scale},
                        {"estimated_sigma", std::isfinite(c.sigma0) ? nlohmann::json(c.EstimatedSigma())
                                                                    : nlohmann::json(nullptr)},
                        {"estimated", c.estimated},
                        {"held_as_stated", c.held}});
    }
    vc["groups"] = groups;
    j["variance_components"] = vc;
  }
  j["datum"] = s.gauge;
  j["outliers_removed"] = s.outliers_removed;
  j["observations_behind_camera"] = s.num_behind_camera_final;
  j["weak_points_narrow_rays"] = s.weak_points_small_angle;
  j["weak_images"] = nlohmann::json::array();
  for (const WeakImage& w : s.weak_images) {
    j["weak_images"].push_back({{"name", w.name}, {"observations", w.observations}});
  }
  j["time_s"] = s.total_time_s;
  j["refined_intrinsics"] = s.refined_intrinsics;
  j["intrinsics"] = nlohmann::json::array();
  for (const Camera& camera : model.cameras) {
    nlohmann::json c;
    c["camera"] = camera.id;
    c["model"] = camera.info().name;
    c["width"] = camera.width;
    c["height"] = camera.height;
    nlohmann::json params;
    for (int i = 0; i < camera.info().num_params(); ++i) {
      params[camera.info().param_names[i]] = camera.params[i];
    }
    c["params"] = params;
    c["pixel_convention"] = "cx, cy with (0, 0) at the centre of the top-left pixel (OpenCV, OpenSfM); COLMAP's "
                            "cameras.txt puts that centre at (0.5, 0.5), so its cx, cy are these plus 0.5";
    c["distortion_curve"] = DistortionCurve(camera);
    j["intrinsics"].push_back(c);
  }
  j["tracks"] = TrackStatistics(model);
  return j;
}

void AddIntrinsicsInMm(nlohmann::json* adjustment, const std::vector<double>& pixel_size_mm,
                       const std::string& pixel_size_source) {
  if (!adjustment->contains("intrinsics")) return;
  for (nlohmann::json& c : (*adjustment)["intrinsics"]) {
    const int id = c.value("camera", 0);
    if (id < 1 || id > static_cast<int>(pixel_size_mm.size()) || !(pixel_size_mm[id - 1] > 0)) continue;
    const nlohmann::json& p = c.at("params");
    if (!p.contains("f") || !p.contains("cx") || !p.contains("cy")) continue;
    const double pitch = pixel_size_mm[id - 1];
    const double w = c.value("width", 0), h = c.value("height", 0);
    nlohmann::json mm = {
        {"pixel_size_mm", pitch},
        {"pixel_size_source", pixel_size_source},
        {"c_mm", p["f"].get<double>() * pitch},
        {"x0_mm", (p["cx"].get<double>() - 0.5 * (w - 1)) * pitch},
        {"y0_mm", -(p["cy"].get<double>() - 0.5 * (h - 1)) * pitch},
        {"convention", "c: camera constant; x0, y0: principal point from the image centre, x right, y up the "
                       "image; distortion coefficients as in params (unit-free)"}};
    for (const nlohmann::json& q : adjustment->value("intrinsics_precision", nlohmann::json::array())) {
      if (q.value("camera", 0) != id || !q.contains("sigma")) continue;
      const nlohmann::json& s = q["sigma"];
      if (s.contains("f")) mm["sigma_c_mm"] = s["f"].get<double>() * pitch;
      if (s.contains("cx")) mm["sigma_x0_mm"] = s["cx"].get<double>() * pitch;
      if (s.contains("cy")) mm["sigma_y0_mm"] = s["cy"].get<double>() * pitch;
    }
    c["mm"] = mm;
  }
}

std::string ExteriorOrientationCsv(const GeoreferenceReport& r) {
  std::ostringstream out;
  out << "# exterior orientation, aerotri\n"
      << "# crs: " << r.crs << " (" << r.crs_name << ")\n"
      << "# x, y, z: camera centre in that CRS" << (r.residuals_in_crs_units ? "" : " (lon, lat, ellipsoidal h)")
      << "\n"
      << "# omega, phi, kappa (deg): R = Rx(omega) Ry(phi) Rz(kappa) turns the photo frame (x right, y up the "
         "image, z out of the lens towards the viewer) into the grid axes (easting, northing, up); a nadir "
         "photo with its top to the north has 0, 0, 0\n"
      << "# sigma_*: posterior standard deviations (a-priori covariance times sigma0^2 = "
      << r.bundle.precision.variance_factor << "); empty when not computed\n";
  out << "name,x,y,z,omega_deg,phi_deg,kappa_deg,sigma_x_m,sigma_y_m,sigma_z_m,sigma_omega_deg,sigma_phi_deg,"
         "sigma_kappa_deg\n";
  out << std::setprecision(12);
  for (const CameraResult& c : r.cameras) {
    out << c.name << "," << c.position_crs.x() << "," << c.position_crs.y() << "," << c.position_crs.z()
        << std::setprecision(9) << "," << c.opk_deg.x() << "," << c.opk_deg.y() << "," << c.opk_deg.z();
    if (c.has_precision) {
      out << std::setprecision(4);
      for (int k = 0; k < 3; ++k) out << "," << c.sigma_position_m[k];
      for (int k = 0; k < 3; ++k) out << "," << c.sigma_opk_deg[k];
    } else {
      out << ",,,,,,";
    }
    out << std::setprecision(12) << "\n";
  }
  return out.str();
}

nlohmann::json FindingsJson(const std::vector<Finding>& findings, Severity severity) {
  nlohmann::json out = nlohmann::json::array();
  for (const Finding& f : findings) {
    if (f.severity != severity) continue;
    out.push_back({{"code", f.code}, {"message", f.message}, {"items", f.items}});
  }
  return out;
}

namespace {

nlohmann::json Enu(const Eigen::Vector3d& v) { return nlohmann::json{{"e_m", v.x()}, {"n_m", v.y()}, {"u_m", v.z()}}; }

// Every registered camera: its GPS residual, position, angles and sigmas.
nlohmann::json CamerasJson(const GeoreferenceReport& r) {
  nlohmann::json j;
  j = nlohmann::json::array();
  for (const CameraResult& c : r.cameras) {
    nlohmann::json cj;
    cj["name"] = c.name;
    cj["gps_prior"] = c.has_prior;
    if (c.has_prior) {
      cj["gps_prior_rejected"] = c.prior_rejected;
      cj["de_m"] = c.d_enu_m.x();
      cj["dn_m"] = c.d_enu_m.y();
      cj["du_m"] = c.d_enu_m.z();
      cj["sigma_h_m"] = c.sigma_h_m;
      cj["sigma_v_m"] = c.sigma_v_m;
    }
    cj["position"] = {c.position_crs.x(), c.position_crs.y(), c.position_crs.z()};
    cj["x"] = c.position_crs.x();  // the same, by name (the report's map)
    cj["y"] = c.position_crs.y();
    cj["z"] = c.position_crs.z();
    cj["omega_phi_kappa_deg"] = {c.opk_deg.x(), c.opk_deg.y(), c.opk_deg.z()};
    if (c.has_precision) {
      cj["sigma_position_m"] = {c.sigma_position_m.x(), c.sigma_position_m.y(), c.sigma_position_m.z()};
      cj["sigma_omega_phi_kappa_deg"] = {c.sigma_opk_deg.x(), c.sigma_opk_deg.y(), c.sigma_opk_deg.z()};
    }
    j.push_back(cj);
  }
  return j;
}

// Leave-one-out over the control points.
void AddLeaveOneOut(const GeoreferenceReport& r, nlohmann::json* out) {
  nlohmann::json& j = *out;
  {
    const LeaveOneOut& loo = r.leave_one_out;
    if (loo.computed) {
      nlohmann::json lj = PointsJson(loo.points, loo.stats, r.residuals_in_crs_units);
      lj["computed"] = true;
      lj["note"] = "each control point withheld from its own adjustment and triangulated as a check point: "
                   "residuals the adjustment did not pull towards zero";
      lj["adjustments"] = loo.adjustments;
      lj["updated"] = loo.updated;
      lj["method"] = loo.updated == static_cast<int>(loo.points.size())
                         ? "block-deletion update of the normal equations at the survey's optimum"
                         : loo.updated > 0 ? "block-deletion update, and a re-solve from the optimum where it "
                                             "could not be taken"
                                           : "a re-solve from the survey's optimum per point";
      lj["iterations"] = loo.iterations;
      lj["time_s"] = loo.time_s;
      j["leave_one_out"] = lj;
    } else {
      j["leave_one_out"] = {{"computed", false}, {"note", loo.note.empty() ? "not asked for" : loo.note}};
    }
  }
}

// The posterior precision and the marks' data snooping.
void AddPrecision(const GeoreferenceReport& r, nlohmann::json* out) {
  nlohmann::json& j = *out;
  {
    const BundlePrecision& p = r.bundle.precision;
    nlohmann::json pj;
    pj["computed"] = p.computed;
    if (!p.computed) pj["note"] = p.note;
    pj["variance_factor"] = p.variance_factor;
    if (p.computed) pj["undetermined_points"] = p.undetermined_points;
    pj["scaling"] = "every sigma is a-posteriori: the a-priori covariance (J^T J)^-1 times sigma0^2 (with variance "
                    "components estimated, J weighed by each group's estimated sigma, and sigma0 1)";
    pj["time_s"] = p.time_s;
    pj["check_points"] = r.check_points_in_bundle
                             ? "free points inside the bundle (no prior; their marks tie the block)"
                             : "independent: triangulated after the adjustment with the cameras held; their "
                               "sigmas carry the cameras' covariance";
    if (p.has_gps_offset) {
      pj["gps_offset_sigma"] = {{"e_m", std::sqrt(p.gps_offset_cov(0, 0))},
                                {"n_m", std::sqrt(p.gps_offset_cov(1, 1))},
                                {"u_m", std::sqrt(p.gps_offset_cov(2, 2))}};
    }
    j["adjustment"]["precision"] = pj;
    nlohmann::json marks = nlohmann::json::array();
    for (const MarkResult& m : r.marks) {
      marks.push_back({{"point", m.point},
                       {"image", m.image},
                       {"role", m.role == PointRole::kControl ? "control" : "check"},
                       {"residual_px", {m.residual_px.x(), m.residual_px.y()}},
                       {"redundancy", {m.redundancy.x(), m.redundancy.y()}},
                       {"w", {m.w.x(), m.w.y()}},
                       {"suspect", m.suspect},
                       {"rejected", m.rejected}});
    }
    int suspects = 0;
    for (const MarkResult& m : r.marks) suspects += m.suspect;
    j["adjustment"]["data_snooping"] = {
        {"test", "Baarda's w-test on each mark's image residual (adjusted - observed), per axis: "
                 "w = v / (sigma sqrt(r)), r the redundancy number; marks beyond critical_value are suspect, "
                 "the largest |w| beyond critical_value_family is rejected (MARK_BLUNDER)"},
        {"critical_value", r.w_critical},
        {"alpha", 0.001},
        {"tests", r.mark_tests},
        {"family_alpha", r.mark_family_alpha},
        {"critical_value_family", r.w_critical_family},
        {"suspects", suspects},
        {"expected_suspects_without_blunders", 0.001 * r.mark_tests},
        {"marks", marks}};
  }
}

// The datum's figures beside the adjustment: control precision, GPS against
// control, the GNSS drift and the block's attitude.
void AddDatumAndGnss(const GeoreferenceReport& r, nlohmann::json* out) {
  nlohmann::json& j = *out;
  if (r.placement.computed) {
    j["placement"] = {{"note", "how well the survey is placed in its CRS: the cameras' posterior position sigmas "
                               "(median; horizontal: root-sum-square of the two axes), every observation group "
                               "weighed as the adjustment estimated it"},
                      {"datum", r.datum_source},
                      {"sigma_h_m", r.placement.sigma_h_m},
                      {"sigma_v_m", r.placement.sigma_v_m}};
  }
  const auto& cp = r.control_precision;
  if (cp.measured) {
    j["control_precision"] = {{"note", "control scatter about the model per axis (free network), against the "
                                       "file's sigmas"},
                              {"points", cp.points},
                              {"stated_m", cp.stated_m},
                              {"estimated_m", cp.estimated_m},
                              {"adopted", cp.adopted},
                              {"judged_by_variance_component", cp.deferred}};
  }
  const GpsVersusControl& versus = r.gps_vs_control;
  if (versus.measured) {
    j["gps_vs_control"] = {{"note", "GPS minus the camera centres of the control-only initial fit"},
                           {"cameras", versus.cameras},
                           {"consistent", versus.consistent},
                           {"offset", Enu(versus.offset_enu_m)},
                           {"offset_sigma", Enu(versus.offset_sigma_m)},
                           {"rms_after_offset", Enu(versus.rms_after_offset_m)},
                           {"significant", versus.significant},
                           {"rejected", versus.rejected}};
  } else {
    j["gps_vs_control"] = nullptr;
  }
  {
    const GpsDriftReport& d = r.gps_drift;
    nlohmann::json flights = nlohmann::json::array();
    for (const GpsDriftReport::Flight& f : d.flights) {
      flights.push_back({{"images", f.images},
                         {"duration_s", f.duration_s},
                         {"trend_m_per_s", Enu(f.trend_m_per_s)},
                         {"trend_sigma_m_per_s", Enu(f.trend_sigma)},
                         {"rate_m_per_s", Enu(f.rate_m_per_s)},
                         {"rate_sigma_m_per_s", Enu(f.rate_sigma)}});
    }
    j["gps_drift"] = {{"note", d.note},
                      {"tested", d.tested},
                      {"estimated", d.estimated},
                      {"axes", {{"e", d.axes[0]}, {"n", d.axes[1]}, {"u", d.axes[2]}}},
                      {"gps_fit_tilt_deg", d.gps_fit_tilt_deg},
                      {"vertical_source", d.vertical_source},
                      {"attitude_prior", d.attitude_prior},
                      {"attitude_prior_sigma_deg_per_photo", d.attitude_prior_sigma_deg},
                      {"flights", flights}};
    nlohmann::json shutters = nlohmann::json::array();
    for (const GeoreferenceReport::Shutter& sh : r.shutters) {
      shutters.push_back({{"camera", sh.camera},
                          {"model", sh.model},
                          {"images", sh.images},
                          {"readout_time_s", sh.readout_time_s},
                          {"readout_estimated", sh.readout_estimated},
                          {"readout_sigma_s", sh.readout_sigma_s},
                          {"readout_stated_s", sh.readout_stated_s},
                          {"mean_speed_mps", sh.mean_speed_mps},
                          {"source", sh.source}});
    }
    j["adjustment"]["shutter"] = shutters;
    const ViewingGeometry& v = r.viewing;
    j["adjustment"]["attitude"] = {{"nadir_block", v.nadir},
                                   {"viewing", v.reason},
                                   {"axes_spread_deg", v.spread_deg},
                                   {"mean_axis_tilt_deg", r.tilt.mean_axis_tilt_deg},
                                   {"median_tilt_deg", r.tilt.median_deg},
                                   {"max_tilt_deg", r.tilt.max_deg},
                                   {"ground_slope_deg", r.tilt.ground_slope_deg},
                                   {"ground_slope_points", r.tilt.ground_points}};
    if (r.gimbal_vertical.images > 0) {
      const GimbalVertical& gv = r.gimbal_vertical;
      j["adjustment"]["attitude"]["gimbal_vertical"] = {
          {"images", gv.images}, {"spread_deg", gv.spread_deg}, {"usable", gv.usable}, {"reason", gv.reason}};
    }
    if (r.gimbal.images > 0) {
      const GimbalAgreement& g = r.gimbal;
      j["adjustment"]["attitude"]["gimbal"] = {{"images", g.images},
                                               {"block_tilt_deg", g.block_tilt_deg},
                                               {"pitch_difference_median_deg", g.pitch_median_deg},
                                               {"pitch_difference_max_deg", g.pitch_max_deg},
                                               {"pitch_worst_image", g.pitch_worst_image},
                                               {"yaw_images", g.yaw_images},
                                               {"yaw_bias_deg", g.yaw_bias_deg},
                                               {"yaw_difference_median_deg", g.yaw_median_deg},
                                               {"yaw_difference_max_deg", g.yaw_max_deg}};
    }
  }
}

// The intrinsics' a-priori precision and correlations per camera group.
void AddIntrinsicsPrecision(const GeoreferenceReport& r, const SparseModel& model, nlohmann::json* out) {
  nlohmann::json& j = *out;
  j["adjustment"]["intrinsics_precision"] = nlohmann::json::array();
  for (const IntrinsicsPrecision& p : r.bundle.intrinsics_precision) {
    nlohmann::json pj;
    pj["camera"] = model.cameras[p.camera].id;
    pj["note"] = "a-priori standard deviations and correlations ((J^T J)^-1 with the stated sigmas)";
    for (size_t k = 0; k < p.names.size(); ++k) pj["sigma"][p.names[k]] = p.sigmas[k];
    pj["correlation"] = {{"params", p.names}, {"matrix", p.correlation}};
    pj["focal_height_correlation"] = {{"median", p.focal_height_correlation_median},
                                      {"max", p.focal_height_correlation_max}};
    nlohmann::json high = nlohmann::json::array();
    for (size_t a = 0; a < p.names.size(); ++a) {
      for (size_t b = a + 1; b < p.names.size(); ++b) {
        if (std::abs(p.correlation[a][b]) > 0.9) {
          high.push_back({{"pair", p.names[a] + "-" + p.names[b]}, {"rho", p.correlation[a][b]}});
        }
      }
    }
    pj["high_correlations"] = high;
    j["adjustment"]["intrinsics_precision"].push_back(pj);
  }
  if (!r.bundle.covariance_note.empty()) j["adjustment"]["intrinsics_precision_note"] = r.bundle.covariance_note;
}

// The GPS offset (one, or per flight) with its sigmas.
void AddGpsOffset(const GeoreferenceReport& r, nlohmann::json* out) {
  nlohmann::json& j = *out;
  j["adjustment"]["gps_offset"] = {{"estimated", r.bundle.gps_offset_estimated},
                                   {"note", "GPS minus camera centre, ENU metres"},
                                   {"offset", Enu(r.bundle.gps_offset_m)}};
  if (r.bundle.gps_offset_estimated && r.bundle.precision.has_gps_offset) {
    const Eigen::Matrix3d& c = r.bundle.precision.gps_offset_cov;
    j["adjustment"]["gps_offset"]["sigma"] = Enu(c.diagonal().cwiseMax(0.0).cwiseSqrt());
  }
  // One offset per flight: each with its sigma and photos (the top-level
  // offset is flight 1's).
  if (!r.bundle.gps_flight_offsets_m.empty()) {
    nlohmann::json flights = nlohmann::json::array();
    std::vector<int> photos(r.bundle.gps_flight_offsets_m.size(), 0);
    for (const CameraResult& c : r.cameras) {
      if (c.has_prior && c.flight >= 0 && c.flight < static_cast<int>(photos.size())) ++photos[c.flight];
    }
    for (size_t f = 0; f < r.bundle.gps_flight_offsets_m.size(); ++f) {
      nlohmann::json fj = {{"flight", f + 1}, {"photos", photos[f]}, {"offset", Enu(r.bundle.gps_flight_offsets_m[f])}};
      const auto& cov = r.bundle.precision.gps_flight_offset_cov;
      if (r.bundle.gps_offset_estimated && f < cov.size()) {
        fj["sigma"] = Enu(cov[f].diagonal().cwiseMax(0.0).cwiseSqrt());
      }
      flights.push_back(fj);
    }
    j["adjustment"]["gps_offset"]["per_flight"] = true;
    j["adjustment"]["gps_offset"]["flights"] = flights;
  }
}

}  // namespace

nlohmann::json GeoreferenceReportJson(const GeoreferenceReport& r, const SparseModel& model) {
  nlohmann::json j;
  j["crs"] = r.crs;
  j["crs_name"] = r.crs_name;
  j["crs_source"] = r.crs_source;
  j["residual_axes"] = r.axes;
  if (r.local_origin) j["crs_local_origin"] = {r.local_origin->x(), r.local_origin->y(), r.local_origin->z()};
  j["enu_origin"] = {{"lat_deg", r.enu_origin.lat_deg},
                     {"lon_deg", r.enu_origin.lon_deg},
                     {"h_m", r.enu_origin.h_m},
                     {"height_reference", "WGS84 ellipsoid"}};
  j["control_points"] = PointsJson(r.control, r.control_stats, r.residuals_in_crs_units);
  j["check_points"] = PointsJson(r.check, r.check_stats, r.residuals_in_crs_units);
  if (r.check_test.tests > 0) {
    j["check_points"]["test"] = {
        {"note", "each residual per axis over its predicted sigma, the root-sum-square of its posterior sigma and "
                 "its survey's (w); rejected above the critical value of the family-wise size over all the axis "
                 "tests (Sidak)"},
        {"tests", r.check_test.tests},
        {"family_alpha", r.check_test.family_alpha},
        {"critical_value", r.check_test.critical_value},
        {"predicted_from", r.check_test.posterior ? "posterior covariance and survey sigmas"
                                                  : "survey and datum sigmas (no posterior covariance)"}};
  }
  const AsprsStatements check = AsprsStatements::From(r.check_stats);
  j["asprs"] = {
      {"based_on", r.check_stats.count > 0 ? "check points" : "no check points"},
      {"edition_2014",
       {{"horizontal_accuracy_95_m", check.horizontal_accuracy_95_m},
        {"nva_95_m", check.nva_95_m},
        {"note", "horizontal 95% = 1.7308 RMSE_r, NVA 95% = 1.96 RMSE_z"}}},
      {"edition_2023",
       {{"rmse_h_m", check.rmse_h_m}, {"rmse_v_m", check.rmse_v_m}, {"rmse_3d_m", check.rmse_3d_m}}}};
  j["cameras"] = CamerasJson(r);
  j["exterior_orientation"] = {
      {"position", "camera centre in the output CRS (for a geographic CRS: lon, lat, ellipsoidal h)"},
      {"angles", "omega, phi, kappa (deg) of R = Rx(omega) Ry(phi) Rz(kappa), the rotation from the photo frame "
                 "(x right, y up the image, z out of the lens towards the viewer) to the grid axes (easting, "
                 "northing, up); a nadir photo with its top to the north has 0, 0, 0"},
      {"sigmas", "posterior standard deviations (scaled by sigma0^2), position on the grid axes"}};
  j["adjustment"] = BundleSummaryJson(r.bundle, model);
  for (auto& c : j["adjustment"]["intrinsics"]) {
    for (const Camera& initial : r.initial_cameras) {
      if (initial.id != c["camera"].get<int>() || initial.info().name != c["model"].get<std::string>()) continue;
      nlohmann::json params;
      for (int i = 0; i < initial.info().num_params(); ++i) params[initial.info().param_names[i]] = initial.params[i];
      c["initial_params"] = params;
    }
  }
  AddLeaveOneOut(r, &j);
  AddPrecision(r, &j);
  nlohmann::json phases = nlohmann::json::array();
  for (const GeoreferenceReport::Phase& p : r.phases) {
    phases.push_back({{"phase", p.name}, {"wall_s", p.wall_s}, {"cpu_s", p.cpu_s}, {"peak_rss_mb", p.peak_rss_mb}});
  }
  j["adjustment"]["phases"] = phases;
  j["adjustment"]["helmert"] = {{"correspondences", r.helmert_correspondences},
                                {"inliers", r.helmert_inliers},
                                {"rms_m", r.helmert_rms_m},
                                {"datum_source", r.datum_source}};
  AddDatumAndGnss(r, &j);
  const BlockGeometry& g = r.geometry;
  j["adjustment"]["block_geometry"] = {{"images", g.images},
                                       {"median_depth_m", g.median_depth_m},
                                       {"relief_ratio", g.relief_ratio},
                                       {"roughness_ratio", g.roughness_ratio},
                                       {"height_variation_ratio", g.height_variation_ratio},
                                       {"tilt_p90_deg", g.tilt_p90_deg},
                                       {"gsd_m", g.gsd_m},
                                       {"gps_sigma_v_m", g.gps_sigma_v_m}};
  j["adjustment"]["block_geometry"]["nadir_flat_single_altitude"] = g.nadir_flat_single_altitude;
  j["adjustment"]["refinement"] = {{"policy", r.refinement_auto ? "auto" : "given (--refine)"},
                                   {"refined", r.refined},
                                   {"reason", r.refinement_reason}};
  AddIntrinsicsPrecision(r, model, &j);
  j["adjustment"]["dome"] = {{"source", r.dome.source},
                             {"points", r.dome.points},
                             {"radius_m", r.dome.radius_m},
                             {"amplitude_m", r.dome.amplitude_m},
                             {"amplitude_sigma_m", r.dome.amplitude_sigma_m},
                             {"t", r.dome.t},
                             {"t_critical", r.dome.t_critical},
                             {"significant", r.dome.significant},
                             {"note", "vertical residual at the block's edge minus at its centre (dz = a + b x + c y + amplitude r^2 / R^2); significant: |t| beyond Student's t at points - 4 degrees of freedom, "
                                      "two-sided 0.27 % (3.0 for many points)"}};
  AddGpsOffset(r, &j);
  j["status"] = SurveyStatus(r.findings);
  j["warnings"] = FindingsJson(r.findings, Severity::kWarning);
  j["errors"] = FindingsJson(r.findings, Severity::kError);
  return j;
}

}  // namespace aerotri
