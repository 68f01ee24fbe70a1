// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// report.json: the machine-readable survey report. Keys (all lengths in
// metres, pixels in px):
//   crs, crs_name, crs_source, enu_origin {lat_deg, lon_deg, h_m},
//   control_points / check_points / leave_one_out {count, rmse_x_m, rmse_y_m,
//     rmse_z_m, rmse_h_m, rmse_3d_m, mean_*_m, residuals_frame, points[{name,
//     dx_m, dy_m, dz_m, sigma_x_m, sigma_y_m, sigma_z_m, reprojection_rms_px,
//     images, solved, why_not}]} (leave_one_out: each control point withheld
//     from its own adjustment; {computed: false, note} when not run),
//   asprs {edition_2014 {horizontal_accuracy_95_m, nva_95_m},
//          edition_2023 {rmse_h_m, rmse_v_m, rmse_3d_m}},
//   cameras [{name, gps_prior, gps_prior_rejected, de_m, dn_m, du_m,
//     position, omega_phi_kappa_deg, sigma_position_m,
//     sigma_omega_phi_kappa_deg}] (GPS residuals after the estimated offset;
//     exterior_orientation {position, angles, sigmas} states the conventions),
//   gps_vs_control {cameras, consistent, offset, offset_sigma,
//     rms_after_offset {e_m, n_m, u_m}, significant, rejected[]} or null,
//   adjustment {initial_rms_px, final_rms_px, iterations, termination, datum,
//     gps_offset {estimated, offset {e_m, n_m, u_m}}, helmert {datum_source, ...},
//     intrinsics [{camera, model, params{name: value}}], sigma0, redundancy,
//     chi2_test, precision {computed, note, variance_factor, check_points,
//     gps_offset_sigma}, data_snooping {critical_value, alpha, tests,
//     family_alpha, critical_value_family, suspects,
//     expected_suspects_without_blunders, marks[{point, image, role,
//     residual_px, redundancy, w, suspect, rejected}]}, ...},
//   status "ok" | "warnings" | "failed",
//   warnings [{code, message, items[]}], errors [{code, message, items[]}]
//     (codes: libphoto/survey/findings.h).

#include <nlohmann/json.hpp>

#include "libphoto/survey/georeferencing.h"

namespace aerotri {

nlohmann::json FindingsJson(const std::vector<Finding>& findings, Severity severity);
nlohmann::json BundleSummaryJson(const BundleSummary& summary, const SparseModel& model);
// Adds to each of adjustment["intrinsics"] whose camera (id k) has a known
// pixel pitch (pixel_size_mm[k - 1] > 0, working resolution) its calibration
// in the photogrammetric convention, "mm": camera constant c, principal
// point x0, y0 from the image centre with y up the image, their posterior
// sigmas (from adjustment["intrinsics_precision"]), the pitch and k1-k3,
// p1, p2 as they are (unit-free on pixel-normalised coordinates), and
// where the pitch came from (pixel_size_source: "EXIF", "the camera file").
void AddIntrinsicsInMm(nlohmann::json* adjustment, const std::vector<double>& pixel_size_mm,
                       const std::string& pixel_size_source = "EXIF");
nlohmann::json GeoreferenceReportJson(const GeoreferenceReport& report, const SparseModel& model);

// exterior_orientation.csv: one line per registered image, the centre in
// the output CRS, omega / phi / kappa (degrees) and their posterior sigmas,
// under '#' lines that state the CRS and the angle convention.
std::string ExteriorOrientationCsv(const GeoreferenceReport& report);

}  // namespace aerotri
