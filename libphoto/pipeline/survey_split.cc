// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/pipeline/survey_split.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <tuple>

#include "georef/local_frame.h"
#include "georef/similarity.h"
#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/io/colmap_text.h"
#include "libphoto/pipeline/workspace.h"

namespace aerotri {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct Cell {
  std::vector<int> photos;  // indices into the positions
  Eigen::Vector2d lo, hi;   // the cell's rectangle (unbounded at the survey's edge)
};

// Recursive bisection into k cells of (nearly) equal counts, across the
// longer side of each cell's photos.
void Bisect(const std::vector<Eigen::Vector2d>& xy, Cell cell, int k, std::vector<Cell>* out) {
  if (k <= 1 || cell.photos.size() < 2) {
    out->push_back(cell);
    return;
  }
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (int p : cell.photos) {
    lo = lo.cwiseMin(xy[p]);
    hi = hi.cwiseMax(xy[p]);
  }
  const int axis = (hi.x() - lo.x()) >= (hi.y() - lo.y()) ? 0 : 1;
  std::sort(cell.photos.begin(), cell.photos.end(), [&](int a, int b) {
    return std::make_pair(xy[a][axis], a) < std::make_pair(xy[b][axis], b);
  });
  const int k1 = k / 2;
  const size_t cut = cell.photos.size() * k1 / k;
  const double at = 0.5 * (xy[cell.photos[cut - 1]][axis] + xy[cell.photos[cut]][axis]);
  Cell a, b;
  a.photos.assign(cell.photos.begin(), cell.photos.begin() + cut);
  b.photos.assign(cell.photos.begin() + cut, cell.photos.end());
  a.lo = b.lo = cell.lo;
  a.hi = b.hi = cell.hi;
  a.hi[axis] = at;
  b.lo[axis] = at;
  Bisect(xy, a, k1, out);
  Bisect(xy, b, k - k1, out);
}

// An argument for a Snakefile rule's shell command: single-quoted for the
// shell, then escaped for the rule's Python string and Snakemake's format
// (braces doubled).
std::string Quote(const std::string& s) {
  std::string shell = "'";
  for (char c : s) shell += c == '\'' ? std::string("'\\''") : std::string(1, c);
  shell += "'";
  std::string out;
  for (char c : shell) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '{' || c == '}') out += c;
    out += c;
  }
  return out;
}

// The similarity from a part's frame to the merged one from the shared
// camera centres: least squares, then robust (RANSAC) with inliers within
// 3x the least-squares fit's median residual, so that one photo placed
// badly in a part does not bend the seam. std::nullopt when collinear.
std::optional<SimilarityFit> FitSeam(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to) {
  const std::optional<Similarity> ls = FitSimilarity(from, to);
  if (!ls) return std::nullopt;
  std::vector<double> residuals;
  for (size_t k = 0; k < from.size(); ++k) residuals.push_back((ls->Apply(from[k]) - to[k]).norm());
  std::nth_element(residuals.begin(), residuals.begin() + residuals.size() / 2, residuals.end());
  double extent = 0.0;
  for (const auto& x : to) extent = std::max(extent, (x - to.front()).norm());
  return FitSimilarityRobust(from, to, std::max(3.0 * residuals[residuals.size() / 2], 1e-9 * extent));
}

}  // namespace

std::vector<SurveyPart> SplitSurvey(const PipelineOptions& o, const SplitOptions& split) {
  if (split.parts < 2) throw InvalidArgument("--parts: expected 2 or more parts, got " + std::to_string(split.parts));
  const IngestView ingest = LoadIngest(o);
  const auto origin = ingest.EnuOrigin();
  if (!origin) throw InvalidArgument("split: the photos have no GPS positions to split the survey by");
  const LocalFrame frame(*origin);
  std::vector<Eigen::Vector2d> xy;
  std::vector<int> image_of;  // position index -> ingest index
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    if (!ingest.usable[i] || !ingest.gps[i]) continue;
    xy.push_back(frame.EnuFromGeodetic(ingest.gps[i]->position).head<2>());
    image_of.push_back(static_cast<int>(i));
  }
  if (xy.size() < 3u * split.parts) {
    throw InvalidArgument("split: " + std::to_string(xy.size()) + " photos with GPS cannot make " +
                          std::to_string(split.parts) + " parts of at least 3");
  }
  double margin = split.margin_m;
  if (!(margin > 0)) {
    std::vector<double> nearest;
    for (size_t a = 0; a < xy.size(); ++a) {
      double best = std::numeric_limits<double>::infinity();
      for (size_t b = 0; b < xy.size(); ++b) {
        if (a != b) best = std::min(best, (xy[a] - xy[b]).norm());
      }
      nearest.push_back(best);
    }
    std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
    margin = 2.5 * nearest[nearest.size() / 2];
  }
  Cell all;
  for (size_t p = 0; p < xy.size(); ++p) all.photos.push_back(static_cast<int>(p));
  all.lo = Eigen::Vector2d::Constant(-std::numeric_limits<double>::infinity());
  all.hi = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  std::vector<Cell> cells;
  Bisect(xy, all, split.parts, &cells);
  std::vector<SurveyPart> parts;
  std::vector<int> cell_of_position(xy.size(), 0);
  for (size_t c = 0; c < cells.size(); ++c) {
    for (int p : cells[c].photos) cell_of_position[p] = static_cast<int>(c);
  }
  std::vector<std::set<int>> members(cells.size());  // ingest indices
  for (size_t c = 0; c < cells.size(); ++c) {
    for (size_t p = 0; p < xy.size(); ++p) {
      const bool inside = (xy[p].array() >= cells[c].lo.array() - margin).all() &&
                          (xy[p].array() <= cells[c].hi.array() + margin).all();
      if (inside || cell_of_position[p] == static_cast<int>(c)) members[c].insert(image_of[p]);
    }
  }
  // Photos without GPS: with their capture-order neighbour's cell.
  std::vector<int> cell_of_image(ingest.names.size(), -1);
  for (size_t p = 0; p < xy.size(); ++p) cell_of_image[image_of[p]] = cell_of_position[p];
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    if (!ingest.usable[i] || cell_of_image[i] >= 0) continue;
    for (size_t d = 1; d < ingest.names.size(); ++d) {
      for (long j : {static_cast<long>(i) - static_cast<long>(d), static_cast<long>(i + d)}) {
        if (j < 0 || j >= static_cast<long>(ingest.names.size()) || !ingest.gps[j] || cell_of_image[j] < 0) continue;
        members[cell_of_image[j]].insert(static_cast<int>(i));
        d = ingest.names.size();
        break;
      }
    }
  }
  for (size_t c = 0; c < cells.size(); ++c) {
    SurveyPart part;
    part.name = "part" + std::to_string(c + 1);
    for (int i : members[c]) part.images.push_back(ingest.names[i]);
    part.core = static_cast<int>(cells[c].photos.size());
    parts.push_back(part);
  }
  return parts;
}

void WriteSplitWorkflow(const PipelineOptions& o, const std::vector<SurveyPart>& parts, const fs::path& aerotri,
                        const std::vector<std::string>& georeference_args) {
  const IngestView ingest = LoadIngest(o);
  const fs::path photos = fs::absolute(ingest.ImagesDir(o));
  json plan = {{"parts", json::array()}, {"images_dir", photos.string()}};
  for (const SurveyPart& part : parts) {
    const fs::path dir = o.workspace / "parts" / part.name / "images";
    fs::remove_all(dir);  // links of an earlier split: a part holds exactly its photos
    fs::create_directories(dir);
    for (const std::string& name : part.images) fs::create_symlink(photos / name, dir / name);
    plan["parts"].push_back({{"name", part.name}, {"images", part.images}, {"core", part.core}});
  }
  WriteTextFileAtomically(o.workspace / "parts" / "plan.json", plan.dump(2) + "\n");

  const std::string exe = "{AEROTRI:q}";  // Snakemake quotes it for the shell
  const size_t shares = parts.size();  // the dense stage's jobs, as many as the parts'
  const std::string threads = o.num_threads > 0 ? " --threads " + std::to_string(o.num_threads) : "";
  std::string georef;
  for (const std::string& arg : georeference_args) {
    const bool plain = !arg.empty() && std::all_of(arg.begin(), arg.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("_./,:=+-", c) != nullptr;
    });
    georef += " " + (plain ? arg : Quote(arg));
  }
  // The parts read their photos' GPS as the survey's ingest did.
  std::ostringstream ingest_args;
  ingest_args << " --max-dimension " << o.features.max_dimension << " --gps-altitude "
              << (o.gps_altitude == AltitudeReference::kEllipsoid ? "ellipsoid" : "egm96") << " --gps-sigma-h "
              << o.gps_sigma_h_m << " --gps-sigma-v " << o.gps_sigma_v_m;
  if (!o.gps_csv.empty()) ingest_args << " --gps-csv " << Quote(fs::absolute(o.gps_csv).string());
  std::ostringstream s;
  s << "# aerotri split workflow: " << parts.size() << " parts of " << ingest.names.size() << " photos.\n"
    << "# Run in this folder: snakemake --cores 2 (a laptop), or with a cluster executor,\n"
    << "# e.g. snakemake --executor slurm --jobs 8 (each part is an independent job).\n"
    << "# Steps are aerotri subcommands; each resumes when rerun.\n"
    << "AEROTRI = " << json(fs::absolute(aerotri).string()).dump() << "  # the aerotri executable every step calls\n"
    << "PARTS = [";
  for (size_t k = 0; k < parts.size(); ++k) s << (k ? ", " : "") << "\"" << parts[k].name << "\"";
  s << "]\n"
    << "SHARES = list(range(1, " << shares << " + 1))  # of the dense and ortho stages\n"
    << "wildcard_constraints:\n    share=\"[0-9]+\"\n\n"
    << "rule all:\n    input: \"report.html\"\n\n"
    << "rule part_sparse:\n"
    << "    input: \"parts/plan.json\"\n"
    << "    output: \"parts/{part}/ws/reconstruction.json\"\n"
    << "    threads: 2\n"
    << "    shell:\n"
    << "        \"" << exe << " ingest parts/{wildcards.part}/images -o parts/{wildcards.part}/ws --quiet"
    << ingest_args.str() << " && "
    << exe << " features -o parts/{wildcards.part}/ws --quiet --threads {threads}"
    << " --max-dimension " << o.features.max_dimension << " && "
    << exe << " match -o parts/{wildcards.part}/ws --quiet --threads {threads} && "
    << exe << " reconstruct -o parts/{wildcards.part}/ws --quiet --threads {threads}\"\n\n"
    << "rule merge:\n"
    << "    input: expand(\"parts/{part}/ws/reconstruction.json\", part=PARTS)\n"
    << "    output: \"reconstruction.json\"\n"
    << "    shell: \"" << exe << " merge -o . --quiet\"\n\n"
    // The adjusted model (georeferenced/) is what follows reads, and nothing
    // after the georeference rewrites it (report.json is completed by the
    // report step: as an input it would make every later step look stale).
    << "rule georeference:\n"
    << "    input: \"reconstruction.json\"\n"
    << "    output: \"georeferenced/images.txt\"\n"
    << "    shell: \"" << exe << " georeference -o . --quiet" << threads << georef << "\"\n\n"
    // The dense stage in as many shares as parts, each an independent job:
    // the depth maps of a share of the pairs, then (all of them done) the
    // fusion of a share of the ground tiles, then the deliverables from the
    // fused shares. The records are Snakemake's temp files; the depth maps
    // and fused points are removed by the last step.
    << "rule dense_depth:\n"
    << "    input: \"georeferenced/images.txt\"\n"
    << "    output: temp(\"dense_parts/depth_{share}_of_" << shares << ".json\")\n"
    << "    threads: 2\n"
    << "    shell: \"" << exe << " dense -o . --quiet --threads {threads} --depth-share {wildcards.share}/" << shares
    << "\"\n\n"
    << "rule dense_fuse:\n"
    << "    input: expand(\"dense_parts/depth_{share}_of_" << shares << ".json\", share=SHARES)\n"
    << "    output: temp(\"dense_parts/fused_{share}_of_" << shares << ".json\")\n"
    << "    threads: 2\n"
    << "    shell: \"" << exe << " dense -o . --quiet --threads {threads} --fuse-share {wildcards.share}/" << shares
    << "\"\n\n"
    << "rule dense:\n"
    << "    input:\n"
    << "        expand(\"dense_parts/depth_{share}_of_" << shares << ".json\", share=SHARES),\n"
    << "        expand(\"dense_parts/fused_{share}_of_" << shares << ".json\", share=SHARES)\n"
    << "    output: \"dsm.tif\"\n"
    << "    shell: \"" << exe << " dense -o . --quiet" << threads << " --from-shares " << shares << "\"\n\n"
    // The orthomosaic in bands of tile rows, each an independent job (the
    // seams and exposure are the whole survey's, computed alike by each),
    // then joined into ortho.tif.
    << "rule ortho_band:\n"
    << "    input: \"dsm.tif\"\n"
    << "    output: temp(\"ortho_parts/band_{share}_of_" << shares << ".json\")\n"
    << "    threads: 2\n"
    << "    shell: \"" << exe << " ortho -o . --quiet --threads {threads} --band-share {wildcards.share}/" << shares
    << "\"\n\n"
    << "rule ortho:\n"
    << "    input: expand(\"ortho_parts/band_{share}_of_" << shares << ".json\", share=SHARES)\n"
    << "    output: \"ortho.tif\"\n"
    << "    shell: \"" << exe << " ortho -o . --quiet" << threads << " --from-shares " << shares << "\"\n\n"
    << "rule report:\n"
    << "    input: \"ortho.tif\"\n"
    << "    output: \"report.html\"\n"
    << "    shell: \"" << exe << " report -o . --quiet\"\n";
  WriteTextFileAtomically(o.workspace / "Snakefile", s.str());
}

SparseModel MergePartModels(const std::vector<SparseModel>& parts, const std::vector<Camera>& cameras,
                            const std::map<std::string, int>& camera_of_image, MergeSummary* summary) {
  MergeSummary local;
  MergeSummary& sum = summary ? *summary : local;
  sum = MergeSummary();
  sum.parts = static_cast<int>(parts.size());
  SparseModel merged;
  merged.cameras = cameras;
  std::vector<bool> camera_set(cameras.size(), false);
  std::map<std::string, int> merged_image;
  // An observation by photo and pixel: every part extracts the same
  // keypoints from the same photo, so equal keys are the same measurement.
  std::map<std::tuple<int, double, double>, int> point_of_observation;
  std::vector<bool> done(parts.size(), false);
  std::map<std::string, int> parts_of_image;
  for (const SparseModel& part : parts) {
    for (const Image& im : part.images) {
      if (im.registered) ++parts_of_image[im.name];
    }
  }
  for (const auto& [name, n] : parts_of_image) sum.shared_images += n > 1 ? 1 : 0;
  for (size_t round = 0; round < parts.size(); ++round) {
    // The next part: the one sharing the most photos with the merged model
    // (the first part first).
    int next = -1;
    size_t best = 0;
    std::vector<Eigen::Vector3d> from, to;
    for (size_t k = 0; k < parts.size(); ++k) {
      if (done[k]) continue;
      if (round == 0) {
        next = static_cast<int>(k);
        break;
      }
      size_t shared = 0;
      for (const Image& im : parts[k].images) shared += im.registered && merged_image.count(im.name) ? 1 : 0;
      if (shared > best) {
        best = shared;
        next = static_cast<int>(k);
      }
    }
    if (next < 0 || (round > 0 && best < 3)) break;
    done[next] = true;
    const SparseModel& part = parts[next];
    Similarity s;
    if (round > 0) {
      for (const Image& im : part.images) {
        const auto it = merged_image.find(im.name);
        if (!im.registered || it == merged_image.end()) continue;
        from.push_back(im.pose.centre_in_world);
        to.push_back(merged.images[it->second].pose.centre_in_world);
      }
      const std::optional<SimilarityFit> fit = FitSeam(from, to);
      if (!fit) {
        done[next] = false;  // collinear shared photos: cannot be placed
        break;
      }
      s = fit->transform;
      sum.seam_rms_m.push_back(fit->rms_m);
    }
    const Eigen::Quaterniond rotation = s.rotation;
    std::vector<int> image_map(part.images.size(), -1);
    for (size_t i = 0; i < part.images.size(); ++i) {
      const Image& im = part.images[i];
      if (!im.registered) continue;
      const auto it = merged_image.find(im.name);
      if (it != merged_image.end()) {
        image_map[i] = it->second;
        continue;
      }
      const auto cam = camera_of_image.find(im.name);
      if (cam == camera_of_image.end()) continue;  // not a photo of this survey
      Image out = im;
      out.id = static_cast<int>(merged.images.size()) + 1;
      out.camera = cam->second;
      out.pose.centre_in_world = s.Apply(im.pose.centre_in_world);
      out.pose.cam_from_world = (im.pose.cam_from_world * rotation.conjugate()).normalized();
      if (!camera_set[cam->second]) {  // the intrinsics the first part refined
        merged.cameras[cam->second].params = part.cameras[im.camera].params;
        camera_set[cam->second] = true;
      }
      image_map[i] = static_cast<int>(merged.images.size());
      merged_image[im.name] = image_map[i];
      merged.images.push_back(out);
    }
    std::vector<std::vector<int>> observations_of(part.points.size());
    for (size_t k = 0; k < part.observations.size(); ++k) {
      observations_of[part.observations[k].point].push_back(static_cast<int>(k));
    }
    for (size_t p = 0; p < part.points.size(); ++p) {
      if (part.points[p].role != PointRole::kTie) continue;
      int target = -1;
      for (int k : observations_of[p]) {
        const Observation& obs = part.observations[k];
        if (image_map[obs.image] < 0) continue;
        const auto it = point_of_observation.find({image_map[obs.image], obs.xy.x(), obs.xy.y()});
        if (it != point_of_observation.end()) {
          target = it->second;
          break;
        }
      }
      if (target >= 0) {
        ++sum.merged_points;
      }
      for (int k : observations_of[p]) {
        const Observation& obs = part.observations[k];
        if (image_map[obs.image] < 0) continue;
        const std::tuple<int, double, double> key{image_map[obs.image], obs.xy.x(), obs.xy.y()};
        if (point_of_observation.count(key)) continue;  // already measured (by this or another point)
        if (target < 0) {
          Point point = part.points[p];
          point.id = static_cast<int>(merged.points.size()) + 1;
          point.position = s.Apply(point.position);
          target = static_cast<int>(merged.points.size());
          merged.points.push_back(point);
        }
        Observation out = obs;
        out.image = image_map[obs.image];
        out.point = target;
        out.keypoint = -1;
        point_of_observation[key] = target;
        merged.observations.push_back(out);
      }
    }
  }
  for (size_t k = 0; k < parts.size(); ++k) {
    if (!done[k]) sum.unlinked_parts.push_back(std::to_string(k + 1));
  }
  // Points measured in fewer than two photos after the merge carry nothing.
  std::vector<int> count(merged.points.size(), 0);
  for (const Observation& obs : merged.observations) ++count[obs.point];
  std::vector<int> remap(merged.points.size(), -1);
  SparseModel out;
  out.cameras = merged.cameras;
  out.images = merged.images;
  for (size_t p = 0; p < merged.points.size(); ++p) {
    if (count[p] < 2) continue;
    remap[p] = static_cast<int>(out.points.size());
    Point point = merged.points[p];
    point.id = remap[p] + 1;
    out.points.push_back(point);
  }
  for (Observation obs : merged.observations) {
    if (remap[obs.point] < 0) continue;
    obs.point = remap[obs.point];
    out.observations.push_back(obs);
  }
  sum.images = static_cast<int>(out.images.size());
  sum.points = static_cast<int>(out.points.size());
  return out;
}

MergeSummary RunMergeStage(const PipelineOptions& o) {
  const fs::path plan_path = o.workspace / "parts" / "plan.json";
  const json plan = ReadJson(plan_path, "split");
  const IngestView ingest = LoadIngest(o);
  std::map<std::string, int> camera_of_image;
  for (size_t i = 0; i < ingest.names.size(); ++i) camera_of_image[ingest.names[i]] = std::max(0, ingest.group[i]);
  std::vector<SparseModel> parts;
  std::map<std::string, std::string> why_not;  // of photos no part registered
  for (const json& part : plan.at("parts")) {
    const fs::path ws = o.workspace / "parts" / part.at("name").get<std::string>() / "ws";
    PipelineOptions po = o;
    po.workspace = ws;
    const ReconstructionRecord record = LoadReconstructionRecord(po);
    for (const auto& im : record.images) {
      if (!im.registered && !im.why_not.empty()) why_not[im.name] = part.at("name").get<std::string>() + ": " + im.why_not;
    }
    parts.push_back(ReadColmapText(ws / "reconstruction"));
  }
  MergeSummary summary;
  const SparseModel merged = MergePartModels(parts, ingest.cameras, camera_of_image, &summary);
  if (!summary.unlinked_parts.empty()) {
    std::string names;
    for (const std::string& p : summary.unlinked_parts) names += (names.empty() ? "part" : ", part") + p;
    throw InvalidArgument(plan_path.string() + ": " + names +
                          " share fewer than 3 registered photos with the rest: widen the seams (--seam-margin) "
                          "or use fewer parts");
  }
  if (fs::exists(o.workspace / "report.json")) {
    Log(o, "merge: a new model: the earlier georeference (report.json, sparse/) is removed and reruns");
    fs::remove(o.workspace / "report.json");
    fs::remove_all(o.workspace / "sparse");
  }
  WriteColmapText(merged, o.workspace / "reconstruction");
  ReconstructionRecord doc;
  doc.initial_pair = "merged from " + std::to_string(summary.parts) + " parts";
  doc.tracks = summary.points;
  doc.registered = summary.images;
  std::set<std::string> registered;
  for (const Image& im : merged.images) registered.insert(im.name);
  for (size_t i = 0; i < ingest.names.size(); ++i) {
    ReconstructionRecord::Image im{ingest.names[i], registered.count(ingest.names[i]) > 0, ""};
    if (!ingest.usable[i]) {
      im.why_not = "unusable image (unreadable or undecodable)";
    } else if (!im.registered) {
      const auto it = why_not.find(ingest.names[i]);
      im.why_not = it != why_not.end() ? it->second : "in no part of the split";
    }
    doc.images.push_back(im);
  }
  doc.options = ReconstructFingerprint(o);
  WriteTextFileAtomically(o.workspace / "reconstruction.json", ToJson(doc).dump(2) + "\n");
  std::ostringstream msg;
  msg << "merge: " << summary.parts << " parts, " << summary.images << " photos (" << summary.shared_images
      << " in two or more parts), " << summary.points << " tie points (" << summary.merged_points
      << " joined across parts); shared camera centres after alignment, RMS per seam:";
  for (double r : summary.seam_rms_m) msg << " " << r << " m";
  Log(o, msg.str());
  return summary;
}

}  // namespace aerotri
