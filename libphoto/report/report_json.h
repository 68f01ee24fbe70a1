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
//   cameras [{name, gps_prior, de_m, dn_m, du_m}],
//   adjustment {initial_rms_px, final_rms_px, iterations, termination, datum,
//     intrinsics [{camera, model, params{name: value}}], ...},
//   warnings [].

#include <nlohmann/json.hpp>

#include "libphoto/adjust/georeferencing.h"

namespace aerotri {

nlohmann::json BundleSummaryJson(const BundleSummary& summary, const SparseModel& model);
nlohmann::json GeoreferenceReportJson(const GeoreferenceReport& report, const SparseModel& model);

}  // namespace aerotri
