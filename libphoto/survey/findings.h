// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What a survey's adjustment tells its user beyond the figures: findings
// (warnings and errors) with a stable code, a sentence and the images or
// points concerned, and the survey's status derived from them. A survey with
// an error finding has status "failed": the pipeline does not write its
// deliverables as if valid and the command exits 1.
//
// Codes (stable; report.json "warnings" / "errors"):
//   ADJUSTMENT_NOT_CONVERGED   warning  solver stopped before convergence
//   REPROJECTION_RMS_HIGH      error    final RMS above QualityGates::max_rms_px
//   REPROJECTION_RMS_GREW      error    final RMS a multiple of the initial one
//   GPS_INCONSISTENT           warning  cameras farther from their GPS than k sigma
//   GPS_MOSTLY_INCONSISTENT    error    more than half of them
//   GPS_CONTROL_OFFSET         warning  GPS and control differ by a constant offset
//   GPS_REJECTED               warning  GPS fixes left out against the control datum
//   GPS_OFFSET_NOT_ESTIMATED   warning  --gps-offset always without control to hold it
//   CONTROL_INCONSISTENT       warning  control points left out of the initial fit
//   CONTROL_RESIDUAL_HIGH      warning  control residuals beyond k sigma
//   CONTROL_WEAKER_THAN_STATED warning  control scatter several times its stated sigmas (the estimate is used)
//   SIGMAS_OPTIMISTIC          warning  an observation group (ties, marks, GPS) scatters 3+ times its stated sigma
//   CONTROL_OUTSIDE_SURVEY     error    surveyed points outside the photographed area (left out)
//   CHECK_POINTS_FAR           warning  check points beyond their predicted sigmas (w-test);
//                              error    most of them far beyond (a misplaced survey)
//   CHECK_POINTS_OFFSET        error    the check points share an offset far beyond their sigmas
//   PRIORS_INCONSISTENT        warning  priors left out of the initial fit
//   DOME                       warning  vertical residuals domed across the block
//   MARK_BLUNDER               warning  Baarda's w-test rejects a target mark at the family-wise
//                                       level (QualityGates::mark_family_alpha) (point, image)
//   MARKS_OFFSET               warning  one photo's (or one point's) marks share an offset: systematic
//   MARK_DUPLICATED            warning  one target labelled as two points in one photo
//   GPS_DRIFT                  warning  GPS positions trend in time: a drift per flight estimated
//   GPS_TILT_REJECTED          warning  GPS heights would tilt a nadir block; levelled by its attitude
//   CAMERA_ATTITUDE_IMPLAUSIBLE error   a nadir block adjusted more than 10 deg off vertical
//   GIMBAL_ATTITUDE_DISAGREES  warning  the block's mean optical axis more than 3 deg from its gimbals';
//                              error    more than 10 deg
//   PRECISION_NOT_COMPUTED     warning  posterior sigmas and the w-test are missing (why)
//   FOCAL_WEAKLY_DETERMINED    warning  f refined as asked on a block that cannot carry it
//   INTRINSICS_CORRELATED      warning  f or the principal point correlated beyond 0.9 with another intrinsic
//   IMAGES_NOT_REGISTERED      warning  photos left out of the model
//   MODEL_SPLIT                warning  groups of photos with no tie points between them, placed by GPS
//   NOTHING_REGISTERED         error    fewer than two photos in the model: no survey
//   NOT_GEOREFERENCED          warning  no GPS and no control: arbitrary frame and scale
//   INPUT                      warning  a problem with an input file (skipped)

#include <string>
#include <vector>

namespace aerotri {

enum class Severity { kWarning, kError };

struct Finding {
  Severity severity = Severity::kWarning;
  std::string code;
  std::string message;             // one sentence a surveyor can act on
  std::vector<std::string> items;  // images or points concerned

  static Finding Warning(std::string code, std::string message, std::vector<std::string> items = {});
  static Finding Error(std::string code, std::string message, std::vector<std::string> items = {});
};

// Limits of the adjustment's quality gates.
struct QualityGates {
  double max_rms_px = 3.0;          // final reprojection RMS (working pixels)
  double max_rms_growth = 2.0;      // final / initial RMS, when the final is above 1 px
  double gps_sigma_multiple = 4.0;  // a camera this many sigma from its GPS is inconsistent
  double max_gps_inconsistent_fraction = 0.5;  // beyond: an error
  // GPS residuals (horizontal RMS) beyond this fraction of the camera
  // layout's spread: the GPS does not belong to the photos (an error).
  double max_gps_residual_over_layout = 0.5;
  double control_sigma_multiple = 5.0;
  // Check points: this many sigma of their survey and of the datum, and at
  // least min_check_threshold_m (their triangulation from images adds a few
  // GSD that no sigma here states).
  double check_sigma_multiple = 5.0;
  double min_check_threshold_m = 0.1;
  // Each check point's residual, per axis, over its full predicted sigma
  // (the posterior covariance of its adjusted or triangulated position plus
  // its survey's): rejected beyond the critical value of this family-wise
  // size over all the check points' tests (CHECK_POINTS_FAR, a warning).
  double check_family_alpha = 0.01;
  // The survey misplaced against its check points (an error): more than half
  // of them rejected, and either a common offset beyond this many predicted
  // sigmas that explains them (CHECK_POINTS_OFFSET), or normalised residuals
  // beyond check_gross_multiple (CHECK_POINTS_FAR).
  double check_offset_multiple = 10.0;
  double check_gross_multiple = 20.0;
  // A significant dome (DomeTest::significant) larger than this many GSD is a warning.
  double max_dome_gsd = 2.0;
  // Data snooping: MARK_BLUNDER when the largest |w| of the marks is
  // significant at this family-wise level over all their tests (Sidak), so
  // that a clean survey is flagged in at most this share of cases at any
  // size; marks beyond the per-test 3.29 (alpha0 0.1 %) are listed as
  // suspect without raising the status.
  double mark_family_alpha = 0.01;
};

// "ok" (no findings), "warnings", or "failed" (any error).
std::string SurveyStatus(const std::vector<Finding>& findings);

// "name1, name2, ... (and N more)": at most max names.
std::string JoinNames(const std::vector<std::string>& names, size_t max = 10);

}  // namespace aerotri
