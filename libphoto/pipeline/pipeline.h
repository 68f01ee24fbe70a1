// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// The photo pipeline over a workspace folder. Each stage reads what earlier
// stages wrote, writes its product atomically, and is skipped when its
// product exists (unless force), so an interrupted run resumes:
//
//   ingest       ingest.json            EXIF / XMP, camera groups, GPS, focal
//   features     features/<image>.sift  SIFT at the working resolution
//   match        matches.bin, matches.json   verified pairs, overlap summary
//   reconstruct  reconstruction/ (COLMAP text, arbitrary frame, working px)
//                + reconstruction.json  per-image registration
//   mark         gcp_marks.txt, check_marks.txt, marks.json, marks.html
//                (only for control / check files of coordinates alone)
//   georeference sparse/ (COLMAP text, ENU metres, full-resolution pixels),
//                georeferenced/ (the same at the working resolution),
//                cameras.csv (positions in the output CRS), report.json
//   dense        cloud.laz (ground-classified; or .las, .copc.laz), cloud.ply, dsm.tif, dtm.tif,
//                contours.gpkg (the deliverable CRS: heights stated)
//   ortho        ortho.tif (RGB + alpha Cloud-Optimised GeoTIFF)
//   report       report.json completed (DSM at check points, coverage) and
//                report.html (self-contained, opens offline)
//
// Every stage records its wall time and the process's peak memory in
// timings.json.

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "georef/gcp_file.h"
#include "libphoto/survey/georeferencing.h"
#include "libphoto/features/features.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/matching/matching.h"
#include "libphoto/sfm/incremental_mapper.h"

namespace aerotri {

struct PipelineOptions {
  std::filesystem::path images_dir;  // needed by ingest (and features)
  std::filesystem::path workspace;
  bool force = false;  // redo stages whose product exists
  // Write the deliverables of a failed adjustment too (tagged as failed).
  bool keep_going = false;
  // Keep the dense stage's depth maps (depth/) once the cloud is fused. By
  // default they are removed then: they are most of a workspace (453 MB of
  // the sample survey's 861 MB) and nothing after fusion reads them; an
  // interrupted dense stage keeps the maps it has and resumes from them.
  bool keep_depth_maps = false;
  int num_threads = 0;

  // ingest
  AltitudeReference gps_altitude = AltitudeReference::kEgm96;
  double gps_sigma_h_m = kDefaultGpsSigmaH;
  double gps_sigma_v_m = kDefaultGpsSigmaV;
  std::filesystem::path gps_csv;  // optional, overrides EXIF

  FeatureOptions features;
  MatchOptions matching;
  MapperOptions mapper;

  // georeference
  std::filesystem::path gcp;          // optional
  std::filesystem::path checkpoints;  // optional
  PixelOrigin gcp_pixel_origin = PixelOrigin::kCentre;  // OpenDroneMap's
  std::filesystem::path camera_file;  // optional calibration certificate (libphoto/adjust/camera_file.h)
  GeoreferenceOptions georef;

  // dense
  double dense_resolution_m = 0.0;  // 0: the median GSD at working resolution
  double dense_image_scale = 1.0;   // of the working images for matching
  int dense_min_views = 2;          // depth maps that must agree on a point
  // The dense stage as separate jobs of a workflow (aerotri split), each its
  // own process on the one workspace: the depth maps of share k of n
  // (kDepthShare), then, once every depth share is done, the fusion of
  // share k of n into the deliverables' CRS (kFuseShare), then the
  // deliverables from the n fused shares (kFromShares): the same cloud and
  // products as kWhole, all in one.
  enum class DenseStep { kWhole, kDepthShare, kFuseShare, kFromShares };
  DenseStep dense_step = DenseStep::kWhole;
  int dense_share = 0;   // k, from 0 (the command line counts from 1)
  int dense_shares = 1;  // n
  double dsm_resolution_m = 0.0;    // 0: twice the dense resolution
  double dsm_fill_m = 2.0;          // holes filled up to this distance
  bool cog = false;                 // Cloud-Optimised GeoTIFF (DSM, DTM)
  std::string cloud_format = "laz";  // las, laz or copc: cloud.las, cloud.laz, cloud.copc.laz
  // Heights of the deliverables under a 2D output CRS given as an EPSG code:
  // "egm96" (the default: the compound CRS code+5773, EGM96 heights, when
  // PROJ's geoid grid is present) or "ellipsoidal" (the CRS's own WGS84
  // ellipsoidal heights, stated in the files' metadata).
  std::string heights = "egm96";

  // terrain (dense stage): ground classification (SMRF), DTM, contours
  double ground_cell_m = 0.5;
  double ground_window_m = 18.0;
  double ground_slope = 0.15;
  double ground_threshold_m = 0.3;
  double contour_interval_m = 0.0;  // 0: a round number near a twentieth of the relief

  // ortho
  bool ortho = true;
  double ortho_resolution_m = 0.0;   // 0: the dense spacing (the GSD at working resolution)
  std::string ortho_surface = "dsm";  // or "dtm"
  std::string ortho_compress = "JPEG";  // or "DEFLATE"
  bool ortho_cog = true;
  // The ortho stage as a workflow's jobs (aerotri split): the band of tile
  // rows of share k of n (kBandShare; several at once on one workspace),
  // then the deliverable from the n bands (kFromShares): the same file as
  // kWhole, all in one.
  enum class OrthoStep { kWhole, kBandShare, kFromShares };
  OrthoStep ortho_step = OrthoStep::kWhole;
  int ortho_share = 0;   // k, from 0
  int ortho_shares = 1;  // n

  // Who asked: recorded in report.json "provenance" with the date and the
  // effective options (set by the command-line tool; empty from a library caller).
  std::string software_version;
  std::vector<std::string> command_line;

  // One callback per stage name ("ingest", "features", ...); may be null.
  std::function<ProgressCallback(const std::string& stage)> progress;
  // Messages for the user (warnings, stage skipped); may be null.
  std::function<void(const std::string&)> log;

  // Every stage's options (FeatureOptions::Check, MatchOptions::Check,
  // MapperOptions::Check, GeoreferenceOptions::Check and the dense, terrain
  // and ortho fields above): throws InvalidArgument naming the option, its
  // value and what was expected. ValidateInputs calls it first.
  void Check() const;
};

// Each returns true when it ran, false when skipped (product present).
bool RunIngestStage(const PipelineOptions& options);
bool RunFeatureStage(const PipelineOptions& options);
bool RunMatchStage(const PipelineOptions& options);
bool RunReconstructStage(const PipelineOptions& options);
// Control or check files with coordinates only (GcpFile::coordinates_only):
// their targets found in the photos (libphoto/targets/marking.h), written
// as OUTPUT/gcp_marks.txt and check_marks.txt, with OUTPUT/marks.json (per
// point and photo: predicted, marked, confidence, or why not). Does
// nothing (and removes an earlier marking's files) when no file needs it.
bool RunMarkStage(const PipelineOptions& options);
// OUTPUT/marks.html, the review page (libphoto/report/review_page.h) of the
// marks in marks.json: by the mark stage, and again by the report stage with
// the adjustment's residuals and w-tests (report: report.json's content, or
// null before the adjustment). Nothing when the workspace has no marks.json.
void WriteReviewPage(const PipelineOptions& options, const nlohmann::json& report);
bool NeedsMarking(const PipelineOptions& options);
// After ingest: throws UsageError when marking is needed, no photo has GPS
// and the coordinate list's CRS does not place it on the Earth (a LOCAL
// list): before the heavy stages, rather than after the reconstruction.
void CheckMarkingPossible(const PipelineOptions& options);
// The options the stages after marking read: coordinates-only files
// replaced by the workspace's marks (IoError when not marked yet).
PipelineOptions WithMarks(const PipelineOptions& options);
bool RunGeoreferenceStage(const PipelineOptions& options);

bool RunDenseStage(const PipelineOptions& options);
bool RunOrthoStage(const PipelineOptions& options);
bool RunReportStage(const PipelineOptions& options);

// Checks every input before the first heavy stage: the output CRS, the GPS
// CSV, control and check files (format, CRS, image names: unknown ones are
// a warning), the workspace (writable; free space against the photos'
// size, a warning). Throws the input's own error naming file and line.
void ValidateInputs(const PipelineOptions& options);

// All stages in order (after ValidateInputs); returns the survey's status (report.json "status":
// ok, warnings, failed). A failed adjustment stops before the dense stage
// unless options.keep_going; the report stage still runs.
std::string RunPipeline(const PipelineOptions& options);
// Removes OUTPUT/depth/ (the dense stage's depth maps) unless
// options.keep_depth_maps, and says how much it freed; nothing else. The
// dense stage calls it once its products are written.
void RemoveDepthMaps(const PipelineOptions& options);
// report.json's status in a workspace, or "" before the georeference stage.
std::string SurveyStatusOf(const std::filesystem::path& workspace);

// The dense cloud's file name for options.cloud_format: cloud.las,
// cloud.laz or cloud.copc.laz.
std::string CloudFileName(const PipelineOptions& options);

// Rebuilds the DSM from OUTPUT's cloud (LAS or LAZ) at options.dsm_resolution_m (0: twice
// the dense spacing recorded in dense.json, as the dense stage chooses) into
// path, by default OUTPUT/dsm_<resolution>m.tif. Returns the path written.
std::filesystem::path RebuildDsm(const PipelineOptions& options, std::filesystem::path path = {});
// Re-evaluates check points (options.checkpoints) on an existing survey and
// rewrites report.json and report.html.
void CheckSurvey(const PipelineOptions& options);

}  // namespace aerotri
