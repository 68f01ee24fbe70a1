// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The survey adjustment as the decisions a photogrammetrist makes, one phase
// each. GeoreferenceAndAdjust (georeferencing.h) runs them top to bottom:
//
//   inputs checked            CheckDuplicatedMarks
//   frame and datum chosen    ChooseFrameAndDatum
//   priors attached           AttachPriors
//   initial similarity        FitInitialSimilarity (control datum, its
//                             precision, else GPS with the attitude levelling)
//   intrinsics to refine      ChooseRefinement
//   GNSS model                ModelGnss (GPS against control: offset, drift,
//                             lever arm, attitude prior)
//   adjustment                AdjustBlock: the bundle engine's screening
//                             solve, least squares, outlier rounds,
//                             variance components and precision, then
//                             HoldWeakFocal
//   GNSS and attitude         ReportGnssAndAttitude
//   check points              EvaluateGroundPoints, TestDome, ReportCameras
//   statistics and snooping   ReportVarianceComponents, SnoopTargetMarks
//   gates and findings        ApplyQualityGates (quality_gates.h)
//   leave-one-out             LeaveControlOut
//
// The survey's state passes between the phases as data (SurveyState): each
// phase reads what the earlier ones wrote and writes its own part, named in
// its comment, so a phase can be run and tested alone on a state built by
// hand or by the phases before it.

#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "georef/crs.h"
#include "georef/gcp_file.h"
#include "georef/gps_fix.h"
#include "georef/local_frame.h"
#include "georef/similarity.h"
#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/geometry/triangulation.h"
#include "libphoto/model/sparse_model.h"
#include "libphoto/survey/findings.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/survey/gnss_drift.h"

namespace aerotri {

// A control or check point of the files on its way through the survey.
struct SurveyedPoint {
  const GroundPoint* source = nullptr;
  Geodetic geodetic;
  PointRole role = PointRole::kControl;
  int point_index = -1;  // in the model, once added
  std::string excluded;  // why its measurements were left out, when they were
};

struct SurveyState {
  // The inputs (StartSurvey). gps is the caller's, with camera positions in
  // a local frame placed on the control's stand-in by ChooseFrameAndDatum.
  SparseModel* model = nullptr;
  std::map<std::string, GpsFix> gps;
  const GcpFile* control = nullptr;
  const GcpFile* checks = nullptr;
  const GeoreferenceOptions* options = nullptr;
  std::optional<GcpFile> control_in_plan;  // the control with zero heights taken as unknown (control points here)
  std::optional<SparseModel> start;  // the model as given, for leave-one-out
  GeoreferenceReport report;         // every phase adds its part

  // ChooseFrameAndDatum: the surveyed points in WGS84, the CRSs, the
  // adjustment's ENU frame.
  std::vector<SurveyedPoint> surveyed;
  std::optional<Crs> control_crs, check_crs, requested_crs, out_crs;
  bool local = false;  // a local engineering frame
  std::optional<LocalFrame> frame;
  std::unordered_map<std::string, int> image_by_name;

  // AttachPriors: GPS priors on the cameras, control and check points (with
  // their marks) appended to the model.
  int num_gps = 0;

  // FitInitialSimilarity: the correspondences of the datum, the GPS images'
  // flights, the fit and what holds the datum.
  std::vector<int> gps_images;  // registered images with GPS
  std::vector<Eigen::Vector3d> gps_from, gps_to;
  double gps_max_sigma = 0.0;
  std::vector<int> control_points;  // triangulated control with heights, by model point index
  std::vector<Eigen::Vector3d> control_from, control_to;
  double control_max_sigma = 0.0;
  std::vector<char> triangulated;  // by model point index
  FlightTimes flights;
  int num_timed = 0;  // GPS images with a capture time
  double median_sigma_h = 0.0, median_sigma_v = 0.0;
  std::vector<Eigen::Vector3d> initial_drift_rates;  // per flight, where significant
  std::optional<SimilarityFit> fit;
  bool control_datum = false;  // three or more control points hold the datum

  // ChooseRefinement and ModelGnss: the final adjustment's options.
  BundleOptions bundle;
  bool focal_held_flat = false;
  std::map<int, PositionPrior> rejected_gps;  // by image index, restored after the adjustment
  int outliers_before_final = 0;

  // AdjustBlock: the model as it entered the final solve (HoldWeakFocal
  // solves again from it).
  std::optional<SparseModel> before_final;

  const LocalFrame& Frame() const { return *frame; }
  const GeoreferenceOptions& Options() const { return *options; }
};

// Inputs checked: the model validated, the state's inputs set.
SurveyState StartSurvey(SparseModel* model, const std::map<std::string, GpsFix>& gps, const GcpFile* control,
                        const GcpFile* checks, const GeoreferenceOptions& options);

// One target labelled as two points: marks of different points within 2 px
// of each other in one photo (a copy-paste in the control file), said with
// both names and the lines (MARK_DUPLICATED); none: no such pair.
std::optional<Finding> CheckDuplicatedMarks(const GcpFile* control, const GcpFile* checks);

// Frame and datum chosen: the surveyed points in WGS84 (a local frame on
// its exact stand-in), the ENU origin, the output CRS. Throws
// InvalidArgument for frames that cannot meet (a local control with
// geodetic GPS) and when nothing can anchor the datum.
void ChooseFrameAndDatum(SurveyState* s);

// Priors attached: GPS on the cameras; surveyed points outside the
// photographed area left out (CONTROL_OUTSIDE_SURVEY); control and check
// points with their marks appended to the model.
void AttachPriors(SurveyState* s);

// A camera's velocity from its GPS track: the positions (ENU metres) and
// capture times of the photos before and after it, each within max_gap_s.
// Both neighbours: the central difference where the two one-sided
// velocities agree (within 20 degrees and 25 % in speed), nothing where
// they do not (a turn at a strip's end); one neighbour: its one-sided
// velocity. By name; photos without a time or a near neighbour left out.
struct TrackFix {
  std::string name;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double time_s = 0.0;
};
std::map<std::string, Eigen::Vector3d> VelocitiesFromTrack(std::vector<TrackFix> fixes, double max_gap_s);

// Initial similarity: the model mapped onto the datum, from three or more
// control points when they hold it (with the control's precision measured,
// CONTROL_WEAKER_THAN_STATED), else from the GPS (and any control), levelled
// by the block's own vertical where the GPS would tilt or drift it.
void FitInitialSimilarity(SurveyState* s);

// What the final adjustment refines: every intrinsic (auto), except the
// focal length of nadir photos of flat ground at one altitude without control
// heights, which is held at its EXIF / certificate value.
void ChooseRefinement(SurveyState* s);

// The GNSS model: with a control datum, the GPS judged against an adjustment
// on control alone (offset, drift in time, positions rejected); the offset,
// drift and attitude prior configured in s->bundle.
void ModelGnss(SurveyState* s);

// The adjustment with every prior (bundle engine: screening, least squares,
// outlier rounds, variance components, precision).
void AdjustBlock(SurveyState* s);

// A focal length the block does not determine: held at its prior and the
// block solved again (auto), or flagged (FOCAL_WEAKLY_DETERMINED).
void HoldWeakFocal(SurveyState* s);

// Each camera group's readout time as the adjustment estimated it, with its
// sigma, into the report's shutters (GeoreferenceOptions::estimate_readout).
void ReportReadouts(SurveyState* s);

// Rejected GPS restored for the report; the drift as estimated (GPS_DRIFT,
// GPS_TILT_REJECTED) and the adjusted attitude against the flight type
// (CAMERA_ATTITUDE_IMPLAUSIBLE, GROUND_TILTED_BY_GPS).
void ReportGnssAndAttitude(SurveyState* s);

// Control and check points against their survey (check points triangulated
// from the adjusted cameras alone), with their posterior sigmas.
void EvaluateGroundPoints(SurveyState* s);

// The dome test: the check points' vertical residuals, else the cameras'
// against their GPS.
void TestDome(SurveyState* s);

// Every registered camera's exterior orientation in the output CRS, its
// sigmas and its GPS residual.
void ReportCameras(SurveyState* s);

// PRECISION_NOT_COMPUTED, and observation groups that scatter several times
// their stated sigmas (SIGMAS_OPTIMISTIC).
void ReportVarianceComponents(SurveyState* s);

// Baarda's data snooping on the target marks (SnoopMarks).
void SnoopTargetMarks(SurveyState* s);

// Leave-one-out: each control point withheld from its own adjustment
// (GeoreferenceOptions::leave_one_out).
void LeaveControlOut(SurveyState* s);
// With leave-one-out asked for: the adjustment's precision passes compute
// each control point's block-deletion update (s->bundle.withhold_points),
// so that LeaveControlOut takes them from the survey's final pass instead
// of solving and inverting once more.
void WithholdControl(SurveyState* s);

// ---- Helpers shared by the phases.

// The views of a model point from registered images.
std::vector<View> ViewsOf(const SparseModel& model, int point_index);
// The Helmert inlier threshold for priors of this largest sigma.
double HelmertThreshold(const GeoreferenceOptions& options, double max_sigma);
// Where the GNSS antenna of an image is: its centre plus the lever arm.
Eigen::Vector3d AntennaOf(const Image& image, const Eigen::Vector3d& lever);
// What the receiver should have read for an image, as adjusted: its antenna,
// plus the GPS offset and the flight's drift where estimated.
Eigen::Vector3d GpsAsAdjusted(const SurveyState& s, const Image& image);
// Every control point in use states its sigmas in its file.
bool ControlSigmasStated(const SurveyState& s);
// GeoreferenceOptions::hold_stated_sigmas: the observation groups whose
// every sigma the survey's files state, held at them (s->bundle).
void HoldStatedSigmas(SurveyState* s);
// Per camera group: whether a registered image uses it.
std::vector<char> CamerasInUse(const SparseModel& model);
void ApplySimilarity(const Similarity& similarity, SparseModel* model);
// The drift trend of the GPS residuals into the report's flights, and the
// significant rates as the adjustment's start (s->initial_drift_rates).
void RecordDriftTrend(SurveyState* s, const DriftTrend& trend);
// Each GPS prior learns its flight and time (when the drift is estimated).
void AttachFlights(SurveyState* s);
std::string FormatDegrees(double deg);
std::string FormatPercent(double fraction);
std::string FormatMetres(double m);
std::string FormatMilliseconds(double s);

}  // namespace aerotri
