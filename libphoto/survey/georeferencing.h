// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Georeferenced adjustment of a sparse model: gauge and scale come from GPS
// positions of the camera centres and from surveyed ground control points,
// the adjustment runs in a local ENU frame (metres) tangent at the survey's
// reference point, and accuracy is measured on independent check points.
//
//  1. Control and check points are converted from their file's CRS to WGS84
//     geodetic through PROJ; the ENU origin is the mean GPS position (or the
//     mean control point when there is no GPS).
//  2. Control points are triangulated in the model's own frame and a robust
//     similarity (Helmert) maps the model onto the datum, so a model in any
//     frame and scale converges. With three or more non-collinear control
//     points triangulated, the datum comes from control alone and the GPS is
//     judged against it: its constant offset from the control datum (GNSS
//     antenna or height-reference error) is measured and, when significant,
//     estimated in the adjustment (GpsOffsetPolicy); GPS positions that still
//     disagree are named and left out. Otherwise camera GPS and control are
//     fitted together.
//  3. Bundle adjustment with GPS priors (horizontal / vertical sigmas) on the
//     camera centres and surveyed priors on the control points; with three
//     or more non-collinear priors no camera is held fixed.
//  4. Check points never enter steps 2–3: afterwards they are triangulated
//     from their image observations alone and compared with their surveyed
//     coordinates in the output CRS.

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "georef/accuracy.h"
#include "georef/crs.h"
#include "georef/gcp_file.h"
#include "georef/local_frame.h"
#include "georef/similarity.h"
#include "libphoto/survey/block_geometry.h"
#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/survey/findings.h"
#include "libphoto/survey/gnss_drift.h"
#include "libphoto/base/progress.h"
#include "georef/gps_fix.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {

// When the adjustment estimates a constant GPS offset (GPS minus camera
// centre, shared by all images): never; when the control datum shows a
// significant one (kAuto: beyond 3 standard errors of the mean and beyond the
// GPS sigma); or whenever three or more control points anchor the datum
// (kAlways). kPerFlight: as kAlways, one offset per flight (photos split
// into flights by capture time, gnss_drift.h SplitFlights), each judged
// about its own; one flight is kAlways.
enum class GpsOffsetPolicy { kNever, kAuto, kAlways, kPerFlight };
std::string ToString(GpsOffsetPolicy policy);
std::optional<GpsOffsetPolicy> ParseGpsOffsetPolicy(const std::string& text);

// The survey adjustment's product defaults, one definition for `aerotri run`,
// `aerotri adjust` and library callers alike: Huber loss departing at 1 px,
// observations beyond 4 px rejected and the block re-solved, intrinsics
// refined only for camera groups seen by 3 or more images. (BundleOptions'
// own defaults are the BAL literature's plain least squares.)
BundleOptions SurveyBundleOptions();

struct GeoreferenceOptions {
  std::string output_crs;       // empty: the control file's CRS, else UTM
  // The adjustment frame's (ENU) origin, e.g. the workspace's; none: the
  // mean GPS of the model's registered images, else the mean control point.
  // Not used in a LOCAL frame, which adjusts in the file's own coordinates.
  std::optional<Geodetic> enu_origin;
  double gcp_sigma_h_m = 0.02;  // when the file gives none
  double gcp_sigma_v_m = 0.03;
  // Helmert inlier threshold (m); 0 picks 5x the largest prior sigma, at
  // least 0.5 m.
  double helmert_inlier_m = 0.0;
  // Keep the control file's sigmas even when the control scatters far more
  // (GeoreferenceReport::control_precision); by default the estimate is used
  // where the sigmas are defaults, and where the file states them, the
  // adjustment's own variance component for the control decides.
  bool keep_stated_control_sigmas = false;
  // With variance components estimated (bundle.estimate_variance_components):
  // observation groups whose every sigma is stated in the survey's files
  // (sigma_px= on every mark or tie, sigmas on every control point) are held
  // at them, the stochastic model as the survey states it (a published
  // block's convention); the groups with default sigmas (matched ties, EXIF
  // GPS) are estimated. false: every group with enough redundancy estimated.
  bool hold_stated_sigmas = true;
  // Control whose heights are all exactly 0 (OpenDroneMap's documentation
  // suggests 0 for an unknown height) is used in plan only, and said
  // (CONTROL_HEIGHTS_ZERO); true: 0 is their surveyed height.
  bool zero_heights_are_heights = false;
  GpsOffsetPolicy gps_offset = GpsOffsetPolicy::kAuto;
  // Gimbal angles by image name (DJI XMP): where the block is not nadir,
  // their pitches give its vertical (MeasureGimbalVertical), so that GPS
  // heights drifting in time cannot tilt an oblique block either. Not used
  // in a LOCAL frame.
  std::map<std::string, GimbalAttitude> gimbal;
  // Rolling shutters by image name: readout time and velocity (ENU m/s) as
  // the photos state them (RollingShutterMotion, sparse_model.h); an image
  // without an entry is exposed at once (a global shutter). Where they came
  // from, for the report. Not used in a LOCAL frame.
  std::map<std::string, RollingShutterMotion> rolling_shutter;
  std::string rolling_shutter_source;
  bool model_rolling_shutter = true;  // false: every photo a global shutter's
  // With model_rolling_shutter: each camera group's readout time estimated
  // in the adjustment, with its sigma (the photos' velocities as stated; their
  // stated readouts only the start), so photos that state a velocity but no
  // readout are modelled too.
  bool estimate_readout = false;
  QualityGates gates;
  // true: every intrinsic is refined where the block determines it: a focal
  // length whose a-priori sigma exceeds weak_focal_rel of its value (the
  // block knows it no better than an EXIF value does) is held at its EXIF /
  // certificate prior (bundle.focal_prior_px) and the block solved again;
  // without a prior it stays refined and is flagged. false:
  // bundle.refine_intrinsics as given, a weak focal length flagged.
  bool auto_refine = true;
  double weak_focal_rel = 0.01;
  // After the adjustment, each control point in turn is withheld: the block
  // adjusted again without it (same options, same start) and the point
  // triangulated as an independent check (GeoreferenceReport::
  // leave_one_out). Needs 4 or more control points (3 still hold the datum).
  bool leave_one_out = false;
  // Posterior sigmas and the marks' w-test after the adjustment
  // (BundleOptions::compute_precision); leave-one-out's own adjustments,
  // which report only the withheld point's residual, go without.
  bool posterior_precision = true;
  BundleOptions bundle = SurveyBundleOptions();
  ProgressCallback progress;

  // Throws InvalidArgument naming the option, its value and the range
  // (the bundle's options included), CrsError for an output CRS PROJ
  // cannot create.
  void Check() const;
};

struct GroundPointResult {
  std::string name;
  PointRole role = PointRole::kControl;
  bool solved = false;     // false: see why_not
  std::string why_not;
  int num_images = 0;      // measurements on images of the model
  // Control in plan only (GroundPoint::horizontal_only): d_m.z() and
  // surveyed_crs.z() are NaN, and the point is not in control_stats.
  bool horizontal_only = false;
  Eigen::Vector3d surveyed_crs = Eigen::Vector3d::Zero();  // output CRS
  Eigen::Vector3d adjusted_crs = Eigen::Vector3d::Zero();
  Eigen::Vector3d d_m = Eigen::Vector3d::Zero();  // adjusted − surveyed (m)
  double reprojection_rms_px = 0.0;
  // Posterior standard deviations of the adjusted (control, check in the
  // bundle) or triangulated (independent check) position, on the axes of d_m.
  bool has_precision = false;
  Eigen::Vector3d sigma_m = Eigen::Vector3d::Zero();
  // Check points (CheckPointGates): each residual over its full predicted
  // sigma, the posterior sigma (sigma_m) and the survey's own combined
  // (predicted_sigma_m), per axis; rejected beyond the family-wise critical
  // value (GeoreferenceReport::check_test).
  bool tested = false;
  Eigen::Vector3d predicted_sigma_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  bool rejected = false;
};

// Baarda's w-test of one target mark (MarkTest), by name.
struct MarkResult {
  std::string point;
  std::string image;
  PointRole role = PointRole::kControl;
  Eigen::Vector2d residual_px = Eigen::Vector2d::Zero();  // adjusted − observed
  Eigen::Vector2d redundancy = Eigen::Vector2d::Zero();
  Eigen::Vector2d w = Eigen::Vector2d::Zero();
  bool suspect = false;   // |w| above the per-test critical value (alpha0 0.1 %)
  bool rejected = false;  // the largest |w|, above the family-wise critical value: MARK_BLUNDER
};

// The two-sided standard-normal critical value at level alpha in (0, 1):
// P(|z| > c) = alpha (3.29 at 0.1 %).
double TwoSidedNormalCriticalValue(double alpha);

// The critical value for the largest |w| of `tests` independent tests at the
// family-wise level family_alpha (Sidak: each at 1 - (1 - family_alpha)^(1/
// tests)). One test: TwoSidedNormalCriticalValue(family_alpha).
double FamilyWiseCriticalValue(int tests, double family_alpha);

// Data snooping's decision over the marks (one test per image axis with a
// redundancy above 1e-6). Marks with |w| > w_critical are marked suspect;
// the one with the largest |w|, when it exceeds w_critical_family, is
// marked rejected and named by the returned MARK_BLUNDER warning (one at a
// time: a blunder raises its neighbours' w too, less). No finding when
// nothing exceeds w_critical_family.
//
// Before it, systematic offsets (FindMarkOffsets) are said as MARKS_OFFSET;
// a worst mark that belongs to such a group is not named alone.
std::vector<Finding> SnoopMarks(std::vector<MarkResult>* marks, double w_critical, double w_critical_family,
                                double family_alpha = 0.01);

// The marks of one image (or of one point) sharing an offset on one axis:
// their mean w, sqrt(k) times (unit variance without an offset), beyond the
// family-wise critical value over every group's two axis tests, also without
// its largest |w| (one blunder is not an offset), two thirds of them on its
// side. Three or more marks per group; the most significant first.
struct MarkOffset {
  bool all = false;       // every mark of the survey (against its ties)
  bool per_image = true;  // the marks of image `name`, else of point `name`
  std::string name;
  int axis = 0;           // 0: x, 1: y
  int marks = 0;
  int same_sign = 0;
  double mean_residual_px = 0.0;
  double z = 0.0;
  double critical_value = 0.0;
  std::vector<int> members;  // indices into the marks
};
std::vector<MarkOffset> FindMarkOffsets(const std::vector<MarkResult>& marks, double family_alpha);
int CountMarkTests(const std::vector<MarkResult>& marks);

struct CameraResult {
  std::string name;
  bool has_prior = false;
  // The GPS position disagreed with the control datum beyond the threshold
  // (after the offset): left out of the adjustment, still reported.
  bool prior_rejected = false;
  // adjusted + GPS offset (+ drift) − GPS (E, N, U): the prior's residual
  Eigen::Vector3d d_enu_m = Eigen::Vector3d::Zero();
  double sigma_h_m = 0.0;
  double sigma_v_m = 0.0;
  int flight = -1;  // the GPS prior's flight, where flights were told apart (drift, per-flight offsets)
  // Exterior orientation in the output CRS: the centre, and ω, φ, κ of
  // R = Rx(ω) Ry(φ) Rz(κ), the rotation from the photo frame (x right, y up
  // the image, z towards the viewer, out of the lens) to the CRS's grid axes
  // (easting, northing, up; for a geographic CRS the local east, north, up).
  // A nadir photo with its top to the north has ω = φ = κ = 0.
  Eigen::Vector3d position_crs = Eigen::Vector3d::Zero();
  Eigen::Vector3d opk_deg = Eigen::Vector3d::Zero();
  bool has_precision = false;
  Eigen::Vector3d sigma_position_m = Eigen::Vector3d::Zero();  // on the grid axes
  Eigen::Vector3d sigma_opk_deg = Eigen::Vector3d::Zero();
};

// Camera GPS against a datum fixed by control alone (step 2), before the
// adjustment: GPS minus the camera centres that the control similarity gives.
struct GpsVersusControl {
  bool measured = false;     // false: fewer than 3 control points anchored the datum
  int cameras = 0;           // with GPS
  int consistent = 0;        // within the threshold after the offset
  Eigen::Vector3d offset_enu_m = Eigen::Vector3d::Zero();  // mean over the consistent ones
  // Per flight, under GpsOffsetPolicy::kPerFlight with two or more flights.
  std::vector<Eigen::Vector3d> flight_offsets_enu_m;
  Eigen::Vector3d offset_sigma_m = Eigen::Vector3d::Zero();  // its standard error
  Eigen::Vector3d rms_after_offset_m = Eigen::Vector3d::Zero();
  bool significant = false;
  std::vector<std::string> rejected;  // images whose GPS left the adjustment
};

// The GNSS drift analysis (gnss_drift.h): whether the GPS errors trend in
// time, what the adjustment estimated, and whether an attitude prior (the
// nadir photos' optical axes, or an oblique block's gimbal pitches) held the
// block's tilt.
struct GpsDriftReport {
  bool tested = false;
  std::string note;               // what was tested, or why not
  double gps_fit_tilt_deg = 0.0;  // the block's tilt had the GPS alone placed it (full similarity)
  bool estimated = false;         // the drift model entered the adjustment
  std::array<bool, 3> axes = {false, false, false};  // E, N, U estimated
  bool attitude_prior = false;    // the attitude prior held the tilt
  double attitude_prior_sigma_deg = 0.0;
  // The vertical the block was levelled by (and the prior's): "nadir" (the
  // mean optical axis of nadir photos) or "gimbal" (the photos' gimbal
  // pitches, GimbalVertical); empty: none found (a block neither nadir nor
  // with gimbal angles: the GPS alone sets its tilt).
  std::string vertical_source;
  struct Flight {
    int images = 0;
    double duration_s = 0.0;
    Eigen::Vector3d trend_m_per_s = Eigen::Vector3d::Zero();  // in the initial residuals
    Eigen::Vector3d trend_sigma = Eigen::Vector3d::Zero();
    Eigen::Vector3d rate_m_per_s = Eigen::Vector3d::Zero();   // estimated in the adjustment
    Eigen::Vector3d rate_sigma = Eigen::Vector3d::Zero();     // posterior; 0 where held or not computed
  };
  std::vector<Flight> flights;
};

// Leave-one-out over the control points: each one's residual when it is
// withheld from its own adjustment (an honest error figure beside the
// control residuals, which the adjustment pulls towards zero).
struct LeaveOneOut {
  bool computed = false;
  std::string note;  // why not, when !computed
  std::vector<GroundPointResult> points;  // role kControl; d_m as a check point
  AccuracyStats stats;
  int adjustments = 0;  // solves: the one the updates come from, and re-solves
  int updated = 0;      // points from the block-deletion update, without a re-solve
  int iterations = 0;  // of every solve, together
  double time_s = 0.0;
};

struct GeoreferenceReport {
  // Per camera group: the shutter as modelled. "rolling": its photos' rows
  // exposed as the camera moved (the readout time, median over the group's
  // photos, and their mean speed); "global": every row at once.
  struct Shutter {
    int camera = 0;  // the camera group's id (as adjustment.intrinsics names it)
    std::string model = "global";
    int images = 0;  // registered photos with their motion modelled
    double readout_time_s = 0.0;
    double readout_sigma_s = 0.0;  // when estimated with the precision
    bool readout_estimated = false;
    double readout_stated_s = 0.0;  // the photos' own (median; 0: none stated)
    double mean_speed_mps = 0.0;
    std::string source;
  };
  std::vector<Shutter> shutters;
  std::string crs;       // as given or chosen
  std::string crs_name;  // PROJ's name
  std::string crs_source;  // "--crs", "control file", "UTM zone of the survey centre"
  bool residuals_in_crs_units = true;  // false for a geographic CRS: ENU metres
  // The axes of every residual and sigma (d_m, sigma_m), in words: the grid
  // axes of a projected CRS, a local frame's x, y, z, or local ENU metres for
  // a geographic or geocentric CRS (never geocentric X, Y, Z as if one were
  // vertical).
  std::string axes;
  // The output CRS as used (a local frame with its coordinates' origin).
  std::optional<Crs> output_crs;
  std::optional<Eigen::Vector3d> local_origin;  // of a local frame (file units)
  Geodetic enu_origin;
  std::string datum_source;  // what the initial similarity was fitted to
  // How well the survey is placed in its CRS: the cameras' posterior
  // position sigmas (median, horizontal as the root-sum-square of the two
  // axes' and vertical), with every group weighed as the adjustment
  // estimated it (ReportVarianceComponents).
  struct PlacementAccuracy {
    bool computed = false;
    double sigma_h_m = 0.0;
    double sigma_v_m = 0.0;
  } placement;
  int helmert_correspondences = 0;
  int helmert_inliers = 0;
  double helmert_rms_m = 0.0;
  GpsVersusControl gps_vs_control;
  // The block's viewing geometry in its own frame (before the similarity),
  // and its cameras' tilt from nadir after the adjustment.
  ViewingGeometry viewing;
  GimbalVertical gimbal_vertical;  // measured when the block is not nadir and has gimbal angles
  TiltStats tilt;
  // The adjusted attitudes against the photos' gimbal angles (when the
  // caller had them: AdjustSurvey); images == 0 when none.
  GimbalAgreement gimbal;
  GpsDriftReport gps_drift;
  // The control's scatter about the model: the initial similarity over every
  // control point consistent with the others, per axis, against the file's
  // sigmas (their RMS over the three axes). Control several times noisier
  // than it claims (handheld GPS stated as RTK) would bend the block to fit
  // it and push its own marks out as outliers; from 3 times the stated
  // figure the adjustment weighs the control by the estimate instead, and
  // says so (CONTROL_WEAKER_THAN_STATED).
  struct ControlPrecision {
    bool measured = false;  // 4 or more control points in the fit
    int points = 0;
    double stated_m = 0.0;
    double estimated_m = 0.0;
    bool adopted = false;
    // The scatter was beyond 3 times the stated sigmas, but the file states
    // them: the adjustment's variance component for the control, which
    // allows for the block's own precision at the control (its redundancy
    // share), decides instead of the free network's scatter.
    bool deferred = false;
  } control_precision;
  BlockGeometry geometry;         // after the initial similarity
  bool check_points_in_bundle = false;  // check points as free points of the bundle
  bool refinement_auto = true;    // refinement chosen (true) or given by the user
  std::string refined;            // what the final adjustment refined
  std::string refinement_reason;  // why
  DomeTest dome;
  BundleSummary bundle;  // bundle.gps_offset_m: the estimated offset
  // The camera groups' intrinsics as they entered the adjustment (from the
  // reconstruction, or the calibration file): the report's "initial" values.
  std::vector<Camera> initial_cameras;
  std::vector<GroundPointResult> control;
  std::vector<GroundPointResult> check;
  AccuracyStats control_stats;
  AccuracyStats check_stats;
  std::vector<CameraResult> cameras;  // every registered image
  // Data snooping on the target marks (control, and check points inside the
  // bundle): Baarda's w-test at the critical value below (α0 = 0.1 %,
  // two-sided normal); precision_note says why the statistics are missing.
  // The survey's status is raised only beyond w_critical_family: the level
  // gates.mark_family_alpha over all mark_tests (at 0.1 % per test, a clean
  // survey of 800 marks, 1,600 tests, expects 1.6 of them beyond 3.29).
  std::vector<MarkResult> marks;
  // The check points' test (CheckPointGates): |w| of each axis against the
  // critical value of the family-wise size over all their tests (Sidak).
  struct CheckTest {
    int tests = 0;
    double family_alpha = 0.01;
    double critical_value = 0.0;
    bool posterior = false;  // predicted from the posterior covariance (else the datum's sigmas)
  } check_test;
  double w_critical = 3.29;
  int mark_tests = 0;
  double mark_family_alpha = 0.01;
  double w_critical_family = 3.29;
  LeaveOneOut leave_one_out;  // when GeoreferenceOptions::leave_one_out
  std::string precision_note;
  // Warnings and errors with stable codes (findings.h); SurveyStatus() of
  // them is the survey's status.
  std::vector<Finding> findings;
  // The phases as run (GeoreferenceAndAdjust, survey_phases.h), in order:
  // what each cost. The adjustment's solves and precision pass are timed
  // inside it (bundle.solves, bundle.precision.time_s).
  struct Phase {
    std::string name;
    double wall_s = 0.0;
    double cpu_s = 0.0;        // the process's CPU time in it, every thread
    double peak_rss_mb = 0.0;  // the resident peak in it (the process's where the kernel cannot reset the mark)
  };
  std::vector<Phase> phases;
};

// d(output CRS)/d(ENU) at an adjustment-frame position, by central
// differences over ±1 m: turns ENU covariances onto the CRS's axes. The
// identity for a geographic or geocentric CRS, whose figures stay in local
// ENU metres.
Eigen::Matrix3d CrsFromEnuJacobian(const LocalFrame& frame, const Crs& crs, const Eigen::Vector3d& enu);

// The intrinsics' correlations that betray weak geometry: every pair with
// |rho| > limit in which the focal length or the principal point takes part
// (f-cx, cx-p1, f-k1, ...), one INTRINSICS_CORRELATED warning per camera
// group naming the pairs. Pairs of distortion coefficients alone (k1-k2,
// k2-k3, ...) are left to the report's high_correlations: the polynomial's
// terms are nearly collinear in any block, while the curve they make is
// determined.
std::vector<Finding> IntrinsicsCorrelationFindings(const std::vector<IntrinsicsPrecision>& precision,
                                                   double limit = 0.9);

// A control or check point against its survey: with triangulate, the point
// is triangulated from views alone (check points) into *position_enu;
// otherwise *position_enu (the adjusted position) is evaluated. Residuals are
// in the CRS (ENU metres for a geographic CRS).
GroundPointResult EvaluateGroundPoint(const std::string& name, PointRole role,
                                      const std::vector<View>& views, const Geodetic& surveyed,
                                      const LocalFrame& frame, const Crs& crs, bool triangulate,
                                      Eigen::Vector3d* position_enu);

// Adjusts model in place; on return it is in the ENU frame of
// report.enu_origin, with control and check points appended as points of
// role kControl / kCheck. gps maps image names to fixes. Throws
// InvalidArgument when nothing can anchor the datum, CrsError for CRS
// problems.
GeoreferenceReport GeoreferenceAndAdjust(SparseModel* model,
                                         const std::map<std::string, GpsFix>& gps,
                                         const GcpFile* control, const GcpFile* checks,
                                         const GeoreferenceOptions& options);

}  // namespace aerotri
