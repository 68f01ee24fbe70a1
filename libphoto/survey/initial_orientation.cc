// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/survey/initial_orientation.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "georef/crs.h"
#include "georef/local_frame.h"
#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/base/error.h"
#include "libphoto/geometry/pose_estimation.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {
namespace {

struct Mark {
  int image = 0;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double sigma_px = 0.0;  // 0: the adjustment's default
  bool suspect = false;   // left out of the intersection: disagrees with the other rays
};

// A point of the initial orientation: a tie point, or a control point (known
// from the start in the control frame, or intersected like a tie point).
struct InitPoint {
  std::string name;
  bool control = false;
  bool known = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::vector<Mark> marks;
};

std::string Names(const std::vector<std::string>& names, size_t at_most = 10) {
  std::string out;
  for (size_t k = 0; k < names.size() && k < at_most; ++k) out += (k ? ", " : "") + names[k];
  if (names.size() > at_most) out += " and " + std::to_string(names.size() - at_most) + " more";
  return out;
}

// The control's Cartesian frame: a local frame's own coordinates (metres,
// from the first point), else ENU metres tangent at the first point.
std::vector<std::optional<Eigen::Vector3d>> ControlInCartesian(const GcpFile& control) {
  std::vector<std::optional<Eigen::Vector3d>> out(control.points.size());
  const GroundPoint* first = nullptr;
  for (const GroundPoint& g : control.points) {
    if (!g.horizontal_only) {
      first = &g;
      break;
    }
  }
  if (!first) return out;
  const Crs crs = Crs::FromString(control.crs);
  if (crs.IsLocal()) {
    for (size_t k = 0; k < control.points.size(); ++k) {
      const GroundPoint& g = control.points[k];
      if (!g.horizontal_only) out[k] = (g.xyz - first->xyz) * crs.LocalUnitMetres();
    }
    return out;
  }
  const LocalFrame frame(crs.ToGeodetic(first->xyz));
  for (size_t k = 0; k < control.points.size(); ++k) {
    const GroundPoint& g = control.points[k];
    if (!g.horizontal_only) out[k] = frame.EnuFromGeodetic(crs.ToGeodetic(g.xyz));
  }
  return out;
}

class Orienter {
 public:
  Orienter(const Camera& camera, const InitialOrientationOptions& options) : camera_(camera), options_(options) {}

  std::vector<std::string> image_names;
  std::vector<std::optional<Pose>> poses;
  std::vector<InitPoint> points;
  std::vector<ImageOrientationResult> results;
  // The points each image measures (indices into points), so that a
  // resection reads its own marks only.
  std::vector<std::vector<int>> points_of_image;

  void IndexMarks() {
    points_of_image.assign(image_names.size(), {});
    for (size_t k = 0; k < points.size(); ++k) {
      for (const Mark& m : points[k].marks) points_of_image[m.image].push_back(static_cast<int>(k));
    }
  }

  // Normalised ray coordinates of a mark; nullopt when the pixel cannot be
  // unprojected through the distortion.
  std::optional<Eigen::Vector2d> Ray(const Mark& m) const { return camera_.NormalizedFromImage(m.xy); }

  // Space resection of image i from the known points it sees.
  bool Resect(int i, bool control_only, int round) {
    std::vector<Eigen::Vector3d> world;
    std::vector<Eigen::Vector2d> rays;
    for (const int k : points_of_image[i]) {
      const InitPoint& p = points[k];
      if (!p.known || (control_only && !p.control)) continue;
      for (const Mark& m : p.marks) {
        if (m.image != i) continue;
        if (const auto ray = Ray(m)) {
          world.push_back(p.position);
          rays.push_back(*ray);
        }
      }
    }
    ImageOrientationResult& r = results[i];
    r.points_used = static_cast<int>(world.size());
    if (static_cast<int>(world.size()) < options_.min_resection_points) return false;
    std::vector<int> inliers;
    const std::optional<Pose> pose =
        EstimateAbsolutePose(world, rays, options_.resection_threshold_px / camera_.focal_px(), &inliers);
    if (!pose || static_cast<int>(inliers.size()) < options_.min_resection_points) return false;
    poses[i] = *pose;
    r.oriented = true;
    r.round = round;
    r.points_used = static_cast<int>(inliers.size());
    r.how = "space resection from " + std::to_string(inliers.size()) + (control_only ? " control points" : " points");
    if (inliers.size() < world.size()) r.how += " (" + std::to_string(world.size() - inliers.size()) + " marks off)";
    return true;
  }

  // Forward intersection of point p from its oriented images. A point whose
  // rays disagree loses its worst mark (a blunder: kept for the adjustment
  // to judge, unused here) while three or more remain.
  bool Intersect(InitPoint* p) const {
    std::vector<View> views;
    std::vector<Mark*> marks;
    for (Mark& m : p->marks) {
      if (!poses[m.image] || m.suspect) continue;
      views.push_back({&camera_, *poses[m.image], m.xy});
      marks.push_back(&m);
    }
    TriangulationOptions t;
    t.min_angle_deg = options_.min_angle_deg;
    while (views.size() >= 2) {
      const auto result = TriangulatePoint(views, t);
      if (!result) return false;
      if (result->reprojection_rms_px <= options_.max_intersection_rms_px) {
        p->known = true;
        p->position = result->position;
        return true;
      }
      if (views.size() < 3) return false;
      size_t worst = 0;
      double worst_error = -1.0;
      for (size_t k = 0; k < views.size(); ++k) {
        const double e = (camera_.ImageFromCamera(views[k].pose.CamFromWorld(result->position)) - views[k].xy).norm();
        if (e > worst_error) {
          worst_error = e;
          worst = k;
        }
      }
      marks[worst]->suspect = true;
      views.erase(views.begin() + static_cast<long>(worst));
      marks.erase(marks.begin() + static_cast<long>(worst));
    }
    return false;
  }

  // A free bundle adjustment of what is oriented and known so far (the
  // certificate's intrinsics held, Huber loss on the marks): resections and
  // intersections drift as the block grows from its seed, and the next
  // round's resections need points that agree with each other.
  void Bundle() {
    SparseModel m;
    m.cameras.push_back(camera_);
    std::vector<int> image_at(poses.size(), -1), point_at(points.size(), -1);
    for (size_t i = 0; i < poses.size(); ++i) {
      if (!poses[i]) continue;
      image_at[i] = static_cast<int>(m.images.size());
      Image image;
      image.id = image_at[i] + 1;
      image.name = image_names[i];
      image.pose = *poses[i];
      m.images.push_back(image);
    }
    for (size_t k = 0; k < points.size(); ++k) {
      const InitPoint& p = points[k];
      if (!p.known) continue;
      int seen = 0;
      for (const Mark& mark : p.marks) seen += image_at[mark.image] >= 0 && !mark.suspect;
      if (seen < 2) continue;
      point_at[k] = static_cast<int>(m.points.size());
      Point point;
      point.id = point_at[k] + 1;
      point.position = p.position;
      m.points.push_back(point);
      for (const Mark& mark : p.marks) {
        if (image_at[mark.image] < 0 || mark.suspect) continue;
        Observation obs;
        obs.image = image_at[mark.image];
        obs.point = point_at[k];
        obs.xy = mark.xy;
        m.observations.push_back(obs);
      }
    }
    if (m.images.size() < 2 || m.points.empty()) return;
    BundleOptions o;
    o.loss = LossType::kHuber;
    o.loss_scale_px = 1.0;
    o.refine_intrinsics = IntrinsicsRefinement::kNone;
    o.use_gps_priors = false;
    o.use_gcp_priors = false;
    o.compute_diagnostics = false;
    o.max_iterations = 50;
    AdjustBundle(&m, o);
    for (size_t i = 0; i < poses.size(); ++i) {
      if (image_at[i] >= 0) poses[i] = m.images[image_at[i]].pose;
    }
    for (size_t k = 0; k < points.size(); ++k) {
      if (point_at[k] >= 0) points[k].position = m.points[point_at[k]].position;
    }
    // Every mark judged again on the adjusted block: one set aside while the
    // poses were rough and that fits now is taken back; one that a point
    // known before its image was oriented cannot explain is set aside.
    for (InitPoint& p : points) {
      if (!p.known) continue;
      for (Mark& mark : p.marks) {
        if (!poses[mark.image]) continue;
        const Eigen::Vector3d in_camera = poses[mark.image]->CamFromWorld(p.position);
        mark.suspect = !(in_camera.z() > 0.0 && (camera_.ImageFromCamera(in_camera) - mark.xy).norm() <=
                                                    options_.max_intersection_rms_px);
      }
    }
  }

  // Relative orientation of the pair sharing the most points; the baseline
  // scaled by GPS where both images have it.
  bool SeedPair(const std::map<std::string, GpsFix>& gps, std::string* seed) {
    std::map<std::pair<int, int>, int> shared;
    for (const InitPoint& p : points) {
      for (size_t a = 0; a < p.marks.size(); ++a) {
        for (size_t b = a + 1; b < p.marks.size(); ++b) {
          const int i = std::min(p.marks[a].image, p.marks[b].image);
          const int j = std::max(p.marks[a].image, p.marks[b].image);
          ++shared[{i, j}];
        }
      }
    }
    std::vector<std::pair<int, std::pair<int, int>>> pairs;
    for (const auto& [ij, count] : shared) {
      if (count >= 8) pairs.push_back({count, ij});
    }
    std::sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    for (size_t k = 0; k < pairs.size() && k < 20; ++k) {
      const auto [i, j] = pairs[k].second;
      std::vector<Eigen::Vector2d> a, b;
      for (const InitPoint& p : points) {
        const Mark* ma = nullptr;
        const Mark* mb = nullptr;
        for (const Mark& m : p.marks) {
          if (m.image == i) ma = &m;
          if (m.image == j) mb = &m;
        }
        if (!ma || !mb) continue;
        const auto ra = Ray(*ma), rb = Ray(*mb);
        if (ra && rb) {
          a.push_back(*ra);
          b.push_back(*rb);
        }
      }
      const auto rel = EstimateRelativePose(a, b, options_.resection_threshold_px / camera_.focal_px());
      if (!rel || rel->inliers < 8) continue;
      double scale = 1.0;
      const auto gi = gps.find(image_names[i]), gj = gps.find(image_names[j]);
      std::string scaled = "unit baseline (no GPS on both)";
      if (gi != gps.end() && gj != gps.end()) {
        const LocalFrame frame(gi->second.position);
        const double baseline = frame.EnuFromGeodetic(gj->second.position).norm();
        if (baseline > 0.0) {
          scale = baseline;
          scaled = "baseline scaled by GPS";
        }
      }
      poses[i] = Pose{};
      Pose pb = rel->b;
      pb.centre_in_world *= scale;
      poses[j] = pb;
      for (const int m : {i, j}) {
        results[m].oriented = true;
        results[m].round = 0;
        results[m].points_used = rel->inliers;
        results[m].how = "relative orientation of the seed pair (" + std::to_string(rel->inliers) + " points)";
      }
      *seed = "relative orientation of " + image_names[i] + " and " + image_names[j] + " (" +
              std::to_string(rel->inliers) + " of " + std::to_string(a.size()) + " shared points, " + scaled + ")";
      return true;
    }
    return false;
  }

 private:
  const Camera& camera_;
  const InitialOrientationOptions& options_;
};

}  // namespace

void InitialOrientationOptions::Check() const {
  if (min_resection_points < 4) {
    throw InvalidArgument("min_resection_points is " + std::to_string(min_resection_points) +
                          "; expected 4 or more (a resection has 6 unknowns and a check)");
  }
  if (!(resection_threshold_px > 0.0) || !(max_intersection_rms_px > 0.0)) {
    throw InvalidArgument("resection_threshold_px and max_intersection_rms_px must be positive");
  }
  if (!(min_angle_deg >= 0.0 && min_angle_deg < 90.0)) {
    throw InvalidArgument("min_angle_deg is " + std::to_string(min_angle_deg) + "; expected 0 to 90 degrees");
  }
}

namespace {

// The model of an orientation: the oriented images and the intersected tie
// points with their marks; images left out and tie points lost are said.
SparseModel ModelOfOrientation(Orienter& o, const Camera& camera, int num_ties,
                               const InitialOrientationOptions& options, InitialOrientationReport* report) {
  SparseModel model;
  Camera c = camera;
  c.id = 1;
  model.cameras.push_back(c);
  std::vector<int> model_image(o.image_names.size(), -1);
  std::vector<std::string> left_out;
  for (size_t i = 0; i < o.image_names.size(); ++i) {
    ImageOrientationResult& r = o.results[i];
    if (!o.poses[i]) {
      r.how = "not oriented: it sees " + std::to_string(r.points_used) + " known point(s), " +
              std::to_string(options.min_resection_points) + " needed for a space resection";
      left_out.push_back(o.image_names[i]);
      report->warnings.push_back("image " + o.image_names[i] + " left out of the adjustment: " + r.how);
      continue;
    }
    Image image;
    image.id = static_cast<int>(model.images.size()) + 1;
    image.name = o.image_names[i];
    image.camera = 0;
    image.pose = *o.poses[i];
    model_image[i] = static_cast<int>(model.images.size());
    model.images.push_back(image);
  }
  std::vector<std::string> lost;
  for (int k = 0; k < num_ties; ++k) {
    const InitPoint& p = o.points[k];
    if (!p.known) {
      lost.push_back(p.name);
      continue;
    }
    Point point;
    point.id = static_cast<int>(model.points.size()) + 1;
    point.position = p.position;
    point.name = p.name;
    const int index = static_cast<int>(model.points.size());
    model.points.push_back(point);
    for (const Mark& m : p.marks) {
      if (model_image[m.image] < 0) continue;
      report->suspect_marks += m.suspect;
      Observation obs;
      obs.image = model_image[m.image];
      obs.point = index;
      obs.xy = m.xy;
      obs.sigma_px = m.sigma_px;
      model.observations.push_back(obs);
    }
  }
  if (!lost.empty()) {
    report->warnings.push_back(std::to_string(lost.size()) + " of " + std::to_string(num_ties) +
                               " tie points not intersected (seen in fewer than 2 oriented images, rays under " +
                               std::to_string(options.min_angle_deg).substr(0, 4) + " deg apart, or a residual above " +
                               std::to_string(options.max_intersection_rms_px).substr(0, 4) +
                               " px): " + Names(lost));
  }
  report->tie_points_intersected = static_cast<int>(model.points.size());
  report->oriented = static_cast<int>(model.images.size());
  report->images = o.results;
  return model;
}

}  // namespace

SparseModel OrientFromMeasurements(const Camera& camera, const TiePointFile& ties, const GcpFile* control,
                                   const std::map<std::string, GpsFix>& gps,
                                   const InitialOrientationOptions& options, InitialOrientationReport* report) {
  options.Check();
  camera.Validate();
  *report = {};
  Orienter o(camera, options);

  // Images: every name measured, in name order (the files' order is not a
  // flight order to rely on).
  std::map<std::string, int> image_index;
  for (const TieMeasurement& m : ties.measurements) image_index[m.image] = 0;
  if (control) {
    for (const GroundPoint& g : control->points) {
      for (const GcpMeasurement& m : g.measurements) image_index[m.image] = 0;
    }
  }
  for (auto& [name, index] : image_index) {
    index = static_cast<int>(o.image_names.size());
    o.image_names.push_back(name);
  }
  o.poses.assign(o.image_names.size(), std::nullopt);
  o.results.resize(o.image_names.size());
  for (size_t i = 0; i < o.image_names.size(); ++i) o.results[i].name = o.image_names[i];

  // Tie points in the file's order of first appearance.
  std::map<std::string, int> tie_index;
  for (const TieMeasurement& m : ties.measurements) {
    const auto [it, inserted] = tie_index.emplace(m.point, static_cast<int>(o.points.size()));
    if (inserted) {
      o.points.push_back({});
      o.points.back().name = m.point;
    }
    o.points[it->second].marks.push_back({image_index.at(m.image), m.xy_px, m.sigma_px.value_or(0.0)});
  }
  const int num_ties = static_cast<int>(o.points.size());
  report->tie_points = num_ties;
  if (control) {
    const auto cartesian = ControlInCartesian(*control);
    for (size_t k = 0; k < control->points.size(); ++k) {
      const GroundPoint& g = control->points[k];
      if (g.measurements.empty()) continue;
      InitPoint p;
      p.name = g.name;
      p.control = true;
      p.known = cartesian[k].has_value();
      if (p.known) p.position = *cartesian[k];
      for (const GcpMeasurement& m : g.measurements) p.marks.push_back({image_index.at(m.image), m.xy_px, 0.0});
      o.points.push_back(std::move(p));
    }
  }

  o.IndexMarks();

  // 1. Seed: resection on control, else a relative pair.
  int seeded = 0;
  for (size_t i = 0; i < o.image_names.size(); ++i) seeded += o.Resect(static_cast<int>(i), true, 0) ? 1 : 0;
  // One image alone intersects nothing: the block then starts from a pair.
  if (seeded >= 2) {
    report->control_frame = true;
    report->seed = "space resection of " + std::to_string(seeded) + " image(s) on " +
                   std::to_string(options.min_resection_points) + " or more control points each";
  } else {
    for (InitPoint& p : o.points) p.known = false;  // control marks become ties of a free block
    for (size_t i = 0; i < o.image_names.size(); ++i) {
      o.poses[i].reset();
      o.results[i] = {};
      o.results[i].name = o.image_names[i];
    }
    if (!o.SeedPair(gps, &report->seed)) {
      throw InvalidArgument(
          "cannot start the aerial triangulation: no image sees " + std::to_string(options.min_resection_points) +
          " or more control points (space resection) and no pair of images shares 8 or more points in a "
          "consistent relative orientation; measure more control or tie points (" + ties.path + ")");
    }
  }

  // 2. Growth: intersect, adjust, resect, until nothing changes.
  for (int round = 1;; ++round) {
    bool changed = false;
    for (InitPoint& p : o.points) {
      if (!p.known && o.Intersect(&p)) changed = true;
    }
    if (changed) o.Bundle();
    for (size_t i = 0; i < o.image_names.size(); ++i) {
      if (!o.poses[i] && o.Resect(static_cast<int>(i), false, round)) changed = true;
    }
    report->rounds = round;
    if (!changed) break;
  }
  o.Bundle();  // the last resections adjusted too, and every mark judged

  SparseModel model = ModelOfOrientation(o, camera, num_ties, options, report);
  if (model.images.empty()) throw InvalidArgument("no image could be oriented from " + ties.path);
  model.Validate();
  return model;
}

}  // namespace aerotri
