// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/targets/marking.h"

#include <algorithm>
#include <array>
#include <tuple>
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

constexpr const char* kNotSeen =
    "no photo's footprint holds it (surveyed outside the area flown, or a wrong coordinate)";

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

// The model's frame in ENU from its camera centres and their GPS; none when
// fewer than 3 photos have GPS or their positions lie on a line (one strip
// flown straight leaves the roll about it open).
std::optional<Similarity> GeoreferenceByGps(const SparseModel& model, const std::map<std::string, GpsFix>& gps,
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
  if (from.size() < 3) return std::nullopt;
  *sigma_h = Median(sigmas);
  const auto fit = FitSimilarityRobust(from, to, std::max(1.0, 4.0 * *sigma_h));
  if (!fit) return std::nullopt;
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

// The cluster that the rays of candidates a and b (in two photos) start:
// the detections their point explains, refined once on all of them; none
// when the rays do not meet or fewer than min_members photos agree.
std::optional<Cluster> ClusterFromPair(const SparseModel& model, const std::vector<Candidate>& cands, size_t a,
                                       size_t b, double max_px, size_t min_members) {
  if (cands[a].image == cands[b].image) return std::nullopt;
  const auto x = Triangulate(model, cands, {static_cast<int>(a), static_cast<int>(b)});
  if (!x) return std::nullopt;
  Cluster c = Support(model, cands, *x, max_px);
  if (c.members.size() < min_members) return std::nullopt;
  if (const auto refined = Triangulate(model, cands, c.members)) {
    Cluster r = Support(model, cands, *refined, max_px);
    if (r.members.size() >= c.members.size()) c = r;
  }
  return c;
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
        const std::optional<Cluster> found = ClusterFromPair(model, left, a, b, max_px, 2);
        if (!found) continue;
        const Cluster& c = *found;
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
// everywhere: the detections in whole photos when made already (photos
// without GPS); those near a prediction are its candidates, and no photo is
// read again.
void DetectNearPredictions(const SparseModel& model, const std::filesystem::path& images_dir,
                           const std::vector<Surveyed>& points, const Similarity& to_enu, double radius_m,
                           const MarkingOptions& options, const std::vector<Candidate>* everywhere,
                           std::vector<PointMarking>* out, std::vector<std::vector<Candidate>>* candidates) {
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
      const double radius_px = radius_m * camera.focal_px() / (c.z() * to_enu.scale);
      // The prediction carries the georeferencing's offset (metres with
      // GPS): a target near the photo's edge can be predicted just outside
      // it, so a photo is searched wherever its search window meets it.
      // Photos whose prediction lies outside and that show no target are
      // dropped once the points are decided (DropUnseenOutside).
      const auto within = [&](double margin) {
        return px.x() >= margin && px.y() >= margin && px.x() <= camera.width - 1 - margin &&
               px.y() <= camera.height - 1 - margin;
      };
      const bool inside = within(2.0);
      if (!within(everywhere ? 2.0 : 2.0 - radius_px)) continue;
      std::vector<Candidate> near;
      if (everywhere) {
        for (const Candidate& d : *everywhere) {
          if (d.image == static_cast<int>(i) && (d.detection.centre_px - px).norm() <= radius_px) near.push_back(d);
        }
      } else {
        if (photo.empty()) {
          photo = cv::imread((images_dir / im.name).string(), cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
          if (photo.empty()) throw IoError((images_dir / im.name).string(), "cannot read the photo to mark targets in it");
        }
        const cv::Rect window = cv::Rect(static_cast<int>(px.x() - radius_px), static_cast<int>(px.y() - radius_px),
                                         static_cast<int>(2 * radius_px + 1), static_cast<int>(2 * radius_px + 1)) &
                                cv::Rect(0, 0, photo.cols, photo.rows);
        TargetDetectionOptions detection = options.detection;
        detection.max_radius_px = std::min(detection.max_radius_px, 0.5 * std::min(window.width, window.height));
        for (TargetDetection& d : DetectTargets(photo(window), detection)) {
          d.centre_px += Eigen::Vector2d(window.x, window.y);
          near.push_back({static_cast<int>(i), d});
        }
      }
      std::lock_guard<std::mutex> lock(mutex);
      TargetMark mark;
      mark.image = im.name;
      mark.predicted_px = px;
      mark.predicted_inside = inside;
      (*out)[p].photos.push_back(mark);
      (*candidates)[p].insert((*candidates)[p].end(), near.begin(), near.end());
    }
    std::lock_guard<std::mutex> lock(mutex);
    ReportProgress(options.progress, static_cast<double>(++done) / model.images.size(),
                   "looking for targets in " + im.name);
  });
}

// The photos searched because their window met them, whose prediction lies
// outside the photo and which show no mark of the point: not photos that
// see it.
void DropUnseenOutside(std::vector<PointMarking>* points) {
  for (PointMarking& p : *points) {
    p.photos.erase(std::remove_if(p.photos.begin(), p.photos.end(),
                                  [](const TargetMark& m) { return !m.detected && !m.predicted_inside; }),
                   p.photos.end());
    if (p.photos.empty() && p.status == "NOT_FOUND") {
      p.status = "NOT_SEEN";
      p.reason = kNotSeen;
    }
  }
}

std::string Fixed(double v, int digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

// Every target in every registered photo (photos without GPS: nothing
// predicts where the targets are).
std::vector<Candidate> DetectEverywhere(const SparseModel& model, const std::filesystem::path& images_dir,
                                        const MarkingOptions& options) {
  std::vector<Candidate> all;
  std::mutex mutex;
  size_t done = 0;
  ParallelFor(model.images.size(), ThreadCount(options.num_threads), [&](size_t i) {
    const Image& im = model.images[i];
    if (!im.registered) return;
    const cv::Mat photo =
        cv::imread((images_dir / im.name).string(), cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
    if (photo.empty()) throw IoError((images_dir / im.name).string(), "cannot read the photo to mark targets in it");
    const std::vector<TargetDetection> found = DetectTargets(photo, options.detection);
    std::lock_guard<std::mutex> lock(mutex);
    for (const TargetDetection& d : found) all.push_back({static_cast<int>(i), d});
    ReportProgress(options.progress, 0.5 * static_cast<double>(++done) / model.images.size(),
                   "looking for targets in the whole of " + im.name);
  });
  // The order of the threads must not change the result.
  std::sort(all.begin(), all.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.image, a.detection.centre_px.x(), a.detection.centre_px.y()) <
           std::tie(b.image, b.detection.centre_px.x(), b.detection.centre_px.y());
  });
  return all;
}

// The targets the photos show: detections in at least three photos that one
// point explains (within max_px in each), the best supported first, each
// detection in one target. Every pair of detections in two photos is a
// hypothesis: two rays of different targets can meet by chance, but a third
// photo does not agree with them.
std::vector<Cluster> TargetsInPhotos(const SparseModel& model, const std::vector<Candidate>& cands, double max_px) {
  std::vector<Cluster> hypotheses;
  for (size_t a = 0; a < cands.size(); ++a) {
    for (size_t b = a + 1; b < cands.size(); ++b) {
      if (std::optional<Cluster> c = ClusterFromPair(model, cands, a, b, max_px, 3)) hypotheses.push_back(*c);
    }
  }
  std::stable_sort(hypotheses.begin(), hypotheses.end(), [](const Cluster& x, const Cluster& y) {
    return x.members.size() != y.members.size() ? x.members.size() > y.members.size() : x.rms_px < y.rms_px;
  });
  std::vector<char> taken(cands.size(), 0);
  std::vector<Cluster> targets;
  for (const Cluster& c : hypotheses) {
    if (std::any_of(c.members.begin(), c.members.end(), [&](int m) { return taken[m] != 0; })) continue;
    for (int m : c.members) taken[m] = 1;
    targets.push_back(c);
  }
  return targets;
}


// A point's status from its clusters; its marks from the chosen one.
// common_offset: the median offset of the points marked unambiguously
// (none on the first pass), which settles a point with two targets near it.
void Decide(const SparseModel& model, const std::vector<Candidate>& cands, const std::vector<Cluster>& clusters,
            double radius_m, const Similarity& to_enu, const Surveyed& s, const Eigen::Vector3d* common_offset,
            PointMarking* p) {
  if (p->photos.empty()) {
    p->status = "NOT_SEEN";
    p->reason = kNotSeen;
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
    const auto inside = std::count_if(p->photos.begin(), p->photos.end(),
                                      [](const TargetMark& m) { return m.predicted_inside; });
    if (inside <= 1 && cands.size() == 1) {
      p->status = "SINGLE_PHOTO";
      p->reason = "seen in one photo only: its mark has nothing to confirm it";
      mark_from({0});
      return;
    }
    p->status = "NOT_FOUND";
    p->reason = "no target within " + Fixed(radius_m, 1) + " m of its surveyed position in the " +
                std::to_string(inside) + " photos that should see it" +
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

std::optional<ListPlacement> PlaceListOnTargets(const std::vector<Eigen::Vector3d>& targets,
                                                const std::vector<Eigen::Vector3d>& surveyed, std::string* why) {
  constexpr double kToleranceM = 0.5;     // a free network's distortion across a block, and the targets' size
  constexpr double kSideRatioSpread = 0.05;  // the model's scale along three sides agrees within 5 %
  if (targets.size() < 3 || surveyed.size() < 3) {
    *why = std::to_string(targets.size()) + " targets found in the photos (seen in 3 photos or more) for " +
           std::to_string(surveyed.size()) + " surveyed points: at least 3 of each are needed to place the list "
           "without GPS";
    return std::nullopt;
  }
  // Assignment (target per surveyed point, -1 none) and fit under a similarity.
  const auto evaluate = [&](const Similarity& sim, std::vector<int>* assign, double* rms) {
    int n = 0;
    double sq = 0.0;
    assign->assign(surveyed.size(), -1);
    for (size_t s = 0; s < surveyed.size(); ++s) {
      double best = kToleranceM;
      for (size_t t = 0; t < targets.size(); ++t) {
        const double d = (sim.Apply(targets[t]) - surveyed[s]).norm();
        if (d < best) best = d, (*assign)[s] = static_cast<int>(t);
      }
      if ((*assign)[s] >= 0) ++n, sq += best * best;
    }
    *rms = n ? std::sqrt(sq / n) : 0.0;
    return n;
  };
  std::vector<std::array<int, 3>> triangles;
  for (int i = 0; i < static_cast<int>(surveyed.size()); ++i) {
    for (int j = i + 1; j < static_cast<int>(surveyed.size()); ++j) {
      for (int k = j + 1; k < static_cast<int>(surveyed.size()); ++k) triangles.push_back({i, j, k});
    }
  }
  const auto area = [&](const std::array<int, 3>& t) {
    return (surveyed[t[1]] - surveyed[t[0]]).cross(surveyed[t[2]] - surveyed[t[0]]).norm();
  };
  std::sort(triangles.begin(), triangles.end(), [&](const auto& x, const auto& y) { return area(x) > area(y); });
  triangles.resize(std::min<size_t>(triangles.size(), 40));
  std::map<std::vector<int>, std::pair<int, double>> fits;  // assignment -> (points placed, rms)
  std::optional<ListPlacement> best;
  std::vector<int> best_assign;
  const int nt = static_cast<int>(targets.size());
  for (const auto& tri : triangles) {
    if (area(tri) < 1.0) continue;  // points on a line place nothing
    const double d01 = (surveyed[tri[0]] - surveyed[tri[1]]).norm(), d12 = (surveyed[tri[1]] - surveyed[tri[2]]).norm(),
                 d02 = (surveyed[tri[0]] - surveyed[tri[2]]).norm();
    for (int a = 0; a < nt; ++a) {
      for (int b = 0; b < nt; ++b) {
        if (b == a) continue;
        const double s01 = d01 / std::max(1e-12, (targets[a] - targets[b]).norm());
        for (int c = 0; c < nt; ++c) {
          if (c == a || c == b) continue;
          const double s12 = d12 / std::max(1e-12, (targets[b] - targets[c]).norm());
          const double s02 = d02 / std::max(1e-12, (targets[a] - targets[c]).norm());
          const double lo = std::min({s01, s12, s02}), hi = std::max({s01, s12, s02});
          if (hi > (1.0 + kSideRatioSpread) * lo) continue;
          auto sim = FitSimilarity({targets[a], targets[b], targets[c]}, {surveyed[tri[0]], surveyed[tri[1]], surveyed[tri[2]]});
          if (!sim) continue;
          std::vector<int> assign;
          double rms = 0.0;
          int n = evaluate(*sim, &assign, &rms);
          // Refit on every point placed, and place again.
          for (int round = 0; round < 2 && n >= 3; ++round) {
            std::vector<Eigen::Vector3d> from, to;
            for (size_t s = 0; s < surveyed.size(); ++s) {
              if (assign[s] >= 0) from.push_back(targets[assign[s]]), to.push_back(surveyed[s]);
            }
            const auto refit = FitSimilarity(from, to);
            if (!refit) break;
            sim = refit;
            n = evaluate(*sim, &assign, &rms);
          }
          if (n < 3) continue;
          auto& f = fits[assign];
          if (f.first == 0 || rms < f.second) f = {n, rms};
          if (!best || n > best->placed || (n == best->placed && rms < best->rms_m)) {
            best = ListPlacement{*sim, n, rms};
            best_assign = assign;
          }
        }
      }
    }
  }
  if (!best) {
    *why = "no three of the " + std::to_string(targets.size()) + " targets found in the photos form a triangle "
           "like any three surveyed points (within 5 % in scale and " + Fixed(kToleranceM, 1) + " m)";
    return std::nullopt;
  }
  for (const auto& [assign, f] : fits) {
    if (f.first < best->placed) continue;
    int differ = 0;
    for (size_t k = 0; k < assign.size(); ++k) differ += assign[k] != best_assign[k];
    if (differ < 2) continue;  // one point between two targets: its own decision, later
    if (f.second < 3.0 * best->rms_m + 0.05) {
      *why = "the targets found in the photos fit the surveyed list in two ways (" + std::to_string(best->placed) +
             " points each, " + Fixed(best->rms_m, 3) + " and " + Fixed(f.second, 3) +
             " m RMS): a symmetric layout, which GPS or a hand mark would settle";
      return std::nullopt;
    }
  }
  return best;
}

namespace {

// The model's frame placed in ENU from the photos alone: every target in
// every photo, triangulated, and the coordinate list placed on them. false
// (every point UNPLACED, with the reason) when it cannot be.
bool GeoreferenceByTargets(const SparseModel& model, const std::filesystem::path& images_dir,
                           const std::vector<Surveyed>& points, const MarkingOptions& options, MarkingResult* result,
                           std::vector<Candidate>* everywhere) {
  *everywhere = DetectEverywhere(model, images_dir, options);
  const std::vector<Cluster> found = TargetsInPhotos(model, *everywhere, options.max_reprojection_px);
  std::vector<Eigen::Vector3d> targets, surveyed;
  for (const Cluster& c : found) targets.push_back(c.position);
  for (const Surveyed& p : points) {
    if (!p.point->horizontal_only) surveyed.push_back(p.enu);
  }
  result->targets_found = static_cast<int>(targets.size());
  std::string why;
  const std::optional<ListPlacement> placed = PlaceListOnTargets(targets, surveyed, &why);
  if (!placed) {
    for (PointMarking& p : result->points) {
      p.status = "UNPLACED";
      p.reason = "the photos have no GPS, and " + why;
    }
    return false;
  }
  result->model_to_enu = placed->model_to_enu;
  result->placement_rms_m = placed->rms_m;
  result->placed_points = placed->placed;
  result->search_radius_m = options.search_radius_m > 0 ? options.search_radius_m : std::max(0.5, 4.0 * placed->rms_m);
  return true;
}

}  // namespace

MarkingResult MarkControl(const SparseModel& model, const std::filesystem::path& images_dir,
                          const std::map<std::string, GpsFix>& gps, const Geodetic& enu_origin, const GcpFile& control,
                          const GcpFile* checks, const MarkingOptions& options) {
  const LocalFrame frame(enu_origin);
  MarkingResult result;
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
      points.push_back(s);
      PointMarking p;
      p.name = g.name;
      p.check = s.check;
      result.points.push_back(p);
    }
  }
  std::vector<Candidate> everywhere;
  double sigma_h = 0.0;
  if (const auto by_gps = GeoreferenceByGps(model, gps, frame, &result.gps_photos, &sigma_h)) {
    result.method = "gps";
    result.model_to_enu = *by_gps;
    result.search_radius_m = options.search_radius_m > 0 ? options.search_radius_m : std::max(1.5, 2.0 * sigma_h);
  } else {
    result.method = "targets";
    if (!GeoreferenceByTargets(model, images_dir, points, options, &result, &everywhere)) return result;
  }
  const Similarity to_model = result.model_to_enu.Inverse();
  for (Surveyed& s : points) {
    if (s.point->horizontal_only) s.enu.z() = HeightNear(model, result.model_to_enu, s.enu.head<2>());
    s.model = to_model.Apply(s.enu);
  }
  std::vector<std::vector<Candidate>> candidates(points.size());
  DetectNearPredictions(model, images_dir, points, result.model_to_enu, result.search_radius_m, options,
                        result.method == "targets" ? &everywhere : nullptr, &result.points, &candidates);
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
  DropUnseenOutside(&result.points);
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
