// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// report.html: a self-contained page (no external files, opens offline) that a
// surveyor can hand to a client: summary, ASPRS accuracy statements, check
// and control point tables, a map of the survey with horizontal residual
// vectors, camera GPS residuals, per-image reprojection error, image overlap
// and coverage, and the DSM as a hillshade. Plots are inline SVG; the
// hillshade is an inline PNG.

#include <nlohmann/json.hpp>
#include <string>

namespace aerotri {

// report: the content of report.json; hillshade_png: PNG bytes or empty.
std::string RenderHtmlReport(const nlohmann::json& report, const std::string& hillshade_png);

std::string Base64(const std::string& bytes);

}  // namespace aerotri
