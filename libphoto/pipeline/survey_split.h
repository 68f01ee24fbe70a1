// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// A survey larger than one machine, as submodels: split the photos by their
// GPS positions into overlapping parts, reconstruct each part on its own
// (any machine: the parts are independent workspaces), then merge the parts'
// models into the survey's and adjust it once, globally, with every GPS fix
// and control point. The stages after the merge (georeference, dense, ortho,
// report) are the ordinary ones on the survey's workspace.
//
// The steps are aerotri subcommands, and the workflow that orders them is
// written for an existing engine (Snakemake: the same file runs on a laptop
// with --cores, or on a Slurm or Kubernetes cluster through its executors):
//
//   aerotri split PHOTOS -o WS --parts N   ingest, the parts, WS/Snakefile
//   (per part)  aerotri ingest / features / match / reconstruct
//               on WS/parts/<part>/ws, photos in WS/parts/<part>/images
//   aerotri merge -o WS                    WS/reconstruction/ from the parts
//   aerotri georeference / dense / ortho / report -o WS
//
// Parts: recursive bisection of the photos' GPS positions across the longer
// side of their extent into N cells of (nearly) equal counts; each part then
// takes its cell's photos and every photo within the seam margin of the
// cell, so that neighbouring parts share photos (a strip or two) and,
// through them, tie points. Merge: the parts are chained by their shared
// photos (a similarity from the shared camera centres, robust to a badly
// placed one), a photo in several parts keeps the pose of the part it was
// first merged from, and points of different parts that share an
// observation (the same keypoint of the same photo: every part extracts the
// same features from the same photo) become one point.

#include <filesystem>
#include <string>
#include <vector>

#include "libphoto/model/sparse_model.h"
#include "libphoto/pipeline/pipeline.h"

namespace aerotri {

struct SplitOptions {
  int parts = 4;
  // Seam margin (metres) around each part's cell; 0: 2.5 x the median
  // distance from a photo to its nearest neighbour (at least one strip on
  // each side of a seam at the usual overlaps).
  double margin_m = 0.0;
};

struct SurveyPart {
  std::string name;                 // "part1", ...
  std::vector<std::string> images;  // its photos, seam photos included
  int core = 0;                     // of which in its own cell
};

// The parts of the ingested survey in options.workspace (GPS of usable
// photos; photos without GPS join the part of their capture-order
// neighbour). Throws InvalidArgument when there are fewer photos with GPS
// than 3 per part, or fewer than 2 parts are asked for.
std::vector<SurveyPart> SplitSurvey(const PipelineOptions& options, const SplitOptions& split);

// WS/parts/<part>/images/ (symbolic links to the photos), WS/parts/plan.json
// and WS/Snakefile, whose rules call `aerotri` (the executable path given)
// with the options of `options` that each step reads (the photos' GPS,
// working size, threads). The global adjustment's step is given
// georeference_args as they are (control, check points, CRS, the adjustment
// policy: `aerotri georeference`'s options; paths absolute, as the workflow
// runs in WS).
void WriteSplitWorkflow(const PipelineOptions& options, const std::vector<SurveyPart>& parts,
                        const std::filesystem::path& aerotri_executable,
                        const std::vector<std::string>& georeference_args);

struct MergeSummary {
  int parts = 0;
  int images = 0;         // registered in the merged model
  int shared_images = 0;  // registered in two or more parts
  int points = 0;
  int merged_points = 0;  // points joined across parts
  std::vector<double> seam_rms_m;  // per part after the first: shared camera centres after alignment
  std::vector<std::string> unlinked_parts;  // parts with fewer than 3 shared photos: left out
};

// Merges part models (each in its own frame) into one model in the first
// part's frame. Cameras are taken per name of the photo's camera group:
// camera_of_image maps a photo name to its index in `cameras`, the merged
// model's cameras (the survey's camera groups, at the working resolution).
SparseModel MergePartModels(const std::vector<SparseModel>& parts, const std::vector<Camera>& cameras,
                            const std::map<std::string, int>& camera_of_image, MergeSummary* summary);

// `aerotri merge`: reads WS/parts/plan.json and each part's
// reconstruction/, writes WS/reconstruction/ and WS/reconstruction.json
// (every photo of the survey: registered, or why not) and removes an earlier
// georeferenced survey (it reruns). Returns the summary.
MergeSummary RunMergeStage(const PipelineOptions& options);

}  // namespace aerotri
