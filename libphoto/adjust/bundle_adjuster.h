// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Bundle adjustment of a SparseModel with Ceres (Levenberg–Marquardt, Schur
// linear solvers), generic over camera models.
//
// Parameter blocks: per registered image its rotation (unit quaternion on
// ceres::QuaternionManifold) and its centre; per camera group its intrinsics
// (refined as BundleOptions says); per tie / control point its position.
// Residuals: reprojection (analytic Jacobians, optional robust loss whose
// scale is in pixels), GPS priors on camera centres (with an optional shared
// offset, per-flight drift and lever arm), surveyed priors on control points,
// optional attitude and intrinsics priors. Check points enter only as free
// points (BundleOptions::check_points_in_bundle); by default they are
// triangulated afterwards with the cameras held.
//
// Each solve is first configured as data (bundle_config.h: which images,
// points and intrinsics take part and vary, which blocks are merged, and the
// gauge), then built and solved. Gauge: with three or more non-collinear
// priors the datum comes from them and no parameter is held fixed. Without
// priors one image's pose is held (or, for a free network, restored exactly
// afterwards) and the scale of the longest baseline from it is restored
// after the solve; with too few priors that image's rotation is held.
// BundleSummary::gauge says which.
//
// Costs follow Ceres: ½Σ‖r‖² over all (robustified) residuals; with no priors,
// no loss and sigma 1 px this is the BAL literature's cost in px².

#include <Eigen/Core>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "libphoto/adjust/schur_lm_solver.h"
#include "libphoto/model/sparse_model.h"

namespace aerotri {

enum class LossType { kNone, kHuber, kCauchy, kTukey };
enum class LinearSolverChoice { kAuto, kDenseSchur, kSparseSchur, kIterativeSchur };
// Who solves: Ceres, or aerotri's own dense-Schur Levenberg–Marquardt
// (dense_schur_solver.h), which takes reprojection-only free networks whose
// images each have a camera group of their own and whose reduced camera
// system fits kMaxDenseSchurSize (BAL problems). kAuto: aerotri's solver
// where it applies, else Ceres.
enum class BundleEngine { kAuto, kCeres, kAerotri };
enum class IntrinsicsRefinement {
  kNone,                 // intrinsics held fixed
  kFocal,                // f
  kFocalPrincipalPoint,  // f, cx, cy
  kAll,                  // every parameter of the model
  kList,                 // the names in BundleOptions::refine_params
};

// The observation groups whose stated sigmas variance-component estimation
// judges (and may rescale): image measurements of tie points and of target
// marks (control and check points), GPS positions horizontally and
// vertically, and the control points' surveyed positions.
enum class ObservationGroup { kTies, kMarks, kGpsHorizontal, kGpsVertical, kControl };
constexpr int kNumObservationGroups = 5;

std::string ToString(ObservationGroup group);
std::string ToString(LossType loss);
std::string ToString(LinearSolverChoice solver);
std::string ToString(BundleEngine engine);
std::optional<BundleEngine> ParseBundleEngine(const std::string& name);
std::string ToString(IntrinsicsRefinement refinement);
std::optional<LossType> ParseLossType(const std::string& name);
std::optional<LinearSolverChoice> ParseLinearSolver(const std::string& name);
// "none", "focal", "focal,pp", "all", or a comma-separated list of parameter
// names ("f,k1,k2"); the list is returned in *params.
std::optional<IntrinsicsRefinement> ParseIntrinsicsRefinement(
    const std::string& text, std::vector<std::string>* params);

struct IterationReport {
  int iteration = 0;      // 0 is the initial state
  double cost = 0.0;      // ½Σ‖r‖²
  double time_s = 0.0;    // since the solver started
  int round = 0;          // outlier-rejection round (0 = first solve)
};

struct BundleOptions {
  // Robust loss on reprojection residuals; loss_scale_px is where it departs
  // from least squares (Huber, Cauchy) or cuts off (Tukey), in pixels.
  LossType loss = LossType::kNone;
  double loss_scale_px = 1.0;
  // The robust loss screens, least squares estimates: the first solve
  // (robust, stopped at screening_function_tolerance) finds the blunders
  // for the outlier rejection; every later solve (outlier rounds, the
  // precision pass, variance-component re-solves) is plain least squares
  // on the screened observations, so sigma0, the chi^2 test, redundancies
  // and covariances mean what they say. It also converges: a Huber cost
  // with residuals on its linear part is minimised by iterative
  // re-weighting, which crawls along a block's weak directions (on the
  // sample survey 36 iterations that gain 0.01 px^2 and end by the
  // tolerance, not at the optimum; least squares converges in 5).
  // Off: every solve uses the loss (the robust estimate). The screening
  // needs residuals to a small fraction of the outlier threshold, not the
  // robust optimum: its tolerance is the looser of this and
  // function_tolerance (on the sample survey the crawl after 1e-5 moves the
  // cost by 0.03 px^2 in all).
  bool least_squares_after_screening = false;
  double screening_function_tolerance = 1e-5;
  // Standard deviation of an image measurement (px); scales reprojection
  // residuals against priors.
  double observation_sigma_px = 1.0;
  // Image sigma of target marks (control and check points' measurements);
  // 0: observation_sigma_px. The loss scale stays in pixels for both.
  double mark_sigma_px = 0.0;

  IntrinsicsRefinement refine_intrinsics = IntrinsicsRefinement::kAll;
  std::vector<std::string> refine_params;  // for kList
  // A camera group seen by fewer adjusted images than this refines its focal
  // length only (too little geometry to calibrate the lens; holding a wrong
  // EXIF focal length fixed would bend the whole block).
  int min_images_to_refine_intrinsics = 1;

  // Prior on each camera group's focal length (index-aligned with
  // SparseModel::cameras; 0 = none), with a relative sigma. Nadir photos of
  // flat ground observe only focal length over depth: without this prior a
  // GPS-only block may trade one for the other. Only EXIF focal lengths
  // measured in millimetres with a sensor size get one (ingest.json).
  std::vector<double> focal_prior_px;
  double focal_prior_sigma_rel = 0.10;
  // A calibration certificate (camera_file.h): priors on single intrinsic
  // parameters, and parameters held at their values whatever
  // refine_intrinsics says.
  struct IntrinsicPrior {
    int camera = -1;  // index in SparseModel::cameras
    int param = -1;   // index in the camera's parameters
    double value = 0.0;
    double sigma = 0.0;  // px, or unitless for distortion
  };
  std::vector<IntrinsicPrior> intrinsics_priors;
  std::vector<std::pair<int, int>> held_params;  // (camera, parameter index)

  bool use_gps_priors = true;
  bool use_gcp_priors = true;

  // Images whose pose (rotation and centre) is held at its value, by image
  // index (nonzero holds; empty or short: the rest vary): a local
  // adjustment's ring of neighbours around the images it refines. Without
  // priors that fix the datum, two or more held images with distinct
  // centres hold the gauge (BundleGauge::kHeldImages).
  std::vector<char> held_poses;

  // A constant offset of every GPS position from its camera centre (GNSS
  // antenna or datum offset, e.g. altitudes in the wrong height reference),
  // estimated as one 3-vector shared by all GPS priors:
  //   r = (C + o − GPS) / σ.
  // Needs control points to anchor the translation; with none used, o stays
  // at its initial value. initial_gps_offset_m is the start (ENU metres).
  bool estimate_gps_offset = false;
  Eigen::Vector3d initial_gps_offset_m = Eigen::Vector3d::Zero();
  // With estimate_gps_offset: one offset per flight instead (each flight's
  // own base station, antenna mount or height reference), on the GPS priors
  // whose PositionPrior::flight is f (priors without a flight share flight
  // 0's); initial_gps_flight_offsets_m are the starts (missing:
  // initial_gps_offset_m).
  bool gps_offset_per_flight = false;
  std::vector<Eigen::Vector3d> initial_gps_flight_offsets_m;
  // A GNSS drift growing linearly in time within each flight (a consumer
  // drone's barometric / GNSS altitude drift), estimated per flight f as a
  // rate d_f (m/s, E N U) on the GPS priors whose PositionPrior::flight is f:
  //   r = (C + o + d_f Δt − GPS) / σ,   Δt = PositionPrior::time_from_flight_s.
  // Axes not in gps_drift_axes stay at their initial rate (zero). The rate is
  // not separable from a tilt of the block unless control anchors the datum
  // or the nadir attitude prior below holds the tilt.
  bool estimate_gps_drift = false;
  std::array<bool, 3> gps_drift_axes = {false, false, true};
  std::vector<Eigen::Vector3d> initial_gps_drift_m_per_s;  // per flight (missing: zero)
  // Attitude prior: in each adjusted image the world's down (−U) lies along
  // attitude_prior_down_in_camera[i] (camera frame, unit; by image index;
  // empty: (0, 0, 1) for every image, a nadir block's optical axis; a zero
  // vector: no prior on that image — an oblique photo without gimbal
  // angles), with this standard deviation per image (degrees); 0: none.
  // The tie points fix the images' attitudes relative to each other, so
  // together the priors hold only the block's common tilt, to about σ / √n:
  // what GPS heights that drift cannot hold.
  double attitude_prior_sigma_deg = 0.0;
  std::vector<Eigen::Vector3d> attitude_prior_down_in_camera;
  // The GNSS antenna's position in the camera frame (metres; x right, y
  // down the image, z along the optical axis): the receiver reads
  // C + Rᵀ l. Zero: the antenna at the camera centre.
  Eigen::Vector3d gnss_lever_arm_m = Eigen::Vector3d::Zero();

  LinearSolverChoice linear_solver = LinearSolverChoice::kAuto;
  BundleEngine engine = BundleEngine::kAuto;
  // How aerotri's Schur engine holds its reduced system (schur_lm_solver.h):
  // dense up to kMaxSchurLmDenseSize columns, sparse beyond (auto).
  ReducedStorage reduced_storage = ReducedStorage::kAuto;
  int num_threads = 0;  // 0: all hardware threads
  int max_iterations = 100;
  // Stop once the cost is estimated within this fraction of the optimum
  // (BundleStopRule in dense_schur_solver.h: the last accepted decrease and
  // its geometric extrapolation); 0: off, only the tolerances below stop.
  double optimality_gap = 0.0;
  // Stop once an accepted step lowers the cost (½Σ of squared residuals over
  // their sigmas) by less than this, absolute; 0: off. A step of d standard
  // deviations along any direction of the normal equations changes that cost
  // by about d²/2, so 1e-6 stops within about a thousandth of a sigma of the
  // optimum where a relative function tolerance stops short along a weak
  // block's valleys (omega-Y correlated beyond 0.99). Not applied to the
  // robust screening solve.
  double cost_change_tolerance = 0.0;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  double max_time_s = 0.0;  // 0: no limit

  // After convergence, tie-point observations whose reprojection error
  // exceeds this (px) are rejected and the problem is solved again, up to
  // max_outlier_rounds times. 0 disables rejection. Target marks are kept:
  // the w-test (compute_precision) judges them.
  double outlier_threshold_px = 0.0;
  int max_outlier_rounds = 2;

  // Diagnostics: images with fewer observations than this, and tie points
  // whose widest ray pair is narrower than this angle, are reported as weak.
  int weak_image_min_observations = 20;
  double weak_point_min_angle_deg = 2.0;
  // The after-solve diagnostics (observations behind their camera, weak
  // images and points). Off: those counts stay 0; the RMS figures are
  // computed either way.
  bool compute_diagnostics = true;

  // After the solve, the a-priori covariance of each camera group's refined
  // intrinsics and of their correlation with the camera heights (the
  // reduced camera system of bundle_precision.h: points eliminated, a dense
  // inverse over cameras and intrinsics): BundleSummary::
  // intrinsics_precision. Skipped (with the reason) above
  // max_covariance_residuals residuals.
  bool compute_intrinsics_covariance = false;
  int max_covariance_residuals = 3000000;

  // After the last solve, the posterior precision of the adjustment
  // (BundleSummary::precision): covariances of every camera centre and
  // rotation, every adjusted point, the GPS offset and the check points, and
  // Baarda's w-test of every target mark, from the reduced camera system
  // (bundle_precision.h). Skipped (with the reason) for images with a camera
  // group of their own (BAL) or a datum held by a fixed image.
  bool compute_precision = false;
  // Check points as free points inside the bundle (their marks tie the
  // block; no prior) instead of independent points triangulated afterwards
  // with the cameras held.
  bool check_points_in_bundle = false;
  // The readout time of each camera group's rolling shutter estimated (one
  // unknown per group, from the photos' stated velocities; their stated
  // readouts, or zero, the start); otherwise each photo's is held as stated.
  // BundleSummary::readouts, with its sigma under compute_precision.
  bool estimate_readout = false;
  // With compute_precision: points (indices in SparseModel::points) each
  // withheld on its own from the precision pass's normal equations, for
  // leave-one-out without a re-solve (BundlePrecision::withheld): their
  // marks and prior, or with check_points_in_bundle their prior only.
  std::vector<int> withhold_points;

  // Each observation group's stated sigmas multiplied by this factor
  // (index: ObservationGroup): the weights variance-component estimation
  // arrives at, or a caller's own.
  std::array<double, kNumObservationGroups> sigma_scale = {1.0, 1.0, 1.0, 1.0, 1.0};
  // Variance-component estimation (with compute_precision): after the last
  // solve, each group's a-posteriori variance factor vᵀPv / r_g (r_g its
  // share of the redundancy, bundle_precision.h) rescales its sigmas and the
  // block is solved again, until every factor is within
  // variance_component_tolerance of 1 or max_variance_component_iterations
  // re-solves were made (a group settles within one standard error of its
  // σ0, 1 / sqrt(2 r_g), if that is larger). A group with a redundancy
  // below kMinGroupRedundancy at the stated weights (σ0 known to worse than
  // 22 %) keeps its stated sigmas. Without it the factors are
  // still computed and reported (BundleSummary::variance_components).
  bool estimate_variance_components = false;
  // Groups held at their stated sigmas while the others are estimated (a
  // survey's own stochastic model, stated observation by observation in its
  // files); their factors are still reported.
  std::array<bool, kNumObservationGroups> hold_stated_sigmas = {false, false, false, false, false};
  int max_variance_component_iterations = 8;
  double variance_component_tolerance = 0.02;
  static constexpr double kMinGroupRedundancy = 10.0;

  std::function<void(const IterationReport&)> iteration_callback;
  // Keep Ceres' FullReport() of every solve in BundleSummary::solver_report.
  bool keep_solver_report = false;

  // Ceres-style validation: false with a message naming the option, its
  // value and the allowed range.
  bool Validate(std::string* error) const;
};

struct WeakImage {
  std::string name;
  int observations = 0;
};

// Precision of one camera group's refined intrinsics, from (JᵀJ)⁻¹ with the
// a-priori weights (image sigma, prior sigmas): what the geometry determines.
struct IntrinsicsPrecision {
  int camera = -1;                  // index in SparseModel::cameras
  std::vector<std::string> names;   // refined parameters, in order
  std::vector<double> values;
  std::vector<double> sigmas;       // a-priori standard deviations (px or unitless)
  std::vector<std::vector<double>> correlation;  // names x names
  // Correlation of the focal length with the heights of the group's cameras:
  // median and largest |ρ(f, Z_i)| (0 when f is not refined).
  double focal_height_correlation_median = 0.0;
  double focal_height_correlation_max = 0.0;
};

// Posterior (a-posteriori) covariances, scaled by the variance factor σ0²
// of the adjustment; frames as in the model (the adjustment frame, metres).
struct ImagePrecision {
  int image = -1;                                     // index in SparseModel::images
  Eigen::Matrix3d centre_cov = Eigen::Matrix3d::Zero();  // m²; zero when held
  // Of the small rotation θ (radians, camera frame) in
  // cam_from_world' = Exp(θ) · cam_from_world; zero when held.
  Eigen::Matrix3d rotation_cov = Eigen::Matrix3d::Zero();
};

struct PointPrecision {
  int point = -1;                               // index in SparseModel::points
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // m²
};

// Baarda's data snooping on one target-mark observation: residual v
// (adjusted − observed, px), its redundancy number r = q_vv / q_ll and the
// normalised residual w = v / (σ √r) per image axis, σ the a-priori image
// sigma of the mark (σ0 a priori = 1).
struct MarkTest {
  int observation = -1;  // index in SparseModel::observations
  int point = -1;
  int image = -1;
  Eigen::Vector2d residual_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d redundancy = Eigen::Vector2d::Zero();
  Eigen::Vector2d w = Eigen::Vector2d::Zero();
  double MaxAbsW() const { return w.cwiseAbs().maxCoeff(); }
};

// A point withheld from the solved bundle (BundleOptions::withhold_points):
// the adjustment as it would be without it, to first order from the
// optimum (bundle_precision.h), over the images and camera groups its
// observations touch (the rest also move, but do not bear on the point).
struct WithheldPoint {
  int point = -1;
  bool computed = false;
  std::string note;  // why not, when !computed
  std::vector<std::pair<int, Pose>> images;                  // index, pose
  std::vector<std::pair<int, std::vector<double>>> cameras;  // index, params
  // With check points in the bundle: the point, adjusted free of its prior.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

struct BundlePrecision {
  bool computed = false;
  std::string note;              // why not, when !computed
  double variance_factor = 1.0;  // σ0², applied to every covariance
  std::vector<ImagePrecision> images;  // adjusted images
  std::vector<PointPrecision> points;  // adjusted points and check points
  // Adjusted points along whose (nearly parallel) rays nothing determines
  // them: left out of `points`; the cameras' covariance is exact without.
  int undetermined_points = 0;
  bool has_gps_offset = false;
  Eigen::Matrix3d gps_offset_cov = Eigen::Matrix3d::Zero();  // flight 0's when per flight
  std::vector<Eigen::Matrix3d> gps_flight_offset_cov;  // per flight (BundleOptions::gps_offset_per_flight)
  // Per flight of the GNSS drift model ((m/s)²); zero rows and columns for
  // axes held.
  std::vector<Eigen::Matrix3d> gps_drift_cov;
  // Per camera group, the variance of its estimated readout time (s²; zero
  // where not estimated).
  std::vector<double> readout_var;
  std::vector<MarkTest> marks;  // control marks, and check marks inside the bundle
  std::vector<WithheldPoint> withheld;  // BundleOptions::withhold_points
  double time_s = 0.0;
  const PointPrecision* ForPoint(int point) const;
  const ImagePrecision* ForImage(int image) const;
};

// One observation group's variance component at the last solve.
struct VarianceComponent {
  ObservationGroup group = ObservationGroup::kTies;
  int rows = 0;             // residual components (two per image measurement)
  double redundancy = 0.0;  // the group's share r_g of the adjustment's redundancy
  // sqrt(vᵀPv / r_g) under the sigmas used (stated × scale): 1 when they
  // describe the data; NaN when the group has no redundancy.
  double sigma0 = 0.0;
  double scale = 1.0;       // BundleOptions::sigma_scale as solved
  bool estimated = false;   // the scale was estimated (not given)
  bool held = false;        // held at its stated sigmas (BundleOptions::hold_stated_sigmas)
  // The group's stated sigma (median over its observations; px for image
  // measurements, m for GPS and control) and what the data shows:
  // stated × scale × sigma0.
  double stated_sigma = 0.0;
  double EstimatedSigma() const { return stated_sigma * scale * sigma0; }
};

struct BundleSummary {
  int num_images = 0;          // adjusted (registered) images
  int num_camera_groups = 0;
  int num_points = 0;          // adjusted points (tie + control)
  int num_observations = 0;    // reprojection residuals
  int num_gps_priors = 0;
  int num_gcp_priors = 0;
  int num_skipped_points = 0;  // tie points with fewer than 2 observations
  int num_behind_camera_initial = 0;  // observations with z <= 0 (kept)
  int num_behind_camera_final = 0;

  double initial_cost = 0.0;
  double final_cost = 0.0;
  double initial_rms_px = 0.0;  // sqrt(mean ‖xy − observed‖²) over observations
  double final_rms_px = 0.0;
  int iterations = 0;           // summed over every solve below
  int outlier_rounds = 0;
  // Every solve in order: the robust screening (least_squares_after_screening)
  // and the least-squares estimate, or the first solve; one per outlier
  // round; one per variance-component re-weighting. What each cost, and why
  // it stopped.
  struct Solve {
    // "robust screening (huber)", "least squares", "first", "outlier round N",
    // "variance components N"
    std::string kind;
    int iterations = 0;
    double initial_cost = 0.0;
    double final_cost = 0.0;
    double time_s = 0.0;
    std::string termination;
  };
  std::vector<Solve> solves;
  int outliers_removed = 0;
  std::string termination;      // Ceres termination type and message
  // A-posteriori sigma of unit weight sqrt(2 cost / redundancy) and the
  // redundancy (residuals − free parameters) of the last solve: sigma0 near
  // 1 when the stated sigmas (image, GPS, control) match the data.
  int redundancy = 0;
  double sigma0 = 0.0;
  bool converged = false;

  // GPS minus camera centre (ENU metres): estimated when
  // BundleOptions::estimate_gps_offset and control anchored it, else the
  // initial value held fixed.
  bool gps_offset_estimated = false;
  Eigen::Vector3d gps_offset_m = Eigen::Vector3d::Zero();  // flight 0's when per flight
  // Per flight, when BundleOptions::gps_offset_per_flight (else empty);
  // GpsOffsetOf() gives an image's.
  std::vector<Eigen::Vector3d> gps_flight_offsets_m;
  // The offset that applies to a GPS prior: its flight's, or the shared one.
  Eigen::Vector3d GpsOffsetOf(const PositionPrior& prior) const {
    if (gps_flight_offsets_m.empty()) return gps_offset_m;
    const int f = prior.flight >= 0 && prior.flight < static_cast<int>(gps_flight_offsets_m.size()) ? prior.flight : 0;
    return gps_flight_offsets_m[f];
  }
  // GNSS drift rates per flight (m/s, E N U), when estimated.
  bool gps_drift_estimated = false;
  std::vector<Eigen::Vector3d> gps_drift_m_per_s;
  // Each camera group's rolling-shutter readout time as estimated
  // (BundleOptions::estimate_readout); sigma_s 0 without the precision.
  struct Readout {
    int camera = -1;  // index into SparseModel::cameras
    int images = 0;   // adjusted photos whose rows it times
    double readout_time_s = 0.0;
    double sigma_s = 0.0;
  };
  std::vector<Readout> readouts;
  int num_attitude_priors = 0;

  std::string linear_solver;
  std::string gauge;            // what anchors the datum
  // What the last solve refined ("all", "none", names, or per camera
  // group), and per camera group the refined parameters' indices.
  std::string refined_intrinsics;
  std::vector<std::vector<int>> refined_params;

  double setup_time_s = 0.0;
  double solve_time_s = 0.0;
  double total_time_s = 0.0;

  std::string solver_report;  // Ceres' full reports, when asked for

  std::vector<IntrinsicsPrecision> intrinsics_precision;
  std::string covariance_note;  // why intrinsics_precision is empty, when asked for

  BundlePrecision precision;  // when BundleOptions::compute_precision
  // Per observation group present, with compute_precision. When they were
  // estimated, sigma0_stated is σ0 of the solve with the stated sigmas (the
  // χ² test of the a-priori model) and sigma0 that of the final solve.
  std::vector<VarianceComponent> variance_components;
  int variance_component_iterations = 0;  // re-solves made by the estimation
  double sigma0_stated = 0.0;
  int redundancy_stated = 0;

  std::vector<WeakImage> weak_images;
  int weak_points_small_angle = 0;

  // Several lines, human readable.
  std::string BriefReport() const;
};

// Adjusts model in place. Throws InvalidArgument for invalid options or an
// invalid model; a solver failure is reported in the summary, not thrown.
BundleSummary AdjustBundle(SparseModel* model, const BundleOptions& options);

// Reprojection error (px, Euclidean) of each observation, index-aligned with
// model.observations; NaN where the point is on the camera plane (z = 0).
std::vector<double> ReprojectionErrors(const SparseModel& model);

}  // namespace aerotri
