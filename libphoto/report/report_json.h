// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// report.json: the machine-readable survey report. Keys (all lengths in
// metres, pixels in px):
//   crs, crs_name, crs_source, enu_origin {lat_deg, lon_deg, h_m},
//   control_points / check_points {count, rmse_x_m, rmse_y_m, rmse_z_m,
//     rmse_h_m, rmse_3d_m, mean_*_m, residuals_frame, points[{name, dx_m,
//     dy_m, dz_m, reprojection_rms_px, images, solved, why_not}]},
//   asprs {edition_2014 {horizontal_accuracy_95_m, nva_95_m},
//          edition_2023 {rmse_h_m, rmse_v_m, rmse_3d_m}},
//   cameras [{name, gps_prior, gps_prior_rejected, de_m, dn_m, du_m}]
//     (residuals after the estimated GPS offset),
//   gps_vs_control {cameras, consistent, offset, offset_sigma,
//     rms_after_offset {e_m, n_m, u_m}, significant, rejected[]} or null,
//   adjustment {initial_rms_px, final_rms_px, iterations, termination, datum,
//     gps_offset {estimated, offset {e_m, n_m, u_m}}, helmert {datum_source, ...},
//     intrinsics [{camera, model, params{name: value}}], ...},
//   status "ok" | "warnings" | "failed",
//   warnings [{code, message, items[]}], errors [{code, message, items[]}]
//     (codes: libphoto/adjust/findings.h).

#include <nlohmann/json.hpp>

#include "libphoto/adjust/georeferencing.h"

namespace aerotri {

nlohmann::json FindingsJson(const std::vector<Finding>& findings, Severity severity);
nlohmann::json BundleSummaryJson(const BundleSummary& summary, const SparseModel& model);
nlohmann::json GeoreferenceReportJson(const GeoreferenceReport& report, const SparseModel& model);

}  // namespace aerotri
