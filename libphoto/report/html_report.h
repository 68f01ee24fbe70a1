// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// report.html: a self-contained page (no external files, opens offline) that a
// surveyor can hand to a client, in the order of a photogrammetric quality
// report: status, summary, ASPRS accuracy statements (with the 2023 class
// sentence), check and control point tables, adjustment statistics, camera
// calibration (initial and adjusted intrinsics with their sigmas, a
// distortion plot), tie points by track length, a map of the survey with
// horizontal residual vectors, camera GPS residuals, per-image reprojection
// error and image overlap (as distributions above 60 images), coverage with
// its colour scale, the DSM as a shaded elevation preview with its legend and
// scale bar, dense density, and time and memory per stage. Plots are inline
// SVG, the DSM preview an inline PNG; a print stylesheet makes the browser's
// print-to-PDF a clean A4 document.

#include <nlohmann/json.hpp>
#include <algorithm>
#include <array>
#include <map>
#include <string>

namespace aerotri {

// report: the content of report.json (report["dsm"]["preview"] describes
// the preview); dsm_preview_png: PNG bytes or empty.
std::string RenderHtmlReport(const nlohmann::json& report, const std::string& dsm_preview_png);
// The same with every preview: PNG bytes by product ("dsm", "dtm", "ortho";
// their figures' scale bars and legends come from report.json's "preview").
std::string RenderHtmlReport(const nlohmann::json& report, const std::map<std::string, std::string>& previews);

std::string Base64(const std::string& bytes);
// Text for HTML: < > & " escaped.
std::string HtmlEscape(const std::string& text);

// The DSM preview's elevation colours, t = 0 (low) to 1 (high): blue, green,
// yellow, brown, white. The preview and its legend both use it.
inline std::array<double, 3> ElevationRampColour(double t) {
  static const double kStops[5][3] = {{40, 90, 170}, {60, 160, 90}, {230, 220, 110}, {170, 110, 60}, {245, 245, 245}};
  t = std::clamp(t, 0.0, 1.0) * 4.0;
  const int k = std::min(3, static_cast<int>(t));
  const double u = t - k;
  return {(1 - u) * kStops[k][0] + u * kStops[k + 1][0], (1 - u) * kStops[k][1] + u * kStops[k + 1][1],
          (1 - u) * kStops[k][2] + u * kStops[k + 1][2]};
}

}  // namespace aerotri
