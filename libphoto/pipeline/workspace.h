// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// What the pipeline stages share about the workspace folder: reading earlier
// stages' products, timings, logging and progress.

#include <chrono>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "libphoto/features/features.h"
#include "libphoto/ingest/ingest.h"
#include "libphoto/pipeline/pipeline.h"
#include "libphoto/pipeline/survey_adjustment.h"

namespace aerotri {

void Log(const PipelineOptions& o, const std::string& message);
ProgressCallback StageProgress(const PipelineOptions& o, const std::string& stage);
// A stage's start: restarts the memory high-water mark (ResetPeakRss) so
// that RecordTiming gives the stage's own peak, not the process's so far, and
// returns the time.
std::chrono::steady_clock::time_point BeginStage();
// Adds {wall_s, peak_rss_mb (this stage's peak since BeginStage),
// process_peak_rss_mb, peak_rss_scope ("stage", or "process" where the
// kernel would not restart the mark)} for a stage to OUTPUT/timings.json.
void RecordTiming(const PipelineOptions& o, const std::string& stage, double seconds);
unsigned Threads(const PipelineOptions& o);
// Parses a workspace JSON file; IoError naming the stage to run when missing.
nlohmann::json ReadJson(const std::filesystem::path& path, const char* stage);
std::filesystem::path FeaturePath(const PipelineOptions& o, const std::string& name);

// FNV-1a 64 of a file's bytes, as 16 hex digits ("" for no path, "missing"
// when absent): a stage's inputs in its recorded options.
std::string ContentHash(const std::filesystem::path& path);
// The options and inputs a stage's product depends on, as recorded in it:
// a stage whose recorded options differ from these reruns.
nlohmann::json IngestFingerprint(const PipelineOptions& o);
// The feature options (features/options.json): changed, every image's
// features are extracted again.
nlohmann::json FeatureFingerprint(const PipelineOptions& o);
// The match options and the features they matched (matches.json "options").
nlohmann::json MatchFingerprint(const PipelineOptions& o);
// The mapper options and the matches it reconstructed from
// (reconstruction.json "options").
nlohmann::json ReconstructFingerprint(const PipelineOptions& o);
nlohmann::json GeoreferenceFingerprint(const PipelineOptions& o);
nlohmann::json DenseFingerprint(const PipelineOptions& o);
nlohmann::json OrthoFingerprint(const PipelineOptions& o);
// report.json "provenance" of the adjustment: software version, command line
// and UTC date of the process that ran the georeference stage, with the
// options that produced it -- ingest's as recorded in ingest.json (it may
// have run in another process), the georeference stage's own. The dense
// stage's are in report.json dense.options (from dense.json).
nlohmann::json Provenance(const PipelineOptions& o, const nlohmann::json& ingest_options);
// The process that made a report: software version, command line and UTC
// date (Provenance's first part; `aerotri adjust` and `check` record it too).
nlohmann::json ProcessProvenance(const std::string& software, const std::vector<std::string>& command_line);
// "" when equal, else "key: recorded -> now; ..." (only differing keys).
std::string FingerprintChanges(const nlohmann::json& recorded, const nlohmann::json& now);
// Whether a stage's product, recorded in record (under key; "" for the
// whole file; a missing file records nothing), was made under the options
// and inputs now: says "STAGE: done already" when so, else what changed and
// that it reruns with the stages after it.
bool StageIsCurrent(const PipelineOptions& o, const std::string& stage, const std::filesystem::path& record,
                    const std::string& key, const nlohmann::json& now);

// matches.json: the match stage's product besides matches.bin, typed.
struct MatchRecord {
  static constexpr int kSchemaVersion = 1;
  std::string strategy;  // how candidate pairs were chosen
  int candidate_pairs = 0;
  int verified_pairs = 0;
  struct Image {
    std::string name;
    int features = 0;
    int verified_pairs = 0;
    int verified_matches = 0;
  };
  std::vector<Image> images;  // every ingested image, in ingest order
  nlohmann::json options;     // MatchFingerprint at the time
};
nlohmann::json ToJson(const MatchRecord& record);
// Throws ParseError naming path and the field.
MatchRecord MatchRecordFromJson(const nlohmann::json& doc, const std::string& path);

// reconstruction.json: the reconstruct stage's record besides the model in
// reconstruction/, typed.
struct ReconstructionRecord {
  static constexpr int kSchemaVersion = 1;
  std::string initial_pair;
  int tracks = 0;
  int dropped_inconsistent_tracks = 0;
  int global_adjustments = 0;
  double adjustment_s = 0.0;  // wall time of the mapper's global adjustments
  int adjustment_iterations = 0;  // their solver iterations
  int local_adjustments = 0;
  double local_adjustment_s = 0.0;
  int registered = 0;
  bool focal_held = false;  // by the mapper (nadir, flat ground, one altitude)
  // The mapper moved the model into the GPS frame at this many registered
  // images and held the fixes as priors from then on (0: it did not).
  int gps_anchored_at_images = 0;
  int rolling_shutter_images = 0;  // photos whose rolling shutter it modelled
  struct Image {
    std::string name;
    bool registered = false;
    std::string why_not;  // when not registered
    int component = -1;   // when registered: 0 the main model, k a further component
  };
  std::vector<Image> images;  // every ingested image, in ingest order
  // Registered photos per component: the main model, then groups with no
  // tie points to it, placed by their GPS (MapperResult::component_images).
  std::vector<int> component_images;
  nlohmann::json options;     // ReconstructFingerprint at the time
};
nlohmann::json ToJson(const ReconstructionRecord& record);
// Throws ParseError naming path and the field.
ReconstructionRecord ReconstructionRecordFromJson(const nlohmann::json& doc, const std::string& path);
// The typed records of a workspace (IoError naming the stage to run when missing).
MatchRecord LoadMatchRecord(const PipelineOptions& o);
ReconstructionRecord LoadReconstructionRecord(const PipelineOptions& o);

struct IngestView {
  std::vector<std::string> names;
  std::vector<bool> usable;
  std::vector<double> scale;  // full px per working px
  std::vector<int> group;
  std::vector<std::optional<GpsFix>> gps;
  std::vector<Camera> cameras;  // per group, working px
  // Per group: the EXIF focal length (working px) when EXIF gave it in
  // millimetres with a sensor size; 0 when it was a guess.
  std::vector<double> focal_prior_px;
  IngestRecord record;
  // The photo folder ingest read (what later stages decode), else options'.
  std::filesystem::path ImagesDir(const PipelineOptions& o) const;
  // The workspace's one ENU origin: the mean GPS position of the usable
  // images (what match, reconstruct and georeference work in); none without GPS.
  std::optional<Geodetic> EnuOrigin() const;
  // The photos' gimbal angles (DJI XMP) by image name, where they have both
  // pitch and yaw.
  std::map<std::string, GimbalAttitude> GimbalAngles() const;
  // The rolling shutters the photos state (RollingShutterStatedBy), by
  // image name, the velocity in ENU; *source says where from, for the report.
  std::map<std::string, RollingShutterMotion> RollingShutters(std::string* source) const;
};

// The ingest stage's options, from the pipeline's.
IngestOptions IngestStageOptions(const PipelineOptions& o);
// The georeference stage's inputs (GPS, full-resolution scales, gimbal
// angles, control, check and camera files) and options (the workspace's ENU
// origin, EXIF focal priors): the stage's and `check --leave-one-out`'s.
SurveyAdjustmentInputs GeoreferenceInputs(const PipelineOptions& o, const IngestView& ingest);
GeoreferenceOptions GeoreferenceStageOptions(const PipelineOptions& o, const IngestView& ingest);

IngestView LoadIngest(const PipelineOptions& o);
// A working-resolution model at each photo's full resolution (one camera
// per group and size; pixels scaled about the pixel-centre convention).
SparseModel ToFullResolution(const SparseModel& model, const IngestView& ingest);
// Features of the usable images (empty for others); images whose features
// are missing are marked unusable.
std::vector<ImageFeatures> LoadFeatures(const PipelineOptions& o, IngestView* ingest);

}  // namespace aerotri
