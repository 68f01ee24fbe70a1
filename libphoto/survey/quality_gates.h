// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The survey adjustment's quality gates (findings.h QualityGates): each
// gate reads the adjusted model and the report and adds its findings.

#include "libphoto/model/sparse_model.h"
#include "libphoto/survey/georeferencing.h"

namespace aerotri {

// Every gate below, in the report's order: convergence and reprojection
// RMS, GPS residuals, check points, dome, control residuals.
void ApplyQualityGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report);

// ADJUSTMENT_NOT_CONVERGED, REPROJECTION_RMS_HIGH / REPROJECTION_RMS_GREW
// (naming the images whose own RMS is above the limit, worst first).
void ReprojectionGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report);

// GPS residuals (after the estimated offset) against their sigmas:
// GPS_INCONSISTENT, or GPS_MOSTLY_INCONSISTENT beyond the fraction.
// With the GPS's sigma estimated, a GPS whose residuals are comparable with
// the spread of the photos' own layout (horizontally) does not follow the
// model at all (positions matched to the wrong photos, another survey's):
// GPS_MOSTLY_INCONSISTENT, whatever its estimated sigma.
void GpsGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report);

// Control points farther from their survey than control_sigma_multiple
// sigma (the names, for CONTROL_RESIDUAL_HIGH).
std::vector<std::string> ControlPointsBeyondSigmas(const SparseModel& model, const QualityGates& gates,
                                                   const GeoreferenceReport& report);

// Check points against what the datum allows (CHECK_POINTS_FAR).
void CheckPointGates(const SparseModel& model, const QualityGates& gates, GeoreferenceReport* report);

// A dome (or bowl) across the block beyond max_dome_gsd (DOME).
void DomeGate(const QualityGates& gates, GeoreferenceReport* report);

}  // namespace aerotri
