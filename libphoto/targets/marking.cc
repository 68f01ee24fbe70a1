// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/targets/marking.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>

#include <opencv2/imgcodecs.hpp>

#include "georef/crs.h"
#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {
namespace {

struct Candidate {
  int image = 0;  // index into the model's images
  TargetDetection detection;
};

struct Surveyed {
  const GroundPoint* point = nullptr;
  bool check = false;
  Eigen::Vector3d enu = Eigen::Vector3d::Zero();
  Eigen::Vector3d model = Eigen::Vector3d::Zero();
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The model's frame in ENU from its camera centres and their GPS.
Similarity GeoreferenceByGps(const SparseModel& model, const std::map<std::string, GpsFix>& gps,
                             const LocalFrame& frame, int* gps_photos, double* sigma_h) {
  std::vector<Eigen::Vector3d> from, to;
  std::vector<double> sigmas;
  for (const Image& im : model.images) {
    const auto it = gps.find(im.name);
    if (!im.registered || it == gps.end()) continue;
    from.push_back(im.pose.centre_in_world);
    to.push_back(frame.EnuFromGeodetic(it->second.position));
    sigmas.push_back(it->second.sigma_h_m);
  }
  *gps_photos = static_cast<int>(from.size());
  if (from.size() < 3) {
    throw UsageError("marking targets from coordinates alone needs the photos' GPS to predict where the targets are: " +
                     std::to_string(from.size()) + " of the model's " + std::to_string(model.images.size()) +
                     " photos have it (at least 3 are needed); mark the targets by hand (gcp_list.txt with pixel "
                     "columns) for a survey without GPS");
  }
  *sigma_h = Median(sigmas);
  const auto fit = FitSimilarityRobust(from, to, std::max(1.0, 4.0 * *sigma_h));
  if (!fit) throw UsageError("the GPS positions of the photos lie on a line: the model cannot be georeferenced by them");
  return fit->transform;
}

// A point's height when it has none: the median of the model's points
// within 5 m horizontally (ENU), else the mean camera height minus nothing known: 0.
double HeightNear(const SparseModel& model, const Similarity& to_enu, const Eigen::Vector2d& en) {
  std::vector<double> z;
  for (const Point& p : model.points) {
    const Eigen::Vector3d e = to_enu.Apply(p.position);
    if ((e.head<2>() - en).norm() < 5.0) z.push_back(e.z());
  }
  return Median(z);
}

struct Cluster {
  std::vector<int> members;  // indices into the point's candidates, one per photo
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double rms_px = 0.0;
};

double ReprojectionError(const SparseModel& model, int image, const Eigen::Vector3d& x, const Eigen::Vector2d& xy) {
  const Image& im = model.images[image];
  const Eigen::Vector3d c = im.pose.CamFromWorld(x);
  if (c.z() <= 0) return 1e9;
  return (model.cameras[im.camera].ImageFromCamera(c) - xy).norm();
}

// The detections of the candidates that one triangulated point explains:
// the best one per photo within max_px.
Cluster Support(const SparseModel& model, const std::vector<Candidate>& cands, const Eigen::Vector3d& x,
                double max_px) {
  std::map<int, std::pair<double, int>> best;  // image -> (error, candidate)
  for (size_t k = 0; k < cands.size(); ++k) {
    const double e = ReprojectionError(model, cands[k].image, x, cands[k].detection.centre_px);
    if (e > max_px) continue;
    auto it = best.find(cands[k].image);
    if (it == best.end() || e < it->second.first) best[cands[k].image] = {e, static_cast<int>(k)};
  }
  Cluster c;
  c.position = x;
  double sq = 0.0;
  for (const auto& [image, entry] : best) {
    c.members.push_back(entry.second);
    sq += entry.first * entry.first;
  }
  c.rms_px = c.members.empty() ? 0.0 : std::sqrt(sq / c.members.size());
  return c;
}

std::optional<Eigen::Vector3d> Triangulate(const SparseModel& model, const std::vector<Candidate>& cands,
                                           const std::vector<int>& members) {
  std::vector<View> views;
  for (int k : members) {
    const Image& im = model.images[cands[k].image];
    views.push_back({&model.cameras[im.camera], im.pose, cands[k].detection.centre_px});
  }
  TriangulationOptions t;
  t.min_angle_deg = 0.5;
  const auto r = TriangulatePoint(views, t);
  if (!r) return std::nullopt;
  return r->position;
}

// The targets the detections of one point show: clusters of detections in
// different photos that one 3D point explains, the best supported first;
// a cluster's members are taken out before the next is sought.
std::vector<Cluster> ClusterCandidates(const SparseModel& model, const std::vector<Candidate>& cands, double max_px) {
  std::vector<Cluster> clusters;
  std::vector<char> taken(cands.size(), 0);
  for (int round = 0; round < 3; ++round) {
    std::vector<Candidate> left;
    std::vector<int> index;
    for (size_t k = 0; k < cands.size(); ++k) {
      if (!taken[k]) left.push_back(cands[k]), index.push_back(static_cast<int>(k));
    }
    std::optional<Cluster> best;
    for (size_t a = 0; a < left.size(); ++a) {
      for (size_t b = a + 1; b < left.size(); ++b) {
        if (left[a].image == left[b].image) continue;
        const auto x = Triangulate(model, left, {static_cast<int>(a), static_cast<int>(b)});
        if (!x) continue;
        Cluster c = Support(model, left, *x, max_px);
        if (c.members.size() < 2) continue;
        if (const auto refined = Triangulate(model, left, c.members)) {
          Cluster r = Support(model, left, *refined, max_px);
          if (r.members.size() >= c.members.size()) c = r;
        }
        if (!best || c.members.size() > best->members.size() ||
            (c.members.size() == best->members.size() && c.rms_px < best->rms_px)) {
          best = c;
        }
      }
    }
    if (!best) break;
    for (int& m : best->members) {
      m = index[m];
      taken[m] = 1;
    }
    clusters.push_back(*best);
  }
  return clusters;
}

// The photos' detections near every predicted point, each photo read once.
void DetectNearPredictions(const SparseModel& model, const std::filesystem::path& images_dir,
                           const std::vector<Surveyed>& points, const Similarity& to_enu, double radius_m,
                           const MarkingOptions& options, std::vector<PointMarking>* out,
                           std::vector<std::vector<Candidate>>* candidates) {
  std::mutex mutex;
  const unsigned threads = ThreadCount(options.num_threads);
  size_t done = 0;
  ParallelFor(model.images.size(), threads, [&](size_t i) {
    const Image& im = model.images[i];
    if (!im.registered) return;
    const Camera& camera = model.cameras[im.camera];
    cv::Mat photo;
    for (size_t p = 0; p < points.size(); ++p) {
      const Eigen::Vector3d c = im.pose.CamFromWorld(points[p].model);
      if (c.z() <= 0) continue;
      const Eigen::Vector2d px = camera.ImageFromCamera(c);
      const double margin = 2.0;
      if (px.x() < margin || px.y() < margin || px.x() > camera.width - 1 - margin ||
          px.y() > camera.height - 1 - margin) {
        continue;
      }
      const double radius_px = radius_m * camera.focal_px() / (c.z() * to_enu.scale);
      if (photo.empty()) {
        photo = cv::imread((images_dir / im.name).string(), cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
        if (photo.empty()) throw IoError((images_dir / im.name).string(), "cannot read the photo to mark targets in it");
      }
      const cv::Rect window = cv::Rect(static_cast<int>(px.x() - radius_px), static_cast<int>(px.y() - radius_px),
                                       static_cast<int>(2 * radius_px + 1), static_cast<int>(2 * radius_px + 1)) &
                              cv::Rect(0, 0, photo.cols, photo.rows);
      TargetDetectionOptions detection = options.detection;
      detection.max_radius_px = std::min(detection.max_radius_px, 0.5 * std::min(window.width, window.height));
      std::vector<TargetDetection> found = DetectTargets(photo(window), detection);
      std::lock_guard<std::mutex> lock(mutex);
      TargetMark mark;
      mark.image = im.name;
      mark.predicted_px = px;
      (*out)[p].photos.push_back(mark);
      for (TargetDetection& d : found) {
        d.centre_px += Eigen::Vector2d(window.x, window.y);
        (*candidates)[p].push_back({static_cast<int>(i), d});
      }
    }
    std::lock_guard<std::mutex> lock(mutex);
    ReportProgress(options.progress, static_cast<double>(++done) / model.images.size(),
                   "looking for targets in " + im.name);
  });
}

std::string Fixed(double v, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

// A point's status from its clusters; its marks from the chosen one.
// common_offset: the median offset of the points marked unambiguously
// (none on the first pass), which settles a point with two targets near it.
void Decide(const SparseModel& model, const std::vector<Candidate>& cands, const std::vector<Cluster>& clusters,
            double radius_m, const Similarity& to_enu, const Surveyed& s, const Eigen::Vector3d* common_offset,
            PointMarking* p) {
  if (p->photos.empty()) {
    p->status = "NOT_SEEN";
    p->reason = "no photo's footprint holds it (surveyed outside the area flown, or a wrong coordinate)";
    return;
  }
  const auto mark_from = [&](const std::vector<int>& members) {
    for (int k : members) {
      for (TargetMark& m : p->photos) {
        if (m.image != model.images[cands[k].image].name) continue;
        m.detected = true;
        m.xy_px = cands[k].detection.centre_px;
        m.confidence = cands[k].detection.confidence;
        m.kind = cands[k].detection.kind;
      }
    }
  };
  if (clusters.empty()) {
    // One photo: its one detection, unconfirmed.
    if (p->photos.size() == 1 && cands.size() == 1) {
      p->status = "SINGLE_PHOTO";
      p->reason = "seen in one photo only: its mark has nothing to confirm it";
      mark_from({0});
      return;
    }
    p->status = "NOT_FOUND";
    p->reason = "no target within " + Fixed(radius_m, 1) + " m of its surveyed position in the " +
                std::to_string(p->photos.size()) + " photos that should see it" +
                (cands.empty() ? "" : " (" + std::to_string(cands.size()) + " detections that no two photos agree on)");
    return;
  }
  size_t chosen = 0;
  const bool two = clusters.size() > 1 &&
                   clusters[1].members.size() >= std::max<size_t>(2, clusters[0].members.size() / 2) &&
                   (to_enu.scale * (clusters[1].position - clusters[0].position)).norm() > 0.2;
  bool resolved = !two;
  if (two && common_offset) {
    // The GPS georeferencing's offset is common to every point: the
    // target that shows it (within a metre, the other three times as far
    // and over 2 m off) is this point's; anything less is not decided.
    double d[2];
    for (int k = 0; k < 2; ++k) d[k] = (to_enu.Apply(clusters[k].position) - s.enu - *common_offset).norm();
    const int nearer = d[1] < d[0] ? 1 : 0;
    if (d[nearer] < 1.0 && d[1 - nearer] > std::max(2.0, 3.0 * d[nearer])) {
      chosen = static_cast<size_t>(nearer);
      resolved = true;
    }
  }
  if (!resolved) {
    p->status = "TWO_CANDIDATES";
    p->reason = "two targets near it, " +
                Fixed(to_enu.scale * (clusters[1].position - clusters[0].position).norm(), 2) +
                " m apart, seen in " + std::to_string(clusters[0].members.size()) + " and " +
                std::to_string(clusters[1].members.size()) +
                " photos, neither clearly at the offset the other points show" +
                (common_offset ? " (" + Fixed((to_enu.Apply(clusters[0].position) - s.enu - *common_offset).norm(), 2) +
                                     " and " + Fixed((to_enu.Apply(clusters[1].position) - s.enu - *common_offset).norm(), 2) +
                                     " m from it)"
                               : std::string()) +
                ": which is this point's is not guessed";
    return;
  }
  const Cluster& best = clusters[chosen];
  p->reason.clear();
  p->status = "MARKED";
  p->target_model = best.position;
  p->offset_m = to_enu.Apply(best.position) - s.enu;
  mark_from(best.members);
  for (TargetMark& m : p->photos) {
    if (!m.detected) continue;
    for (size_t i = 0; i < model.images.size(); ++i) {
      if (model.images[i].name == m.image) m.reprojection_px = ReprojectionError(model, static_cast<int>(i), best.position, m.xy_px);
    }
  }
}

}  // namespace

MarkingResult MarkControl(const SparseModel& model, const std::filesystem::path& images_dir,
                          const std::map<std::string, GpsFix>& gps, const Geodetic& enu_origin, const GcpFile& control,
                          const GcpFile* checks, const MarkingOptions& options) {
  const LocalFrame frame(enu_origin);
  MarkingResult result;
  double sigma_h = 0.0;
  result.model_to_enu = GeoreferenceByGps(model, gps, frame, &result.gps_photos, &sigma_h);
  result.search_radius_m = options.search_radius_m > 0 ? options.search_radius_m : std::max(1.5, 2.0 * sigma_h);
  const Similarity to_model = result.model_to_enu.Inverse();
  std::vector<Surveyed> points;
  for (const GcpFile* file : {&control, checks}) {
    if (!file) continue;
    const Crs crs = Crs::FromString(file->crs);
    for (const GroundPoint& g : file->points) {
      Surveyed s;
      s.point = &g;
      s.check = file == checks;
      Eigen::Vector3d xyz = g.xyz;
      if (g.horizontal_only) xyz.z() = 0.0;
      s.enu = frame.EnuFromGeodetic(crs.ToGeodetic(xyz));
      if (g.horizontal_only) s.enu.z() = HeightNear(model, result.model_to_enu, s.enu.head<2>());
      s.model = to_model.Apply(s.enu);
      points.push_back(s);
      PointMarking p;
      p.name = g.name;
      p.check = s.check;
      result.points.push_back(p);
    }
  }
  std::vector<std::vector<Candidate>> candidates(points.size());
  DetectNearPredictions(model, images_dir, points, result.model_to_enu, result.search_radius_m, options,
                        &result.points, &candidates);
  std::vector<std::vector<Cluster>> clusters(points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    PointMarking& p = result.points[k];
    std::sort(p.photos.begin(), p.photos.end(), [](const TargetMark& a, const TargetMark& b) { return a.image < b.image; });
    clusters[k] = ClusterCandidates(model, candidates[k], options.max_reprojection_px);
    // Rays of two different targets can meet by chance within the
    // tolerance (along an epipolar line): such a meeting far from where the
    // point was searched for is no target of it.
    const double limit = 1.5 * result.search_radius_m;
    clusters[k].erase(std::remove_if(clusters[k].begin(), clusters[k].end(),
                                     [&](const Cluster& c) {
                                       return (result.model_to_enu.Apply(c.position) - points[k].enu).norm() > limit;
                                     }),
                      clusters[k].end());
    Decide(model, candidates[k], clusters[k], result.search_radius_m, result.model_to_enu, points[k], nullptr, &p);
  }
  // Points with two targets near them, again, knowing the common offset.
  std::vector<double> offsets[3];
  for (const PointMarking& p : result.points) {
    if (p.status != "MARKED") continue;
    for (int a = 0; a < 3; ++a) offsets[a].push_back(p.offset_m[a]);
  }
  if (offsets[0].size() >= 2) {
    const Eigen::Vector3d common(Median(offsets[0]), Median(offsets[1]), Median(offsets[2]));
    for (size_t k = 0; k < points.size(); ++k) {
      if (result.points[k].status != "TWO_CANDIDATES") continue;
      Decide(model, candidates[k], clusters[k], result.search_radius_m, result.model_to_enu, points[k], &common,
             &result.points[k]);
    }
  }
  // One target for two points: neither is marked.
  for (size_t a = 0; a < points.size(); ++a) {
    for (size_t b = a + 1; b < points.size(); ++b) {
      PointMarking &pa = result.points[a], &pb = result.points[b];
      if (pa.status != "MARKED" || pb.status != "MARKED") continue;
      if (result.model_to_enu.scale * (pa.target_model - pb.target_model).norm() > 0.1) continue;
      for (auto [self, other] : {std::pair{&pa, &pb}, std::pair{&pb, &pa}}) {
        self->reason = "its target is " + other->name + "'s too (two points on one target): neither is marked";
        for (TargetMark& m : self->photos) m.detected = false;
      }
      pa.status = pb.status = "SHARED_TARGET";
    }
  }
  for (size_t k = 0; k < points.size(); ++k) {
    const PointMarking& p = result.points[k];
    if (!p.Marked()) continue;
    GcpFile& file = p.check ? result.check_marks : result.control_marks;
    GroundPoint g = *points[k].point;
    g.measurements.clear();
    for (const TargetMark& m : p.photos) {
      if (m.detected) g.measurements.push_back({m.image, m.xy_px, 0, std::nullopt});
    }
    file.points.push_back(g);
  }
  result.control_marks.crs = control.crs;
  if (checks) result.check_marks.crs = checks->crs;
  return result;
}

}  // namespace aerotri
