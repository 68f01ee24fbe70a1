// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/report/html_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace aerotri {
namespace {

using json = nlohmann::json;

std::string Escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Num(double v, int decimals = 3) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

double Get(const json& j, const char* key, double fallback = NAN) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}

// j[key] when it is a string; fallback when it is absent, null (an
// un-georeferenced survey's "crs") or of another type.
std::string Text(const json& j, const char* key, const std::string& fallback = "") {
  return j.is_object() && j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : fallback;
}

// Tick values at 1, 2 or 5 times a power of ten covering [lo, hi], about
// `target` of them: axis labels a reader can use (0.5, 1.0, 1.5, not
// -9.44, -5.36).
std::vector<double> NiceTicks(double lo, double hi, int target = 5) {
  if (!(hi > lo)) hi = lo + 1.0;
  const double raw = (hi - lo) / std::max(1, target);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  for (double v = std::floor(lo / step) * step; v <= hi + 1e-9 * step; v += step) {
    ticks.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  }
  if (ticks.back() < hi) ticks.push_back(ticks.back() + step);
  return ticks;
}

// Decimals that show a tick step exactly (0.25 -> 2, 5 -> 0).
int DecimalsFor(const std::vector<double>& ticks) {
  if (ticks.size() < 2) return 2;
  const double step = ticks[1] - ticks[0];
  return std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
}

// A horizontal bar chart of one or more series per label. `decimals` is how
// values print in tooltips (0 for counts).
std::string BarChart(const std::vector<std::string>& labels, const std::vector<std::vector<double>>& series,
                     const std::vector<std::string>& names, const std::vector<std::string>& colours,
                     const std::string& unit, int decimals = 3) {
  const int n = static_cast<int>(labels.size());
  if (n == 0) return "<p>No data.</p>";
  double lo = 0.0, hi = 0.0;
  for (const auto& s : series) {
    for (double v : s) {
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
  }
  const std::vector<double> ticks = NiceTicks(lo, hi);
  lo = ticks.front();
  hi = ticks.back();
  const int row = 6 * static_cast<int>(series.size()) + 6, left = 130, width = 520;
  const int height = n * row + 56;
  auto x = [&](double v) { return left + (v - lo) / (hi - lo) * width; };
  std::ostringstream svg;
  svg << "<svg viewBox='0 0 " << left + width + 60 << " " << height << "' class='chart'>";
  for (double t : ticks) {
    svg << "<line x1='" << x(t) << "' y1='0' x2='" << x(t) << "' y2='" << n * row << "' stroke='"
        << (t == 0.0 ? "#888" : "#e4e4e4") << "'/>";
  }
  for (int i = 0; i < n; ++i) {
    const int y = i * row;
    svg << "<text x='" << left - 6 << "' y='" << y + row - 4 << "' text-anchor='end' font-size='9'>"
        << Escape(labels[i]) << "</text>";
    for (size_t s = 0; s < series.size(); ++s) {
      const double v = series[s][i];
      if (!std::isfinite(v)) continue;
      const double a = x(std::min(0.0, v)), b = x(std::max(0.0, v));
      svg << "<rect x='" << a << "' y='" << y + 3 + 6 * s << "' width='" << std::max(0.5, b - a)
          << "' height='5' fill='" << colours[s] << "'><title>" << Escape(labels[i]) << " " << names[s] << ": "
          << Num(v, decimals) << " " << unit << "</title></rect>";
    }
  }
  const int tick_decimals = DecimalsFor(ticks);
  for (double t : ticks) {
    svg << "<text x='" << x(t) << "' y='" << n * row + 14 << "' text-anchor='middle' font-size='9'>"
        << Num(t, tick_decimals) << "</text>";
  }
  // The unit under the axis, the legend on a line of its own below it.
  svg << "<text x='" << left + width / 2 << "' y='" << n * row + 30 << "' text-anchor='middle' font-size='10'>"
      << Escape(unit) << "</text>";
  if (names.size() > 1) {
    svg << "<text x='" << left + width / 2 << "' y='" << n * row + 46 << "' text-anchor='middle' font-size='10'>";
    for (size_t s = 0; s < names.size(); ++s) {
      svg << "<tspan fill='" << colours[s] << "'>" << (s ? "   " : "") << "■ " << Escape(names[s]) << "</tspan>";
    }
    svg << "</text>";
  }
  svg << "</svg>";
  return svg.str();
}

// Above this many labels a chart shows the distribution instead of one bar
// per label: readable on a 500-image survey.
constexpr int kMaxBars = 60;

// The distribution of one value over many labels: a histogram on nice bins,
// the median, and the labels of the largest values.
std::string Distribution(const std::vector<std::string>& labels, const std::vector<double>& values,
                         const std::string& what, const std::string& unit, int decimals) {
  std::vector<std::pair<double, std::string>> v;
  for (size_t i = 0; i < values.size(); ++i) {
    if (std::isfinite(values[i])) v.emplace_back(values[i], labels[i]);
  }
  if (v.empty()) return "<p>No data.</p>";
  std::sort(v.begin(), v.end());
  const std::vector<double> edges = NiceTicks(v.front().first, v.back().first, 12);
  std::vector<int> count(edges.size() - 1, 0);
  for (const auto& [value, label] : v) {
    size_t b = std::upper_bound(edges.begin(), edges.end(), value) - edges.begin();
    b = std::min(count.size(), std::max<size_t>(1, b)) - 1;
    ++count[b];
  }
  const int cmax = *std::max_element(count.begin(), count.end());
  const int left = 40, width = 600, height = 160;
  const double bw = static_cast<double>(width) / count.size();
  std::ostringstream svg;
  svg << "<svg viewBox='0 0 " << left + width + 20 << " " << height + 40 << "' class='chart'>";
  const int d = DecimalsFor(edges);
  for (size_t b = 0; b < count.size(); ++b) {
    const double h = cmax > 0 ? static_cast<double>(height) * count[b] / cmax : 0.0;
    svg << "<rect x='" << left + b * bw + 1 << "' y='" << height - h << "' width='" << bw - 2 << "' height='" << h
        << "' fill='#a6c'><title>" << count[b] << " " << Escape(what) << " from " << Num(edges[b], d) << " to "
        << Num(edges[b + 1], d) << " " << Escape(unit) << "</title></rect>";
  }
  for (size_t e = 0; e < edges.size(); e += std::max<size_t>(1, edges.size() / 7)) {
    svg << "<text x='" << left + e * bw << "' y='" << height + 14 << "' text-anchor='middle' font-size='9'>"
        << Num(edges[e], d) << "</text>";
  }
  svg << "<text x='" << left - 4 << "' y='10' text-anchor='end' font-size='9'>" << cmax << "</text>"
      << "<text x='" << left + width / 2 << "' y='" << height + 32 << "' text-anchor='middle' font-size='10'>"
      << Escape(unit) << " (bars: number of " << Escape(what) << ")</text></svg>";
  std::ostringstream h;
  h << svg.str() << "<p>" << v.size() << " " << Escape(what) << ": median " << Num(v[v.size() / 2].first, decimals)
    << " " << Escape(unit) << "; largest: ";
  for (size_t k = 0; k < std::min<size_t>(5, v.size()); ++k) {
    const auto& [value, label] = v[v.size() - 1 - k];
    h << (k ? ", " : "") << Escape(label) << " " << Num(value, decimals);
  }
  h << ".</p>";
  return h.str();
}

// One bar per label when they fit, the distribution otherwise.
std::string PerLabelChart(const std::vector<std::string>& labels, const std::vector<double>& values,
                          const std::string& name, const std::string& colour, const std::string& what,
                          const std::string& unit, int decimals) {
  if (static_cast<int>(labels.size()) > kMaxBars) return Distribution(labels, values, what, unit, decimals);
  return BarChart(labels, {values}, {name}, {colour}, unit, decimals);
}

// The ASPRS 2023 (Edition 2) accuracy statement in its words, the class
// being the tested RMSE rounded up to the half centimetre; and the warning
// that fewer than 30 check points are below its minimum for a statement.
std::string AsprsStatement(const json& asprs, int check_points) {
  const json& e = asprs.value("edition_2023", json::object());
  const double h = Get(e, "rmse_h_m"), v = Get(e, "rmse_v_m");
  if (!std::isfinite(h) && !std::isfinite(v)) return "";
  auto cls = [](double rmse_m) { return std::ceil(rmse_m * 100.0 / 0.5 - 1e-9) * 0.5; };
  std::ostringstream out;
  out << "<p class='asprs'>";
  if (std::isfinite(h)) {
    out << "This data set was tested to meet ASPRS Positional Accuracy Standards for Digital Geospatial Data, "
           "Edition 2 (2023) for a "
        << Num(cls(h), 1) << " cm RMSE<sub>H</sub> horizontal positional accuracy class. The tested horizontal "
        << "positional accuracy was found to be RMSE<sub>H</sub> = " << Num(h * 100.0, 1) << " cm. ";
  }
  if (std::isfinite(v)) {
    out << "This data set was tested to meet ASPRS Positional Accuracy Standards for Digital Geospatial Data, "
           "Edition 2 (2023) for a "
        << Num(cls(v), 1) << " cm RMSE<sub>V</sub> vertical positional accuracy class. The tested vertical "
        << "positional accuracy was found to be RMSE<sub>V</sub> = " << Num(v * 100.0, 1)
        << " cm in non-vegetated terrain.";
  }
  out << "</p>";
  if (check_points < 30) {
    out << "<p class='warn'><b>Only " << check_points
        << " check points:</b> ASPRS 2023 asks for at least 30 before accuracy is stated as tested; these "
           "figures are indicative, not a compliance statement.</p>";
  }
  return out.str();
}

std::string PointTable(const json& group, const char* title) {
  std::ostringstream h;
  h << "<h3>" << title << " (" << group.value("count", 0) << ")</h3>";
  if (!group.contains("points") || group["points"].empty()) return h.str() + "<p>None.</p>";
  // Check points tested against their predicted sigmas: w per axis.
  const bool tested = group.contains("test");
  h << "<table><tr><th>name</th><th>images</th><th>dx (m)</th><th>dy (m)</th><th>dz (m)</th><th>3D (m)</th>"
       "<th>&sigma;x, &sigma;y, &sigma;z (m)</th><th>reprojection RMS (px)</th>"
    << (tested ? "<th>w x, y, z</th>" : "") << "</tr>";
  for (const auto& p : group["points"]) {
    h << "<tr><td>" << Escape(Text(p, "name", "")) << "</td><td>" << p.value("images", 0) << "</td>";
    if (p.value("solved", false)) {
      const double dx = Get(p, "dx_m"), dy = Get(p, "dy_m"), dz = Get(p, "dz_m");
      h << "<td>" << Num(dx) << "</td><td>" << Num(dy) << "</td><td>" << Num(dz) << "</td><td>"
        << Num(std::sqrt(dx * dx + dy * dy + dz * dz)) << "</td><td>"
        << (p.contains("sigma_x_m") ? Num(Get(p, "sigma_x_m")) + ", " + Num(Get(p, "sigma_y_m")) + ", " +
                                          Num(Get(p, "sigma_z_m"))
                                    : std::string("–"))
        << "</td><td>" << Num(Get(p, "reprojection_rms_px"), 2) << "</td>";
      if (tested && p.contains("w") && p["w"].is_array() && p["w"].size() == 3) {
        const bool rejected = p.value("rejected", false);
        h << "<td" << (rejected ? " class='warn'" : "") << ">" << Num(p["w"][0].get<double>(), 1) << ", "
          << Num(p["w"][1].get<double>(), 1) << ", " << Num(p["w"][2].get<double>(), 1)
          << (rejected ? " (rejected)" : "") << "</td>";
      } else if (tested) {
        h << "<td>–</td>";
      }
    } else {
      h << "<td colspan='" << (tested ? 7 : 6) << "'>not solved: " << Escape(Text(p, "why_not", "")) << "</td>";
    }
    h << "</tr>";
  }
  h << "<tr class='total'><td>RMSE</td><td></td><td>" << Num(Get(group, "rmse_x_m")) << "</td><td>"
    << Num(Get(group, "rmse_y_m")) << "</td><td>" << Num(Get(group, "rmse_z_m")) << "</td><td>"
    << Num(Get(group, "rmse_3d_m")) << "</td><td></td><td></td>" << (tested ? "<td></td>" : "") << "</tr></table>";
  if (tested) {
    const json& t = group["test"];
    h << "<p>Each residual is divided by its predicted sigma (the posterior sigma and the survey's, "
         "root-sum-square): w. A point is rejected when an axis's |w| exceeds "
      << Num(t.value("critical_value", 0.0), 2) << ", the critical value at "
      << Num(100.0 * t.value("family_alpha", 0.0), 0) << " % over all " << t.value("tests", 0)
      << " axis tests (predicted from " << Escape(t.value("predicted_from", std::string())) << ").</p>";
  }
  return h.str();
}

// σ0, redundancy, the χ² test, the precision of the exterior orientation
// and the data snooping of the marks.
std::string AdjustmentStatistics(const json& r) {
  const json& adj = r.value("adjustment", json::object());
  std::ostringstream h;
  h << "<h2>Adjustment statistics</h2><table>"
    << "<tr><td>&sigma;<sub>0</sub> (a-posteriori sigma of unit weight)</td><td>" << Num(Get(adj, "sigma0", NAN), 4)
    << "</td></tr><tr><td>redundancy</td><td>" << adj.value("redundancy", 0) << "</td></tr>";
  if (adj.contains("chi2_test")) {
    const json& c = adj["chi2_test"];
    h << "<tr><td>&chi;<sup>2</sup> test of &sigma;<sub>0</sub> against the stated sigmas (z)</td><td>"
      << Num(Get(c, "z", NAN), 2) << (c.value("consistent", false) ? " (consistent)" : " (inconsistent)")
      << "</td></tr>";
  }
  h << "<tr><td>termination</td><td>" << Escape(Text(adj, "termination", "")) << "</td></tr>";
  if (adj.contains("solves") && !adj["solves"].empty()) {
    // The solves in order: the robust screening, the least-squares estimate,
    // outlier rounds and variance-component re-weightings.
    std::string list;
    for (const json& s : adj["solves"]) {
      list += (list.empty() ? "" : "; ") + Text(s, "kind", "") + " " + std::to_string(s.value("iterations", 0)) +
              " it., " + Num(Get(s, "time_s", NAN), 1) + " s";
    }
    h << "<tr><td>solves</td><td>" << Escape(list) << "</td></tr>";
  }
  h << "</table>";
  if (adj.contains("variance_components")) {
    const json& vc = adj["variance_components"];
    const bool estimated = vc.value("estimated", false);
    h << "<h3>Variance components</h3><p>"
      << (estimated ? "Each observation group weighed by the scatter it shows (re-solved " +
                          std::to_string(vc.value("iterations", 0)) + " time(s)); &sigma;<sub>0</sub> with the "
                          "stated sigmas was " + Num(Get(vc, "sigma0_stated", NAN), 3) + "."
                    : std::string("The stated sigmas kept; each group's &sigma;<sub>0</sub> shows whether they "
                                  "describe its data."))
      << "</p><table><tr><th>group</th><th>observations</th><th>redundancy</th><th>stated &sigma;</th>"
         "<th>group &sigma;<sub>0</sub></th><th>shown by the data</th><th>weighed by</th></tr>";
    for (const auto& g : vc.value("groups", json::array())) {
      const std::string unit = " " + Text(g, "unit", "");
      const int decimals = 3;
      h << "<tr><td>" << Escape(Text(g, "group", "")) << "</td><td>" << g.value("rows", 0) << "</td><td>"
        << Num(Get(g, "redundancy"), 1) << "</td><td>" << Num(Get(g, "stated_sigma"), decimals) << unit
        << "</td><td>" << Num(Get(g, "sigma0"), 3) << "</td><td>" << Num(Get(g, "estimated_sigma"), decimals) << unit
        << "</td><td>" << Num(Get(g, "stated_sigma") * Get(g, "scale", 1.0), decimals) << unit << "</td></tr>";
    }
    h << "</table>";
  }
  const json& p = adj.value("precision", json::object());
  if (!p.value("computed", false)) {
    h << "<p>Posterior precision not computed: " << Escape(Text(p, "note", "not asked for")) << "</p>";
    return h.str();
  }
  // Exterior orientation precision: median and largest over the cameras.
  std::vector<std::vector<double>> v(6);
  for (const auto& c : r.value("cameras", json::array())) {
    if (!c.contains("sigma_position_m")) continue;
    for (int k = 0; k < 3; ++k) {
      v[k].push_back(c["sigma_position_m"][k].get<double>());
      v[3 + k].push_back(c["sigma_omega_phi_kappa_deg"][k].get<double>());
    }
  }
  static const char* kNames[] = {"&sigma;X (m)", "&sigma;Y (m)", "&sigma;Z (m)",
                                 "&sigma;&omega; (deg)", "&sigma;&phi; (deg)", "&sigma;&kappa; (deg)"};
  h << "<h3>Exterior orientation precision (" << v[0].size()
    << " cameras; a-posteriori, full list in exterior_orientation.csv)</h3><table><tr><th></th>";
  for (const char* n : kNames) h << "<th>" << n << "</th>";
  h << "</tr>";
  for (const bool largest : {false, true}) {
    h << "<tr><td>" << (largest ? "largest" : "median") << "</td>";
    for (auto& x : v) {
      if (x.empty()) {
        h << "<td>–</td>";
        continue;
      }
      std::sort(x.begin(), x.end());
      h << "<td>" << Num(largest ? x.back() : x[x.size() / 2], 4) << "</td>";
    }
    h << "</tr>";
  }
  h << "</table><p>" << Escape(Text(r.value("exterior_orientation", json::object()), "angles", "")) << ". "
    << Escape(Text(p, "check_points", "")) << ".</p>";
  // Data snooping.
  const json& ds = adj.value("data_snooping", json::object());
  const json& marks = ds.value("marks", json::array());
  double max_w = 0.0;
  std::string worst;
  for (const auto& m : marks) {
    for (int a = 0; a < 2; ++a) {
      const double w = std::abs(m["w"][a].get<double>());
      if (w > max_w) {
        max_w = w;
        worst = Text(m, "point", "") + " on " + Text(m, "image", "");
      }
    }
  }
  const double critical = Get(ds, "critical_value", 3.29);
  const double family = Get(ds, "critical_value_family", critical);
  h << "<h3>Data snooping of the target marks</h3><p>Baarda's w-test on " << marks.size() << " marks ("
    << static_cast<int>(Get(ds, "tests", 0)) << " tests): " << static_cast<int>(Get(ds, "suspects", 0))
    << " above " << Num(critical, 2) << " (&alpha;<sub>0</sub> 0.1 % per test; "
    << Num(Get(ds, "expected_suspects_without_blunders", 0), 1) << " expected without blunders); largest |w| "
    << Num(max_w, 2) << (worst.empty() ? std::string() : " (" + Escape(worst) + ")") << " against "
    << Num(family, 2) << " for the largest of all tests (&alpha; " << Num(100 * Get(ds, "family_alpha", 0.01), 1)
    << " %)"
    << (max_w > family ? " &mdash; <b>rejected: measure this mark again</b>" : " &mdash; none rejected")
    << ".</p>";
  return h.str();
}

// Map of cameras, control and check points with horizontal residual vectors.
std::string SurveyMap(const json& r) {
  struct Mark {
    double x, y, dx, dy;
    std::string name, kind;
  };
  std::vector<Mark> marks;
  for (const auto& c : r.value("cameras", json::array())) {
    if (c.contains("x")) marks.push_back({c["x"], c["y"], 0, 0, Text(c, "name", ""), "camera"});
  }
  for (const char* group : {"control_points", "check_points"}) {
    if (!r.contains(group)) continue;
    for (const auto& p : r[group].value("points", json::array())) {
      if (!p.value("solved", false) || !p.contains("surveyed")) continue;
      marks.push_back({p["surveyed"][0], p["surveyed"][1], p["dx_m"], p["dy_m"], Text(p, "name", ""),
                       std::string(group) == "control_points" ? "control" : "check"});
    }
  }
  if (marks.empty()) return "<p>No positions to map.</p>";
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300, dmax = 0;
  for (const Mark& m : marks) {
    x0 = std::min(x0, m.x);
    x1 = std::max(x1, m.x);
    y0 = std::min(y0, m.y);
    y1 = std::max(y1, m.y);
    dmax = std::max(dmax, std::hypot(m.dx, m.dy));
  }
  const double span = std::max({x1 - x0, y1 - y0, 1.0});
  const double size = 560, pad = 30, s = (size - 2 * pad) / span;
  // Residual arrows: the largest is drawn 60 px long; the scale bar says how long 1 cm is.
  const double arrow = dmax > 0 ? 60.0 / dmax : 0.0;
  // Centre the survey in the square map.
  const double ox = 0.5 * (size - 2 * pad - (x1 - x0) * s), oy = 0.5 * (size - 2 * pad - (y1 - y0) * s);
  auto px = [&](double x) { return pad + ox + (x - x0) * s; };
  auto py = [&](double y) { return size - pad - oy - (y - y0) * s; };
  std::ostringstream svg;
  svg << "<svg viewBox='0 0 " << size << " " << size + 58 << "' class='map'>"
      << "<defs><marker id='ah' markerWidth='6' markerHeight='6' refX='5' refY='3' orient='auto'>"
      << "<path d='M0,0 L6,3 L0,6 z' fill='#c00'/></marker></defs>"
      << "<rect x='0' y='0' width='" << size << "' height='" << size << "' fill='#f7f7f2' stroke='#ccc'/>";
  for (const Mark& m : marks) {
    const double X = px(m.x), Y = py(m.y);
    if (m.kind == "camera") {
      svg << "<circle cx='" << X << "' cy='" << Y << "' r='2.5' fill='#4a7'><title>" << Escape(m.name)
          << "</title></circle>";
      continue;
    }
    const bool control = m.kind == "control";
    svg << "<path d='M" << X << "," << Y - 6 << " L" << X + 5 << "," << Y + 4 << " L" << X - 5 << "," << Y + 4
        << " z' fill='" << (control ? "#d80" : "#06c") << "'><title>" << Escape(m.name) << "</title></path>";
    svg << "<text x='" << X + 7 << "' y='" << Y - 6 << "' font-size='9'>" << Escape(m.name) << "</text>";
    if (arrow > 0) {
      svg << "<line x1='" << X << "' y1='" << Y << "' x2='" << X + m.dx * arrow << "' y2='" << Y - m.dy * arrow
          << "' stroke='#c00' stroke-width='1.5' marker-end='url(#ah)'/>";
    }
  }
  const double bar_m = span / 4.0;
  svg << "<line x1='" << pad << "' y1='" << size + 12 << "' x2='" << pad + bar_m * s << "' y2='" << size + 12
      << "' stroke='#000' stroke-width='2'/><text x='" << pad << "' y='" << size + 28 << "' font-size='10'>"
      << Num(bar_m, 1) << " m (map)</text>";
  if (arrow > 0) {
    svg << "<line x1='" << size / 2 << "' y1='" << size + 12 << "' x2='" << size / 2 + 0.01 * arrow << "' y2='"
        << size + 12 << "' stroke='#c00' stroke-width='2'/><text x='" << size / 2 << "' y='" << size + 28
        << "' font-size='10' fill='#c00'>1 cm (residual vectors)</text>";
  }
  // The symbols' legend on a line of its own, under the two scale bars.
  svg << "<text x='" << pad << "' y='" << size + 50
      << "' font-size='10'><tspan fill='#4a7'>● camera</tspan>   <tspan fill='#d80'>▲ control</tspan>   "
         "<tspan fill='#06c'>▲ check</tspan></text></svg>";
  return svg.str();
}

std::string CoverageMap(const json& cov) {
  if (!cov.is_object() || !cov.contains("counts")) return "<p>No coverage computed.</p>";
  const int nx = cov["nx"], ny = cov["ny"];
  const auto counts = cov["counts"].get<std::vector<int>>();
  int cmax = 1;
  for (int c : counts) cmax = std::max(cmax, c);
  const double cell = 400.0 / std::max(nx, ny);
  std::ostringstream svg;
  const double lx = nx * cell + 12, top = 44, bar = std::max(60.0, std::min(200.0, ny * cell - 80));
  svg << "<svg viewBox='0 0 " << nx * cell + 120 << " " << std::max(ny * cell, top + bar + 26) << "' class='map'>";
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const int c = counts[static_cast<size_t>(y) * nx + x];
      if (c < 0) continue;
      const double t = static_cast<double>(c) / cmax;
      const int red = static_cast<int>(255 * (1 - t)), green = static_cast<int>(80 + 150 * t);
      svg << "<rect x='" << x * cell << "' y='" << y * cell << "' width='" << cell + 0.5 << "' height='" << cell + 0.5
          << "' fill='rgb(" << (c == 0 ? 220 : red) << "," << (c == 0 ? 60 : green) << "," << (c == 0 ? 60 : 90)
          << ")'><title>" << c << " images</title></rect>";
    }
  }
  // Colour scale: the same ramp as the cells, 1 image at the bottom, the
  // largest count at the top; 0 (a gap) in its own red.
  svg << "<text x='" << lx << "' y='14' font-size='11'>images per</text><text x='" << lx
      << "' y='28' font-size='11'>ground point</text>";
  const int steps = 20;
  for (int k = 0; k < steps; ++k) {
    const double t = 1.0 - static_cast<double>(k) / (steps - 1);
    svg << "<rect x='" << lx << "' y='" << top + k * bar / steps << "' width='14' height='" << bar / steps + 0.5
        << "' fill='rgb(" << static_cast<int>(255 * (1 - t)) << "," << static_cast<int>(80 + 150 * t) << ",90)'/>";
  }
  svg << "<text x='" << lx + 18 << "' y='" << top + 8 << "' font-size='10'>" << cmax << "</text>"
      << "<text x='" << lx + 18 << "' y='" << top + bar << "' font-size='10'>1</text>"
      << "<rect x='" << lx << "' y='" << top + bar + 10 << "' width='14' height='10' fill='rgb(220,60,60)'/>"
      << "<text x='" << lx + 18 << "' y='" << top + bar + 19 << "' font-size='10'>0 (gap)</text></svg>";
  return svg.str();
}

// The DSM preview with its elevation legend and a scale bar, scaling with
// the page (one SVG, the image inside it).
// The cloud file: its name, format and size (LAZ: against the same points
// uncompressed), with the classes it carries.
std::string CloudSentence(const json& c) {
  std::ostringstream s;
  const std::string file = Text(c, "file", "cloud.las");
  const std::string format = Text(c, "format", "las");
  s << "Cloud: " << Escape(file) << " ("
    << (format == "laz" ? "LAZ: LAS 1.4 compressed as LASzip does"
                        : format == "copc" ? "COPC: LAZ 1.4 in an octree, read in place by QGIS, PDAL and web viewers"
                                           : "LAS 1.4, uncompressed")
    << "; ASPRS classes 2 ground, 1 above ground, 7 noise)";
  if (c.contains("bytes")) {
    s << ", " << Num(Get(c, "bytes") / 1e6, 1) << " MB";
    if (format != "las") {
      s << ", " << Num(100.0 * Get(c, "compression_ratio", NAN), 1) << " % of the "
        << Num(Get(c, "uncompressed_las_bytes") / 1e6, 1) << " MB of the same points as LAS";
    }
  }
  s << "; and cloud.ply.";
  return s.str();
}

std::string DsmFigure(const std::string& png, const json& preview) {
  const double w = Get(preview, "width_px", 600), hgt = Get(preview, "height_px", 400);
  const double mpp = Get(preview, "metres_per_px", NAN);
  std::ostringstream svg;
  svg << "<svg class='dsm' viewBox='0 0 " << w + 110 << " " << hgt + 44 << "'>"
      << "<image width='" << w << "' height='" << hgt << "' href='data:image/png;base64," << Base64(png) << "'/>"
      << "<rect width='" << w << "' height='" << hgt << "' fill='none' stroke='#ccc'/>";
  if (std::isfinite(mpp) && mpp > 0) {
    // A scale bar of a round length near a quarter of the width.
    const std::vector<double> t = NiceTicks(0.0, 0.25 * w * mpp, 1);
    const double metres = t.size() > 1 ? t[1] : 0.25 * w * mpp;
    const double len = metres / mpp;
    svg << "<rect x='10' y='" << hgt + 12 << "' width='" << len / 2 << "' height='6' fill='#000'/>"
        << "<rect x='" << 10 + len / 2 << "' y='" << hgt + 12 << "' width='" << len / 2
        << "' height='6' fill='#fff' stroke='#000'/>"
        << "<text x='10' y='" << hgt + 34 << "' font-size='11'>0</text><text x='" << 10 + len << "' y='" << hgt + 34
        << "' font-size='11' text-anchor='middle'>" << Num(metres, DecimalsFor(t)) << " m</text>";
  }
  const double x_min = Get(preview, "x_min"), y_max = Get(preview, "y_max");
  const double x_max = Get(preview, "x_max"), y_min = Get(preview, "y_min");
  if (std::isfinite(x_min) && std::isfinite(y_min)) {
    // The corners' coordinates (output CRS), as on a map sheet's frame.
    svg << "<text x='" << w << "' y='" << hgt + 24 << "' font-size='10' text-anchor='end'>top left "
        << Num(x_min, 1) << ", " << Num(y_max, 1) << "; bottom right " << Num(x_max, 1) << ", " << Num(y_min, 1)
        << "</text>";
  }
  const double lo = Get(preview, "z_low_m"), hi = Get(preview, "z_high_m");
  if (std::isfinite(lo) && std::isfinite(hi)) {
    const double x = w + 14, top = 20, bar = std::min(hgt - 40, 220.0);
    svg << "<text x='" << x << "' y='12' font-size='11'>height (m)</text>";
    const int steps = 32;
    for (int k = 0; k < steps; ++k) {
      const auto c = ElevationRampColour(1.0 - (k + 0.5) / steps);
      svg << "<rect x='" << x << "' y='" << top + k * bar / steps << "' width='16' height='" << bar / steps + 0.5
          << "' fill='rgb(" << static_cast<int>(c[0]) << "," << static_cast<int>(c[1]) << ","
          << static_cast<int>(c[2]) << ")'/>";
    }
    const std::vector<double> ticks = NiceTicks(lo, hi, 5);
    for (double v : ticks) {
      if (v < lo || v > hi) continue;
      const double y = top + (hi - v) / (hi - lo > 0 ? hi - lo : 1.0) * bar;
      svg << "<line x1='" << x + 16 << "' y1='" << y << "' x2='" << x + 20 << "' y2='" << y
          << "' stroke='#000'/><text x='" << x + 23 << "' y='" << y + 4 << "' font-size='10'>"
          << Num(v, DecimalsFor(ticks)) << "</text>";
    }
  }
  svg << "</svg>";
  return svg.str();
}

// Ground classification, DTM and contours.
std::string TerrainSection(const json& r, const std::string& dtm_png) {
  if (!r.contains("dtm")) return "";
  std::ostringstream h;
  const auto& d = r["dtm"];
  const auto& g = r.value("ground", json::object());
  const auto& c = r.value("contours", json::object());
  const double ground = Get(g, "ground"), above = Get(g, "above_ground"), noise = Get(g, "noise");
  const double all = ground + above + noise;
  h << "<h2>Terrain model (DTM) and contours</h2><p>The dense cloud is classified by "
    << Escape(Text(g, "method", "a ground filter")) << ": " << Num(100.0 * ground / std::max(1.0, all), 1)
    << " % ground, " << Num(100.0 * above / std::max(1.0, all), 1) << " % above ground (buildings, vegetation), "
    << Num(100.0 * noise / std::max(1.0, all), 2) << " % noise (cell " << Num(Get(g, "cell_m"), 2) << " m, window "
    << Num(Get(g, "window_m"), 1) << " m, slope " << Num(Get(g, "slope"), 2) << "). dtm.tif: the DSM's grid, "
    << Num(100.0 * Get(d, "interpolated_fraction"), 1) << " % of its cells interpolated under objects. "
    << "contours.gpkg: " << Get(c, "lines") << " lines every " << Num(Get(c, "interval_m"), 2)
    << " m (index every " << c.value("index_every", 5) << "th), from the DTM smoothed by a " << Num(Get(c, "smoothing_sigma_m"), 2)
    << " m Gaussian.</p>";
  const auto& cp = d.value("check_points", json::object());
  if (cp.value("count", 0) > 0) {
    h << "<p>DTM at the " << cp.value("count", 0) << " check points: RMSE z " << Num(Get(cp, "rmse_z_m"), 3)
      << " m.</p>";
  }
  if (!dtm_png.empty()) h << DsmFigure(dtm_png, d.value("preview", json::object()));
  return h.str();
}

// The orthomosaic: how it was made, its accuracy at the check points.
std::string OrthoSection(const json& r, const std::string& ortho_png) {
  if (!r.contains("ortho")) return "";
  std::ostringstream h;
  const auto& o = r["ortho"];
  h << "<h2>Orthomosaic</h2><p>" << Escape(Text(o, "file", "ortho.tif")) << ": " << o.value("width", 0) << " x "
    << o.value("height", 0) << " cells of " << Num(Get(o, "resolution_m"), 3) << " m, RGB + alpha"
    << (o.value("cog", false) ? ", Cloud-Optimised GeoTIFF" : ", GeoTIFF") << " (" << Escape(Text(o, "compress", ""))
    << "), drawn through " << Escape(Text(o, "surface", "dsm.tif")) << " from " << o.value("images_used", 0)
    << " photos; " << Num(100.0 * Get(o, "filled_fraction"), 1) << " % of the surveyed surface filled.</p>";
  const auto& cp = o.value("check_points", json::object());
  const int n = cp.value("count", 0);
  const int listed = static_cast<int>(cp.value("points", json::array()).size());
  if (listed > 0) {
    h << "<table><tr><th>check point</th><th>dx (m)</th><th>dy (m)</th><th>horizontal (m)</th></tr>";
    for (const auto& p : cp["points"]) {
      h << "<tr><td>" << Escape(Text(p, "name", "")) << "</td>";
      if (p.value("located", false)) {
        h << "<td>" << Num(p["d_m"][0].get<double>(), 3) << "</td><td>" << Num(p["d_m"][1].get<double>(), 3)
          << "</td><td>" << Num(Get(p, "dh_m"), 3) << "</td></tr>";
      } else {
        h << "<td colspan='3'>not located: " << Escape(Text(p, "reason", "")) << "</td></tr>";
      }
    }
    h << "</table><p>Targets located in the orthomosaic itself (" << Escape(Text(cp, "method", "")) << ").</p>";
  }
  if (n > 0) {
    const double rmse_h = Get(cp, "rmse_h_m");
    // ASPRS 2023 (Edition 2): horizontal class by RMSE_H; the sentence for orthoimagery.
    h << "<p><b>ASPRS:</b> This orthoimagery was tested to meet ASPRS Positional Accuracy Standards for Digital "
         "Geospatial Data, Edition 2 (2023) for a "
      << Num(100.0 * rmse_h, 1) << " cm RMSE<sub>H</sub> horizontal positional accuracy class. The tested "
      << "horizontal positional accuracy was found to be RMSE<sub>H</sub> = " << Num(100.0 * rmse_h, 1) << " cm ("
      << "RMSE<sub>x</sub> " << Num(100.0 * Get(cp, "rmse_x_m"), 1) << " cm, RMSE<sub>y</sub> "
      << Num(100.0 * Get(cp, "rmse_y_m"), 1) << " cm, " << n << " check points"
      << (n < 30 ? "; ASPRS 2023 asks for at least 30" : "") << ").</p>";
  } else if (listed > 0) {
    h << "<p class='warn'>No check-point target was located in the orthomosaic: no horizontal accuracy is "
         "stated for it.</p>";
  }
  if (!ortho_png.empty()) h << DsmFigure(ortho_png, o.value("preview", json::object()));
  return h.str();
}

// Initial and adjusted intrinsics with their sigmas, and the lens
// distortion along the image diagonal.
std::string CameraCalibration(const json& r) {
  const json& adj = r.value("adjustment", json::object());
  const json& groups = adj.value("intrinsics", json::array());
  if (groups.empty()) return "";
  std::ostringstream h;
  h << "<h2>Camera calibration</h2><p>Refined: " << Escape(Text(adj, "refined_intrinsics", "–")) << " ("
    << Escape(Text(adj.value("refinement", json::object()), "reason", "")) << "). Initial: as the adjustment "
    << "started (from the reconstruction or the calibration file). Pixels at the working resolution, (0, 0) at "
       "the centre of the top-left pixel.</p>";
  for (const auto& g : groups) {
    json sigma = json::object();
    for (const auto& p : adj.value("intrinsics_precision", json::array())) {
      if (p.value("camera", -1) == g.value("camera", -2) && p.contains("sigma")) sigma = p["sigma"];
    }
    h << "<h3>Camera " << g.value("camera", 0) << " (" << Escape(Text(g, "model", "")) << ", "
      << g.value("width", 0) << " x " << g.value("height", 0) << " px)</h3><table><tr><th>parameter</th>"
      << "<th>initial</th><th>adjusted</th><th>change</th><th>&sigma; (a priori)</th></tr>";
    const json& params = g.value("params", json::object());
    const json& initial = g.value("initial_params", json::object());
    // The usual order (f, principal point, radial, tangential), then any other.
    std::vector<std::string> names;
    for (const char* n : {"f", "fx", "fy", "cx", "cy", "k1", "k2", "k3", "p1", "p2"}) {
      if (params.contains(n)) names.push_back(n);
    }
    for (auto it = params.begin(); it != params.end(); ++it) {
      if (std::find(names.begin(), names.end(), it.key()) == names.end()) names.push_back(it.key());
    }
    for (const std::string& name : names) {
      const double v = Get(params, name.c_str());
      const bool pixels = name == "f" || name == "fx" || name == "fy" || name == "cx" || name == "cy";
      const int d = pixels ? 2 : 6;
      const double v0 = Get(initial, name.c_str());
      h << "<tr><td>" << Escape(name) << (pixels ? " (px)" : "") << "</td><td>" << Num(v0, d) << "</td><td>"
        << Num(v, d) << "</td><td>" << Num(v - v0, d) << "</td><td>"
        << (sigma.contains(name) ? Num(Get(sigma, name.c_str()), d) : std::string("held")) << "</td></tr>";
    }
    h << "</table>";
    for (const auto& shutter : adj.value("shutter", json::array())) {
      if (shutter.value("camera", -1) != g.value("camera", -2)) continue;
      if (shutter.value("model", "") == "rolling") {
        h << "<p>Shutter: rolling, each row seen from where the camera was when it was read: readout "
          << Num(1000.0 * Get(shutter, "readout_time_s"), 1)
          << (shutter.value("readout_estimated", false) && Get(shutter, "readout_sigma_s") > 0.0
                  ? " ± " + Num(1000.0 * Get(shutter, "readout_sigma_s"), 1)
                  : std::string())
          << " ms, " << shutter.value("images", 0)
          << " photos at a mean " << Num(Get(shutter, "mean_speed_mps"), 1) << " m/s ("
          << Escape(Text(shutter, "source", "")) << ").</p>";
      } else {
        h << "<p>Shutter: global (" << Escape(Text(shutter, "source", "")) << ").</p>";
      }
    }
    if (g.contains("mm")) {
      const json& mm = g["mm"];
      auto with_sigma = [&](const char* value, const char* s) {
        return Num(Get(mm, value), 4) + (mm.contains(s) ? " &plusmn; " + Num(Get(mm, s), 4) : std::string()) + " mm";
      };
      h << "<p>In the photogrammetric convention (pixel pitch " << Num(Get(mm, "pixel_size_mm") * 1000.0, 3)
        << " &micro;m from " << Escape(Text(mm, "pixel_size_source", "EXIF")) << "): camera constant c " << with_sigma("c_mm", "sigma_c_mm") << ", principal point x0 "
        << with_sigma("x0_mm", "sigma_x0_mm") << ", y0 " << with_sigma("y0_mm", "sigma_y0_mm")
        << " (from the image centre, y up the image).</p>";
    }
    const json& curve = g.value("distortion_curve", json::object());
    const auto radius = curve.value("radius_px", std::vector<double>{});
    const auto radial = curve.value("radial_px", std::vector<double>{});
    const auto tangential = curve.value("tangential_px", std::vector<double>{});
    if (radius.size() < 2 || radial.size() != radius.size() || tangential.size() != radius.size()) continue;
    double lo = 0.0, hi = 0.0;
    for (size_t k = 0; k < radius.size(); ++k) {
      lo = std::min({lo, radial[k], tangential[k]});
      hi = std::max({hi, radial[k], tangential[k]});
    }
    const std::vector<double> yt = NiceTicks(lo, hi, 5), xt = NiceTicks(0.0, radius.back(), 6);
    const double left = 50, width = 520, height = 200;
    auto X = [&](double v) { return left + v / xt.back() * width; };
    auto Y = [&](double v) { return 10 + (yt.back() - v) / (yt.back() - yt.front()) * height; };
    std::ostringstream svg;
    svg << "<svg class='chart' viewBox='0 0 " << left + width + 20 << " " << height + 64 << "'>";
    for (double t : yt) {
      svg << "<line x1='" << left << "' x2='" << left + width << "' y1='" << Y(t) << "' y2='" << Y(t) << "' stroke='"
          << (t == 0.0 ? "#888" : "#e4e4e4") << "'/><text x='" << left - 4 << "' y='" << Y(t) + 3
          << "' font-size='9' text-anchor='end'>" << Num(t, DecimalsFor(yt)) << "</text>";
    }
    for (double t : xt) {
      svg << "<text x='" << X(t) << "' y='" << height + 24 << "' font-size='9' text-anchor='middle'>"
          << Num(t, DecimalsFor(xt)) << "</text>";
    }
    for (const auto& [values, colour] : {std::make_pair(&radial, "#c33"), std::make_pair(&tangential, "#36c")}) {
      svg << "<polyline fill='none' stroke='" << colour << "' stroke-width='2' points='";
      for (size_t k = 0; k < radius.size(); ++k) svg << X(radius[k]) << "," << Y((*values)[k]) << " ";
      svg << "'/>";
    }
    svg << "<text x='" << left + width / 2 << "' y='" << height + 40
        << "' font-size='10' text-anchor='middle'>distance from the principal point along the diagonal (px)</text>"
        << "<text x='" << left + width / 2 << "' y='" << height + 56 << "' font-size='10' text-anchor='middle'>"
        << "<tspan fill='#c33'>■ radial</tspan>   <tspan fill='#36c'>■ tangential</tspan> displacement (px)"
        << "</text></svg>";
    h << svg.str();
  }
  return h.str();
}

// The cameras' attitude against the flight type, and the GNSS drift model.
std::string AttitudeAndDrift(const json& r) {
  const json& att = r.value("adjustment", json::object()).value("attitude", json::object());
  const json& d = r.value("gps_drift", json::object());
  if (att.empty() && d.empty()) return "";
  std::ostringstream h;
  h << "<h2>Attitude and GNSS drift</h2><p>Viewing geometry: " << Escape(Text(att, "viewing", "–"))
    << ". Adjusted tilt from nadir: mean optical axis " << Num(Get(att, "mean_axis_tilt_deg"), 1) << "&deg;, median photo "
    << Num(Get(att, "median_tilt_deg"), 1) << "&deg;, largest " << Num(Get(att, "max_tilt_deg"), 1) << "&deg;.";
  if (att.value("ground_slope_points", 0) > 0) {
    h << " The ground's mean slope: " << Num(Get(att, "ground_slope_deg"), 1) << "&deg; (plane through "
      << att.value("ground_slope_points", 0) << " tie points).";
  }
  h << "</p>";
  if (att.contains("gimbal")) {
    const json& g = att["gimbal"];
    h << "<p>Against the photos' gimbal angles (" << g.value("images", 0) << " photos): the block "
      << Num(Get(g, "block_tilt_deg"), 1) << "&deg; off the vertical their pitches state; per photo pitch differs by "
      << Num(Get(g, "pitch_difference_median_deg"), 1) << "&deg; (median), " << Num(Get(g, "pitch_difference_max_deg"), 1)
      << "&deg; at most; headings by " << Num(Get(g, "yaw_difference_median_deg"), 1)
      << "&deg; (median) after a common compass offset of " << Num(Get(g, "yaw_bias_deg"), 1) << "&deg;.</p>";
  }
  h << "<p>GNSS drift: " << Escape(Text(d, "note", "–")) << ".";
  if (d.value("attitude_prior", false)) {
    h << " Tilt held by an attitude prior ("
      << (Text(d, "vertical_source", "") == "gimbal" ? "each photo's vertical from its gimbal pitch"
                                                     : "the nadir photos' optical axes down")
      << ") of " << Num(Get(d, "attitude_prior_sigma_deg_per_photo"), 0) << "&deg; per photo.";
  }
  h << "</p>";
  const json& flights = d.value("flights", json::array());
  if (d.value("estimated", false) && !flights.empty()) {
    h << "<table><tr><th>flight</th><th>photos</th><th>duration (s)</th><th>axis</th><th>trend found (m/s)</th>"
         "<th>estimated (m/s)</th><th>&sigma; (m/s)</th><th>over the flight (m)</th></tr>";
    const json& axes = d.value("axes", json::object());
    int k = 0;
    for (const auto& f : flights) {
      ++k;
      for (const char* a : {"e", "n", "u"}) {
        if (!axes.value(a, false)) continue;
        const std::string key = std::string(a) + "_m";
        const double rate = Get(f.value("rate_m_per_s", json::object()), key.c_str());
        h << "<tr><td>" << k << "</td><td>" << f.value("images", 0) << "</td><td>" << Num(Get(f, "duration_s"), 0)
          << "</td><td>" << (a[0] == 'e' ? "E" : a[0] == 'n' ? "N" : "U") << "</td><td>"
          << Num(Get(f.value("trend_m_per_s", json::object()), key.c_str()), 4) << "</td><td>" << Num(rate, 4)
          << "</td><td>" << Num(Get(f.value("rate_sigma_m_per_s", json::object()), key.c_str()), 4) << "</td><td>"
          << Num(rate * Get(f, "duration_s"), 1) << "</td></tr>";
      }
    }
    h << "</table>";
  }
  // The GPS offset(s) the adjustment estimated, with their sigmas.
  const json& offset = r.value("adjustment", json::object()).value("gps_offset", json::object());
  if (offset.value("estimated", false)) {
    json rows = offset.value("flights", json::array());
    if (rows.empty()) rows.push_back({{"offset", offset.value("offset", json::object())},
                                      {"sigma", offset.value("sigma", json::object())}});
    h << "<p>GPS offset estimated (GPS minus camera centre, east / north / up metres"
      << (offset.value("per_flight", false) ? ", one per flight" : "") << "):</p><table><tr><th>flight</th>"
      << "<th>photos</th><th>E</th><th>N</th><th>U</th><th>&sigma; E</th><th>&sigma; N</th><th>&sigma; U</th></tr>";
    for (const auto& f : rows) {
      const json& o = f.value("offset", json::object());
      const json& sg = f.value("sigma", json::object());
      h << "<tr><td>" << (f.contains("flight") ? std::to_string(f.value("flight", 0)) : std::string("all")) << "</td><td>"
        << (f.contains("photos") ? std::to_string(f.value("photos", 0)) : std::string("–")) << "</td>";
      for (const char* a : {"e_m", "n_m", "u_m"}) h << "<td>" << Num(Get(o, a), 3) << "</td>";
      for (const char* a : {"e_m", "n_m", "u_m"}) h << "<td>" << Num(Get(sg, a), 3) << "</td>";
      h << "</tr>";
    }
    h << "</table>";
  }
  return h.str();
}

// Tie points by the number of images measuring them.
std::string TrackTable(const json& r) {
  const json& t = r.value("adjustment", json::object()).value("tracks", json::object());
  if (!t.contains("by_length")) return "";
  std::ostringstream h;
  h << "<h2>Tie points</h2><p>" << t.value("tie_points", 0) << " tie points, measured in " << Num(Get(t, "mean_length"), 2)
    << " images on average (median " << t.value("median_length", 0) << ", at most " << t.value("max_length", 0)
    << ").</p><table><tr><th>images per point</th>";
  std::vector<std::string> keys;
  for (int n = 2; n < 10; ++n) keys.push_back(std::to_string(n));
  keys.push_back("10+");
  for (const auto& k : keys) h << "<th>" << k << "</th>";
  h << "</tr><tr><td>tie points</td>";
  for (const auto& k : keys) h << "<td>" << t["by_length"].value(k, 0) << "</td>";
  h << "</tr></table>";
  return h.str();
}

// Wall time and peak memory of every stage (timings.json).
std::string Timings(const json& r) {
  const json& t = r.value("timings", json::object());
  if (!t.is_object() || t.empty()) return "";
  static const char* kOrder[] = {"ingest", "features", "match", "reconstruct", "georeference", "dense", "ortho", "report"};
  std::ostringstream h;
  h << "<h2>Processing</h2><table><tr><th>stage</th><th>time (s)</th><th>peak memory (MB)</th></tr>";
  double total = 0.0;
  for (const char* stage : kOrder) {
    if (!t.contains(stage)) continue;
    total += Get(t[stage], "wall_s", 0.0);
    h << "<tr><td>" << stage << "</td><td>" << Num(Get(t[stage], "wall_s"), 1) << "</td><td>"
      << Num(Get(t[stage], "peak_rss_mb"), 0) << "</td></tr>";
  }
  h << "<tr class='total'><td>total</td><td>" << Num(total, 1) << "</td><td></td></tr></table>";
  return h.str();
}

}  // namespace

std::string HtmlEscape(const std::string& text) { return Escape(text); }

std::string Base64(const std::string& bytes) {
  static const char* kTable = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += kTable[(v >> 6) & 63];
    out += kTable[v & 63];
  }
  if (i < bytes.size()) {
    unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string RenderHtmlReport(const json& r, const std::string& hillshade_png) {
  return RenderHtmlReport(r, std::map<std::string, std::string>{{"dsm", hillshade_png}});
}

namespace {

// The page head: styles for screen and print.
std::string HtmlHead() {
  std::ostringstream h;
  h << "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>aerotri survey report</title><style>"
       "body{font-family:sans-serif;margin:2em auto;max-width:1000px;color:#222}"
       "h1{border-bottom:3px solid #4a7}h2{margin-top:1.6em;border-bottom:1px solid #ccc}"
       "table{border-collapse:collapse;margin:.5em 0;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;"
       "text-align:right}th{background:#eef}td:first-child{text-align:left}tr.total td{font-weight:bold;"
       "background:#f4f4f4}.cards{display:flex;flex-wrap:wrap;gap:10px}.card{border:1px solid #ccc;"
       "border-radius:6px;padding:8px 14px;min-width:140px}.card b{display:block;font-size:20px}"
       "svg.chart{width:100%;max-width:720px}svg.map{width:100%;max-width:600px}.warn{color:#a50}"
       "img.dsm{max-width:100%;border:1px solid #ccc}svg.dsm{width:100%;max-width:900px}"
       "p.asprs{background:#f4f8f4;border-left:4px solid #4a7;padding:6px 10px}"
       // Print (the browser's print-to-PDF): full width, no page breaks inside
       // a figure or table, headings kept with what follows.
       "@media print{@page{size:A4;margin:14mm}body{max-width:none;margin:0;font-size:11px}"
       "h1{font-size:20px}h2{font-size:15px;page-break-after:avoid;break-after:avoid}"
       "h3{page-break-after:avoid;break-after:avoid}svg,img,table,.cards,p.asprs{page-break-inside:avoid;"
       "break-inside:avoid}svg.chart,svg.map,svg.dsm{max-width:100%}a{color:inherit;text-decoration:none}}"
       "</style></head><body>";
  return h.str();
}

// Who made the report, and the status first: a failed survey must not look like any other.
std::string StatusSection(const json& r) {
  std::ostringstream h;
  if (r.contains("provenance") && r["provenance"].is_object()) {
    // Who made it, when, and how: the adjustment's process.
    const json& p = r["provenance"];
    std::string command;
    for (const auto& arg : p.value("command_line", json::array())) {
      if (arg.is_string()) command += (command.empty() ? "" : " ") + arg.get<std::string>();
    }
    h << "<p style='color:#555;font-size:12px'>" << Escape(Text(p, "software", "aerotri")) << "; adjusted "
      << Escape(Text(p, "date_utc", "")) << (command.empty() ? "" : " by <code>" + Escape(command) + "</code>")
      << "</p>";
  }
  {
    // The status first: a failed survey must not look like any other.
    const std::string status = Text(r, "status", "unknown");
    const char* colour = status == "ok" ? "#2a7a3a" : status == "warnings" ? "#a06000" : "#b00020";
    h << "<div style='border:2px solid " << colour << ";border-radius:6px;padding:8px 14px;margin:1em 0'>"
      << "<b style='color:" << colour << ";font-size:20px'>status: " << Escape(status) << "</b>";
    const auto& errors = r.value("errors", json::array());
    if (status == "failed") {
      h << " &mdash; this survey is not usable as it stands";
    }
    if (!errors.empty()) {
      h << "<ul>";
      for (const auto& e : errors) {
        h << "<li style='color:" << colour << "'>" << Escape(Text(e, "code", "")) << ": "
          << Escape(Text(e, "message", "")) << "</li>";
      }
      h << "</ul>";
    }
    const size_t num_warnings = r.value("warnings", json::array()).size();
    if (num_warnings > 0) h << "<div>" << num_warnings << " warnings: see the end of this report</div>";
    h << "</div>";
  }
  return h.str();
}

// The headline figures and the frame.
std::string SummaryCards(const json& r) {
  std::ostringstream h;
  const auto& images = r.value("images", json::object());
  const auto& adj = r.value("adjustment", json::object());
  h << "<div class='cards'>"
    << "<div class='card'>images registered<b>" << images.value("registered", 0) << " / " << images.value("total", 0)
    << "</b></div>"
    << "<div class='card'>reprojection RMS<b>" << Num(Get(adj, "final_rms_px"), 2) << " px</b></div>"
    << "<div class='card'>&sigma;<sub>0</sub> (redundancy " << adj.value("redundancy", 0) << ")<b>"
    << Num(Get(adj, "sigma0", NAN), 3) << "</b></div>"
    << "<div class='card'>GSD<b>" << Num(Get(r, "gsd_m", NAN) * 100, 1) << " cm</b></div>"
    << "<div class='card'>check points RMSE 3D<b>"
    << (r.value("check_points", json::object()).value("count", 0) > 0
            ? Num(Get(r.value("check_points", json::object()), "rmse_3d_m"), 3) + " m"
            : std::string("none"))
    << "</b></div>"
    << "<div class='card'>CRS<b style='font-size:14px'>" << Escape(Text(r, "crs_name", Text(r, "crs", "none")))
    << "</b></div></div>";
  h << "<p>CRS " << Escape(Text(r, "crs", "–")) << " (" << Escape(Text(r, "crs_source", ""))
    << "); adjustment in a local ENU frame at lat " << Num(Get(r.value("enu_origin", json::object()), "lat_deg"), 7)
    << ", lon " << Num(Get(r.value("enu_origin", json::object()), "lon_deg"), 7) << ", h "
    << Num(Get(r.value("enu_origin", json::object()), "h_m"), 2) << " m (WGS84 ellipsoid). Datum: "
    << Escape(Text(adj, "datum", "–")) << ".</p>";
  return h.str();
}

// Accuracy: the ASPRS statements, check, control and leave-one-out tables, the DSM at the check points.
std::string AccuracySection(const json& r) {
  std::ostringstream h;
  h << "<h2>Accuracy</h2>";
  const int num_checks = r.value("check_points", json::object()).value("count", 0);
  if (num_checks == 0) {
    // Nothing measured the accuracy: no statement, no zeros that read as one.
    h << "<p class='warn'><b>No check points:</b> the accuracy of this survey is not tested; no ASPRS "
         "statement can be made (ASPRS 2023 asks for at least 30 independent check points).</p>";
  } else if (r.contains("asprs")) {
    const auto& a = r["asprs"];
    h << "<table><tr><th>ASPRS statement (" << Escape(Text(a, "based_on", "")) << ")</th><th>value (m)</th></tr>"
      << "<tr><td>2014: horizontal accuracy at 95 % (1.7308 RMSE<sub>r</sub>)</td><td>"
      << Num(Get(a["edition_2014"], "horizontal_accuracy_95_m")) << "</td></tr>"
      << "<tr><td>2014: non-vegetated vertical accuracy at 95 % (1.96 RMSE<sub>z</sub>)</td><td>"
      << Num(Get(a["edition_2014"], "nva_95_m")) << "</td></tr>"
      << "<tr><td>2023: RMSE<sub>H</sub></td><td>" << Num(Get(a["edition_2023"], "rmse_h_m")) << "</td></tr>"
      << "<tr><td>2023: RMSE<sub>V</sub></td><td>" << Num(Get(a["edition_2023"], "rmse_v_m")) << "</td></tr>"
      << "<tr><td>2023: RMSE<sub>3D</sub></td><td>" << Num(Get(a["edition_2023"], "rmse_3d_m")) << "</td></tr></table>";
    h << AsprsStatement(a, r.value("check_points", json::object()).value("count", 0));
  }
  if (r.contains("check_points")) h << PointTable(r["check_points"], "Check points (never used in the adjustment)");
  if (r.contains("control_points")) h << PointTable(r["control_points"], "Control points");
  if (r.contains("leave_one_out") && r["leave_one_out"].contains("points")) {
    h << PointTable(r["leave_one_out"], "Control points, each withheld from its own adjustment (leave-one-out)");
  } else if (r.contains("leave_one_out")) {
    h << "<p>Leave-one-out: " << Escape(Text(r["leave_one_out"], "note", "")) << ".</p>";
  }
  if (num_checks > 0 && r.contains("dsm") && r["dsm"].contains("check_points")) {
    const auto& d = r["dsm"]["check_points"];
    h << "<h3>DSM at the check points</h3><table><tr><th>name</th><th>DSM − surveyed z (m)</th></tr>";
    for (const auto& p : d.value("points", json::array())) {
      h << "<tr><td>" << Escape(Text(p, "name", "")) << "</td><td>"
        << (p.contains("dz_m") ? Num(Get(p, "dz_m")) : std::string("outside the DSM")) << "</td></tr>";
    }
    h << "<tr class='total'><td>RMSE (" << d.value("count", 0) << " points)</td><td>" << Num(Get(d, "rmse_z_m"))
      << "</td></tr></table>";
  }
  return h.str();
}

// Camera positions against GPS, reprojection error per image, overlap and coverage.
std::string ResidualCharts(const json& r) {
  std::ostringstream h;
  const auto& images = r.value("images", json::object());
  std::vector<std::string> names;
  std::vector<double> de, dn, du;
  for (const auto& c : r.value("cameras", json::array())) {
    if (!c.value("gps_prior", false)) continue;
    names.push_back(Text(c, "name", ""));
    de.push_back(Get(c, "de_m"));
    dn.push_back(Get(c, "dn_m"));
    du.push_back(Get(c, "du_m"));
  }
  h << "<h2>Camera positions against GPS</h2><p>Adjusted camera centre minus its GPS position (east, north, up).</p>";
  if (static_cast<int>(names.size()) > kMaxBars) {
    std::vector<double> horizontal(de.size());
    for (size_t i = 0; i < de.size(); ++i) horizontal[i] = std::hypot(de[i], dn[i]);
    h << "<h3>Horizontal</h3>" << Distribution(names, horizontal, "cameras", "metres (horizontal)", 3)
      << "<h3>Up</h3>" << Distribution(names, du, "cameras", "metres (up)", 3);
  } else {
    h << BarChart(names, {de, dn, du}, {"east", "north", "up"}, {"#c33", "#36c", "#3a3"}, "metres");
  }

  std::vector<std::string> inames;
  std::vector<double> rms, pairs;
  for (const auto& im : images.value("per_image", json::array())) {
    if (!im.value("registered", false)) continue;
    inames.push_back(Text(im, "name", ""));
    rms.push_back(Get(im, "reprojection_rms_px"));
  }
  h << "<h2>Reprojection error per image</h2>"
    << PerLabelChart(inames, rms, "RMS", "#a6c", "images", "pixels (working resolution)", 3);
  std::vector<std::string> mnames;
  if (r.contains("matching")) {
    for (const auto& im : r["matching"].value("per_image", json::array())) {
      mnames.push_back(Text(im, "name", ""));
      pairs.push_back(im.value("verified_pairs", 0));
    }
    h << "<h2>Image overlap</h2><p>" << Escape(Text(r["matching"], "strategy", "")) << ": "
      << r["matching"].value("verified_pairs", 0) << " verified pairs of " << r["matching"].value("candidate_pairs", 0)
      << " candidates.</p>" << PerLabelChart(mnames, pairs, "verified pairs", "#e90", "images", "image pairs", 0);
  }
  h << "<h3>Coverage</h3>" << CoverageMap(r.value("coverage", json()));
  {
    // The DSM against the ground the photos cover (not against its raster).
    const json& fc = r.value("dsm", json::object()).value("footprint_coverage", json::object());
    const double seen = Get(fc, "seen_by_2_m2");
    if (std::isfinite(seen) && seen > 0.0) {
      const double fraction = Get(fc, "fraction");
      h << "<p" << (fraction < 0.9 ? " class='warn'" : "") << ">The DSM covers " << Num(100.0 * fraction, 1)
        << " % of the ground seen by two or more photos (" << Num(Get(fc, "covered_m2"), 0) << " of "
        << Num(seen, 0) << " m&sup2;; " << Num(Get(fc, "seen_by_exactly_2_m2"), 0)
        << " m&sup2; of it seen by exactly two photos, one stereo pair at most; "
        << Num(Get(fc, "seen_by_1_m2"), 0) << " m&sup2; more seen by one photo only).</p>";
    }
  }
  return h.str();
}

// The elevation model, terrain and orthomosaic previews.
std::string ElevationSection(const json& r, const std::map<std::string, std::string>& previews) {
  std::ostringstream h;
  const auto png_of = [&](const char* key) {
    const auto it = previews.find(key);
    return it == previews.end() ? std::string() : it->second;
  };
  const std::string hillshade_png = png_of("dsm");  // the DSM preview
  h << "<h2>Elevation model</h2>";
  if (!hillshade_png.empty()) {
    const auto& d = r.value("dsm", json::object());
    const double points = Get(r.value("dense", json::object()), "points"), cell = Get(d, "resolution_m");
    const double covered = Get(d, "cells_with_points") * cell * cell;
    h << "<p>" << Escape(Text(d, "file", "dsm.tif")) << ": " << d.value("width", 0) << " x "
      << d.value("height", 0) << " cells of " << Num(cell, 3) << " m, "
      << Num(100.0 * Get(d, "filled_fraction", NAN), 1) << " % with data; dense cloud "
      << Num(points / 1e6, 2) << " M points, " << Num(points / covered, 0) << " points/m&sup2; where the DSM has "
      << "points. Heights: " << Escape(Text(r.value("heights", json::object()), "description",
                                            "as " + Text(r, "crs", "") + " defines them"))
      << " (deliverables in " << Escape(Text(r.value("heights", json::object()), "crs", Text(r, "crs", "")))
      << "). " << CloudSentence(r.value("dense", json::object()).value("cloud", json::object())) << "</p>"
      << DsmFigure(hillshade_png, d.value("preview", json::object()));
    h << TerrainSection(r, png_of("dtm")) << OrthoSection(r, png_of("ortho"));
  } else if (r.contains("dense") && r["dense"].contains("skipped")) {
    h << "<p>No dense cloud or DSM: " << Escape(Text(r["dense"], "skipped")) << ".</p>";
  } else {
    h << "<p>No DSM.</p>";
  }
  return h.str();
}

// The images table, timings and the warnings.
std::string ImagesAndWarnings(const json& r) {
  std::ostringstream h;
  const auto& images = r.value("images", json::object());
  const size_t num_images = images.value("per_image", json::array()).size();
  h << "<h2>Images</h2>";
  // A long list stays folded (500 rows would bury what follows); print opens it.
  if (num_images > static_cast<size_t>(kMaxBars)) h << "<details><summary>" << num_images << " images</summary>";
  h << "<table><tr><th>image</th><th>registered</th><th>GPS</th><th>RMS (px)</th><th>note</th></tr>";
  for (const auto& im : images.value("per_image", json::array())) {
    h << "<tr><td>" << Escape(Text(im, "name", "")) << "</td><td>" << (im.value("registered", false) ? "yes" : "no")
      << "</td><td>" << (im.value("gps", false) ? "yes" : "no") << "</td><td>" << Num(Get(im, "reprojection_rms_px"), 2)
      << "</td><td class='warn'>" << Escape(Text(im, "why_not", "")) << "</td></tr>";
  }
  h << "</table>";
  if (num_images > static_cast<size_t>(kMaxBars)) h << "</details>";
  h << Timings(r);
  // Findings (the warnings already hold the ingest ones) and the check stage's.
  std::vector<std::string> warnings;
  for (const auto& w : r.value("warnings", json::array())) {
    warnings.push_back(w.is_string() ? w.get<std::string>()
                                     : Text(w, "code", "") + ": " + Text(w, "message", ""));
  }
  for (const auto& w : r.value("check_warnings", json::array())) warnings.push_back(w.is_string() ? w.get<std::string>() : w.dump());
  if (!warnings.empty()) {
    h << "<h2>Warnings</h2><ul>";
    for (const auto& w : warnings) h << "<li class='warn'>" << Escape(w) << "</li>";
    h << "</ul>";
  }
  return h.str();
}

}  // namespace

std::string RenderHtmlReport(const json& r, const std::map<std::string, std::string>& previews) {
  std::ostringstream h;
  h << HtmlHead();
  h << "<h1>aerotri survey report</h1>";
  h << StatusSection(r) << SummaryCards(r) << AccuracySection(r);
  h << AdjustmentStatistics(r);
  h << AttitudeAndDrift(r) << CameraCalibration(r) << TrackTable(r);
  h << "<h2>Survey map and residual vectors</h2>" << SurveyMap(r);
  h << ResidualCharts(r) << ElevationSection(r, previews) << ImagesAndWarnings(r);
  h << "<p style='color:#888;font-size:11px'>generated by aerotri</p></body></html>\n";
  return h.str();
}

}  // namespace aerotri
