// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/sfm/incremental_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <type_traits>
#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>

#include "libphoto/survey/block_geometry.h"
#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/survey/findings.h"
#include "libphoto/survey/gnss_drift.h"
#include "libphoto/base/error.h"
#include "georef/similarity.h"
#include "libphoto/sfm/guided_matching.h"
#include "libphoto/sfm/tracks.h"
#include "libphoto/geometry/pose_estimation.h"
#include "libphoto/geometry/triangulation.h"

namespace aerotri {

void MapperOptions::Check() const {
  CheckOption(min_pnp_inliers >= 4, "mapper min_pnp_inliers", min_pnp_inliers, "at least 4 (P3P and one to check)");
  CheckOption(max_reprojection_px > 0.0 && std::isfinite(max_reprojection_px), "mapper max_reprojection_px",
              max_reprojection_px, "a positive number of pixels");
  CheckOption(min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 90.0,
              "mapper min_triangulation_angle_deg", min_triangulation_angle_deg, "an angle in [0, 90) degrees");
  CheckOption(init_min_median_angle_deg >= 0.0 && init_min_median_angle_deg < 90.0,
              "mapper init_min_median_angle_deg", init_min_median_angle_deg, "an angle in [0, 90) degrees");
  CheckOption(init_candidates >= 1, "mapper init_candidates", init_candidates, "at least 1 pair");
  CheckOption(rescue_search_radius_px > 0.0 && std::isfinite(rescue_search_radius_px),
              "mapper rescue_search_radius_px", rescue_search_radius_px, "a positive number of pixels");
  CheckOption(num_threads >= 0, "--threads", num_threads, "0 (all cores) or more");
  CheckOption(gps_check_m >= 0.0 && std::isfinite(gps_check_m), "mapper gps_check_m", gps_check_m,
              "0 (no check) or a distance in metres");
  CheckOption(local_adjust_images >= 0, "mapper local_adjust_images", local_adjust_images,
              "0 (no local adjustment) or a number of images");
  CheckOption(local_adjust_iterations >= 1, "mapper local_adjust_iterations", local_adjust_iterations,
              "at least 1 solver iteration");
  CheckOption(global_adjust_growth > 0.0 && global_adjust_growth <= 10.0, "mapper global_adjust_growth",
              global_adjust_growth, "a fraction of the registered images in (0, 10]");
  CheckOption(gps_prior_min_images >= 3, "mapper gps_prior_min_images", gps_prior_min_images,
              "at least 3 images (a similarity to the GPS needs three)");
  CheckOption(iterative_above_images >= 0, "mapper iterative_above_images", iterative_above_images,
              "0 (every adjustment exact) or a number of images");
}

namespace {

constexpr double kDeg = M_PI / 180.0;

// The horizontal spread of positions across their main direction, as the
// ratio of the smaller eigenvalue of their scatter to the larger (0.01: a
// tenth of the length across it); -1 when they do not spread at all.
double AcrossSpreadRatio(const std::vector<Eigen::Vector3d>& positions) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& t : positions) mean += t.head<2>() / static_cast<double>(positions.size());
  Eigen::Matrix2d spread = Eigen::Matrix2d::Zero();
  for (const auto& t : positions) spread += (t.head<2>() - mean) * (t.head<2>() - mean).transpose();
  const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues();
  return ev(1) > 0.0 ? ev(0) / ev(1) : -1.0;
}

// How far a camera may lie from its fix for the fix to enter as a prior:
// 3 times the fixes' median horizontal sigma, at least 10 m.
double AnchorThreshold(std::vector<double> sigmas_h_m) {
  std::nth_element(sigmas_h_m.begin(), sigmas_h_m.begin() + sigmas_h_m.size() / 2, sigmas_h_m.end());
  return std::max(10.0, 3.0 * sigmas_h_m[sigmas_h_m.size() / 2]);
}

class Mapper {
 public:
  Mapper(const std::vector<std::string>& names, const std::vector<int>& camera_of_image,
         const std::vector<Camera>& cameras, const std::vector<ImageFeatures>& features,
         const std::vector<PairMatches>& matches, const MapperOptions& options,
         const std::vector<std::optional<Eigen::Vector3d>>& gps_enu,
         const std::map<std::string, GimbalAttitude>& gimbal = {}, const MapperPriors& priors = {})
      : features_(features), matches_(matches), options_(options), gps_(gps_enu), gimbal_(gimbal), priors_(priors) {
    gps_.resize(names.size());
    priors_.gps_sigma_h_m.resize(names.size(), 0.0);
    priors_.gps_sigma_v_m.resize(names.size(), 0.0);
    priors_.rolling_shutter.resize(names.size());
    priors_.attitude.resize(names.size());
    triangulation_px_ = options.max_reprojection_px;
    has_prior_.assign(names.size(), 0);
    model_.cameras = cameras;
    for (size_t i = 0; i < names.size(); ++i) {
      Image image;
      image.id = static_cast<int>(i) + 1;
      image.name = names[i];
      image.camera = camera_of_image[i];
      image.registered = false;
      model_.images.push_back(image);
    }
    std::vector<int> counts;
    for (const ImageFeatures& f : features) counts.push_back(static_cast<int>(f.keypoints.size()));
    tracks_ = BuildTracks(counts, matches);
    point_of_track_.assign(tracks_.tracks.size(), -1);
    status_.resize(names.size());
    gps_strikes_.assign(names.size(), 0);
    failures_.assign(names.size(), 0);
    for (const PairMatches& m : matches) {
      has_pair_[m.i] = has_pair_[m.j] = true;
    }
  }

  MapperResult Run() {
    MapperResult result;
    result.num_tracks = static_cast<int>(tracks_.tracks.size());
    result.dropped_inconsistent_tracks = tracks_.dropped_inconsistent;
    const bool from_priors = options_.gps_priors && options_.start_from_priors && StartFromPriors();
    if (from_priors) {
      result.initial_pair = "from the photos' GPS and attitude";
    } else if (!Initialise(&result.initial_pair)) {
      for (size_t i = 0; i < status_.size(); ++i) {
        status_[i].why_not = has_pair_.count(static_cast<int>(i))
                                 ? "no image pair with enough matches and parallax to start from"
                                 : "no verified image pair (no overlap found)";
      }
      result.images = status_;
      result.model = model_;
      return result;
    }
    int last_ba = NumRegistered();
    while (true) {
      const std::vector<int> candidates = NextImages();
      bool registered_one = false;
      int registered_image = -1;
      for (int image : candidates) {
        if (Register(image)) {
          registered_one = true;
          registered_image = image;
          Report();
          break;
        }
      }
      if (!registered_one) {
        // Retry after an adjustment if it has not run on this model yet.
        if (last_ba != NumRegistered()) {
          GlobalAdjust(false);
          last_ba = NumRegistered();
          std::fill(failures_.begin(), failures_.end(), 0);
          continue;
        }
        break;
      }
      const int n = NumRegistered();
      if (n <= 8 || n >= last_ba + std::max(2, static_cast<int>(options_.global_adjust_growth * last_ba))) {
        GlobalAdjust(false);
        last_ba = n;
      } else {
        LocalAdjust(registered_image);
      }
    }
    if (options_.gps_rescue) {
      while (RescueWithGps()) {
        GlobalAdjust(false);
      }
    }
    GlobalAdjust(true);
    ++adjustments_;
    for (size_t i = 0; i < status_.size(); ++i) {
      if (!model_.images[i].registered && status_[i].why_not.empty()) {
        status_[i].why_not = has_pair_.count(static_cast<int>(i))
                                 ? "too few 2D-3D correspondences to register"
                                 : "no verified image pair (no overlap found)";
      }
    }
    Compact();
    for (const Image& image : model_.images) result.rolling_shutter_images += image.registered && image.rolling_shutter;
    result.model = std::move(model_);
    result.images = status_;
    result.global_adjustments = adjustments_;
    result.focal_held = focal_held_;
    result.gps_anchored_at_images = anchored_at_;
    result.adjustment_s = adjustment_s_;
    result.adjustment_iterations = adjustment_iterations_;
    result.local_adjustments = local_adjustments_;
    result.local_adjustment_s = local_adjustment_s_;
    for (size_t i = 0; i < gps_strikes_.size(); ++i) {
      if (gps_strikes_[i] > 0) result.gps_deregistered.push_back(result.model.images[i].name);
    }
    return result;
  }

 private:
  int NumRegistered() const { return model_.NumRegisteredImages(); }

  void Report() {
    ReportProgress(options_.progress, static_cast<double>(NumRegistered()) / model_.images.size(),
                   std::to_string(NumRegistered()) + "/" + std::to_string(model_.images.size()) +
                       " images registered, " + std::to_string(NumLivePoints()) + " points");
  }

  int NumLivePoints() const {
    int n = 0;
    for (int p : point_of_track_) n += p >= 0;
    return n;
  }

  std::optional<Eigen::Vector2d> Normalized(int image, int feature) const {
    const Keypoint& k = features_[image].keypoints[feature];
    return model_.cameras[model_.images[image].camera].NormalizedFromImage(Eigen::Vector2d(k.x, k.y));
  }

  Eigen::Vector2d Pixel(int image, int feature) const {
    const Keypoint& k = features_[image].keypoints[feature];
    return {k.x, k.y};
  }

  double Focal(int image) const { return model_.cameras[model_.images[image].camera].focal_px(); }

  bool Initialise(std::string* description) {
    std::vector<const PairMatches*> order;
    for (const PairMatches& m : matches_) order.push_back(&m);
    // Many inliers first. Nadir photos of fairly flat ground are mostly
    // explained by a homography, so only near-pure homographies (no parallax)
    // are set back; favouring low homography ratios picked weak side-overlap
    // pairs whose two-view model then bent the calibration.
    auto score = [](const PairMatches* m) {
      const double h = static_cast<double>(m->homography_inliers) / std::max<size_t>(1, m->inliers.size());
      return static_cast<double>(m->inliers.size()) * (h > 0.97 ? 0.3 : 1.0);
    };
    std::sort(order.begin(), order.end(), [&](auto* a, auto* b) { return score(a) > score(b); });
    for (int k = 0; k < std::min<int>(options_.init_candidates, static_cast<int>(order.size())); ++k) {
      if (TryPair(*order[k])) {
        *description = model_.images[order[k]->i].name + " + " + model_.images[order[k]->j].name;
        return true;
      }
    }
    return false;
  }

  bool TryPair(const PairMatches& m) {
    std::vector<Eigen::Vector2d> a, b;
    std::vector<int> fa, fb;
    for (const auto& in : m.inliers) {
      const auto na = Normalized(m.i, in[0]), nb = Normalized(m.j, in[1]);
      if (!na || !nb) continue;
      a.push_back(*na);
      b.push_back(*nb);
      fa.push_back(in[0]);
      fb.push_back(in[1]);
    }
    if (a.size() < 30) return false;
    const double threshold = options_.max_reprojection_px / std::sqrt(Focal(m.i) * Focal(m.j));
    const std::optional<RelativePose> relative = EstimateRelativePose(a, b, threshold);
    if (!relative || relative->inliers < 30) return false;
    const int good = relative->inliers;
    std::vector<Pose> saved = {model_.images[m.i].pose, model_.images[m.j].pose};
    model_.images[m.i].pose = Pose();
    model_.images[m.j].pose = relative->b;
    model_.images[m.i].registered = model_.images[m.j].registered = true;
    // Triangulate the pair's tracks and check parallax.
    std::vector<double> angles;
    for (size_t k = 0; k < fa.size(); ++k) {
      const int track = tracks_.track_of[m.i][fa[k]];
      if (track < 0 || point_of_track_[track] >= 0) continue;
      const int p = TriangulateTrack(track);
      if (p >= 0) {
        const Eigen::Vector3d x = model_.points[p].position;
        const Eigen::Vector3d ra = (x - model_.images[m.i].pose.centre_in_world).normalized();
        const Eigen::Vector3d rb = (x - model_.images[m.j].pose.centre_in_world).normalized();
        angles.push_back(std::acos(std::clamp(ra.dot(rb), -1.0, 1.0)) / kDeg);
      }
    }
    std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
    const double median = angles.empty() ? 0.0 : angles[angles.size() / 2];
    if (angles.size() < 100 || median < options_.init_min_median_angle_deg) {
      Reset(saved, m.i, m.j);
      return false;
    }
    status_[m.i] = {true, "", static_cast<int>(a.size()), good};
    status_[m.j] = {true, "", static_cast<int>(a.size()), good};
    GlobalAdjust(false);
    if (NumLivePoints() < 100) {
      Reset(saved, m.i, m.j);
      return false;
    }
    Report();
    return true;
  }

  void Reset(const std::vector<Pose>& saved, int a, int b) {
    model_.images[a].pose = saved[0];
    model_.images[b].pose = saved[1];
    model_.images[a].registered = model_.images[b].registered = false;
    model_.points.clear();
    model_.observations.clear();
    std::fill(point_of_track_.begin(), point_of_track_.end(), -1);
    status_[a] = status_[b] = ImageRegistration();
  }

  // Triangulates a track from its registered views; returns the point index
  // or -1. Views whose reprojection error is too large are left out.
  int TriangulateTrack(int track) {
    std::vector<View> views;
    std::vector<const TrackElement*> elements;
    for (const TrackElement& e : tracks_.tracks[track]) {
      const Image& image = model_.images[e.image];
      if (!image.registered) continue;
      const Eigen::Vector2d xy = Pixel(e.image, e.feature);
      views.push_back({&model_.cameras[image.camera], image.PoseAtRow(xy.y(), model_.cameras[image.camera].height), xy});
      elements.push_back(&e);
    }
    if (views.size() < 2) return -1;
    TriangulationOptions topt;
    topt.min_angle_deg = options_.min_triangulation_angle_deg;
    const auto t = TriangulatePoint(views, topt);
    if (!t) return -1;
    std::vector<int> keep;
    for (size_t v = 0; v < views.size(); ++v) {
      const Eigen::Vector3d pc = views[v].pose.CamFromWorld(t->position);
      if (pc.z() <= 0) continue;
      if ((views[v].camera->ImageFromCamera(pc) - views[v].xy).norm() <= triangulation_px_) {
        keep.push_back(static_cast<int>(v));
      }
    }
    if (keep.size() < 2) return -1;
    Point point;
    point.id = static_cast<int>(model_.points.size()) + 1;
    point.position = t->position;
    const Keypoint& k = features_[elements[keep[0]]->image].keypoints[elements[keep[0]]->feature];
    point.color = {k.rgb[0], k.rgb[1], k.rgb[2]};
    const int p = static_cast<int>(model_.points.size());
    model_.points.push_back(point);
    for (int v : keep) {
      model_.observations.push_back({elements[v]->image, p, views[v].xy, elements[v]->feature});
    }
    point_of_track_[track] = p;
    return p;
  }

  std::vector<int> NextImages() {
    std::vector<std::pair<int, int>> counts;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (model_.images[i].registered || failures_[i] >= 2 || gps_strikes_[i] > 0) continue;
      int n = 0;
      for (int t : tracks_.track_of[i]) n += (t >= 0 && point_of_track_[t] >= 0);
      if (n >= options_.min_pnp_inliers) counts.push_back({n, static_cast<int>(i)});
      status_[i].correspondences = n;
    }
    std::sort(counts.rbegin(), counts.rend());
    std::vector<int> out;
    for (size_t k = 0; k < counts.size() && k < 5; ++k) out.push_back(counts[k].second);
    return out;
  }

  // What SolvePnP asks of n correspondences, for the registration report.
  std::string PnpNeeds(size_t n, double min_inlier_ratio) const {
    const int needed = std::max(options_.min_pnp_inliers,
                                static_cast<int>(std::ceil(min_inlier_ratio * static_cast<double>(n))));
    return " (at least " + std::to_string(needed) + " needed)";
  }

  // PnP RANSAC (P3P) on 2D-3D correspondences given as undistorted rays,
  // refined by Levenberg-Marquardt on the inliers. std::nullopt when fewer
  // than min_pnp_inliers, or less than min_inlier_ratio of them, agree.
  std::optional<Pose> SolvePnP(int image, const std::vector<Eigen::Vector3d>& world,
                               const std::vector<Eigen::Vector2d>& rays, double min_inlier_ratio,
                               std::vector<int>* inliers) const {
    const double threshold = options_.max_reprojection_px / Focal(image);
    const std::optional<Pose> pose = EstimateAbsolutePose(world, rays, threshold, inliers);
    if (!pose || static_cast<int>(inliers->size()) < options_.min_pnp_inliers ||
        inliers->size() < min_inlier_ratio * world.size()) {
      return std::nullopt;
    }
    return pose;
  }

  bool Register(int image) {
    std::vector<Eigen::Vector3d> world;
    std::vector<Eigen::Vector2d> rays;
    std::vector<int> feats;
    for (size_t f = 0; f < tracks_.track_of[image].size(); ++f) {
      const int t = tracks_.track_of[image][f];
      if (t < 0 || point_of_track_[t] < 0) continue;
      const auto n = Normalized(image, static_cast<int>(f));
      if (!n) continue;
      world.push_back(model_.points[point_of_track_[t]].position);
      rays.push_back(*n);
      feats.push_back(static_cast<int>(f));
    }
    ImageRegistration& st = status_[image];
    st.correspondences = static_cast<int>(world.size());
    if (static_cast<int>(world.size()) < options_.min_pnp_inliers) {
      st.why_not = "too few 2D-3D correspondences (" + std::to_string(world.size()) + ")";
      ++failures_[image];
      return false;
    }
    std::vector<int> inliers;
    const auto pose = SolvePnP(image, world, rays, 0.2, &inliers);
    st.inliers = static_cast<int>(inliers.size());
    if (!pose) {
      st.why_not = "PnP found " + std::to_string(inliers.size()) + " inliers of " +
                   std::to_string(world.size()) + " 2D-3D correspondences" + PnpNeeds(world.size(), 0.2);
      ++failures_[image];
      return false;
    }
    Image& img = model_.images[image];
    img.pose = *pose;
    img.registered = true;
    st.registered = true;
    st.why_not.clear();
    const Camera& camera = model_.cameras[img.camera];
    for (size_t k = 0; k < feats.size(); ++k) {
      const int f = feats[k];
      const int p = point_of_track_[tracks_.track_of[image][f]];
      const Eigen::Vector2d xy = Pixel(image, f);
      const Eigen::Vector3d pc = img.PoseAtRow(xy.y(), camera.height).CamFromWorld(model_.points[p].position);
      if (pc.z() <= 0) continue;
      if ((camera.ImageFromCamera(pc) - xy).norm() <= options_.max_reprojection_px) {
        model_.observations.push_back({image, p, xy, f});
      }
    }
    // New tracks through this image.
    for (size_t f = 0; f < tracks_.track_of[image].size(); ++f) {
      const int t = tracks_.track_of[image][f];
      if (t >= 0 && point_of_track_[t] < 0) TriangulateTrack(t);
    }
    return true;
  }


  // Guided registration of images left out, from their GPS position (see the
  // header). Returns true when at least one image registered.
  bool RescueWithGps() {
    // Similarity from the model frame to the GPS frame.
    std::vector<Eigen::Vector3d> from, to;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (model_.images[i].registered && gps_[i]) {
        from.push_back(model_.images[i].pose.centre_in_world);
        to.push_back(*gps_[i]);
      }
    }
    if (from.size() < 3) return false;
    const auto fit = FitSimilarityRobust(from, to, 15.0, 3);
    if (!fit || fit->num_inliers < 3) return false;
    const Similarity model_from_gps = fit->transform.Inverse();
    bool any = false;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (model_.images[i].registered || !gps_[i] || features_[i].keypoints.empty() || gps_strikes_[i] >= 2) continue;
      if (RescueImage(static_cast<int>(i), model_from_gps, fit->transform,
                      std::max(10.0, 5.0 * fit->rms_m))) {
        any = true;
        Report();
      }
    }
    return any;
  }

  // Attitude of a registered capture-order neighbour (index order, up to 3
  // away): the one closest by GPS. Interpolating between the two sides would
  // be wrong at a strip's end, where the next photo flies the other way.
  std::optional<Eigen::Quaterniond> NeighbourAttitude(int image) const {
    const int n = static_cast<int>(model_.images.size());
    int best = -1;
    double best_distance = 1e300;
    for (int d = -3; d <= 3; ++d) {
      const int j = image + d;
      if (d == 0 || j < 0 || j >= n || !model_.images[j].registered) continue;
      const double distance = gps_[image] && gps_[j] ? (*gps_[image] - *gps_[j]).norm() : 1e6 + std::abs(d);
      if (distance < best_distance) {
        best_distance = distance;
        best = j;
      }
    }
    if (best < 0) return std::nullopt;
    return model_.images[best].pose.cam_from_world;
  }

  bool RescueImage(int image, const Similarity& model_from_gps, const Similarity& gps_from_model,
                   double max_gps_distance_m) {
    const auto attitude = NeighbourAttitude(image);
    if (!attitude) return false;
    Pose pose;
    pose.cam_from_world = *attitude;
    pose.centre_in_world = model_from_gps.Apply(*gps_[image]);
    const Camera& camera = model_.cameras[model_.images[image].camera];
    // The model's points, each with the descriptor of its track's first
    // registered element.
    std::vector<GuidedPoint> points;
    std::map<int, cv::Mat> descriptors;  // per reference image, decoded once
    for (size_t t = 0; t < tracks_.tracks.size(); ++t) {
      const int p = point_of_track_[t];
      if (p < 0) continue;
      for (const TrackElement& e : tracks_.tracks[t]) {
        if (!model_.images[e.image].registered) continue;
        auto it = descriptors.find(e.image);
        if (it == descriptors.end()) it = descriptors.emplace(e.image, features_[e.image].FloatDescriptors()).first;
        points.push_back({p, model_.points[p].position, it->second.row(e.feature)});
        break;
      }
    }
    std::sort(points.begin(), points.end(), [](const GuidedPoint& a, const GuidedPoint& b) { return a.id < b.id; });
    const GuidedMatcher matcher(features_[image], camera, options_.rescue_search_radius_px);
    const Eigen::Vector2d shift = matcher.VoteShift(pose, points);
    bool refined_pose = false;
    for (double radius : {40.0, 3.0 * options_.max_reprojection_px}) {
      std::vector<Eigen::Vector3d> world;
      std::vector<Eigen::Vector2d> rays;
      std::vector<std::pair<int, int>> pairs;  // (feature, point)
      // The first pass from the prediction shifted by the vote, the second
      // from the pose the first found.
      for (const GuidedMatch& m : matcher.Match(pose, refined_pose ? Eigen::Vector2d::Zero() : shift, radius, points)) {
        const auto n = Normalized(image, m.feature);
        if (!n) continue;
        world.push_back(model_.points[m.point].position);
        rays.push_back(*n);
        pairs.push_back({m.feature, m.point});
      }
      ImageRegistration& st = status_[image];
      st.correspondences = static_cast<int>(world.size());
      if (static_cast<int>(world.size()) < options_.min_pnp_inliers) {
        st.why_not = "guided matching from GPS found " + std::to_string(world.size()) +
                     " 2D-3D correspondences";
        return false;
      }
      std::vector<int> inliers;
      const auto solved = SolvePnP(image, world, rays, 0.3, &inliers);
      if (!solved) {
        st.why_not = "guided matching from GPS: PnP found " + std::to_string(inliers.size()) +
                     " inliers of " + std::to_string(world.size()) + PnpNeeds(world.size(), 0.3);
        return false;
      }
      pose = *solved;
      refined_pose = true;
      if (radius > 3.0 * options_.max_reprojection_px) continue;  // second, tight pass
      // The pose found must agree with the GPS position it started from.
      const double gps_distance = (gps_from_model.Apply(pose.centre_in_world) - *gps_[image]).norm();
      if (gps_distance > max_gps_distance_m) {
        st.why_not = "guided matching from GPS: the pose found lies " + std::to_string(gps_distance) +
                     " m from the GPS position";
        return false;
      }
      // Accept: observations of the inliers (checked with the full camera).
      Image& img = model_.images[image];
      img.pose = pose;
      img.registered = true;
      st.registered = true;
      st.inliers = static_cast<int>(inliers.size());
      st.why_not.clear();
      for (int k : inliers) {
        const auto [feat, p] = pairs[k];
        const Eigen::Vector3d pc = pose.CamFromWorld(model_.points[p].position);
        const Eigen::Vector2d xy = Pixel(image, feat);
        if (pc.z() > 0 && (camera.ImageFromCamera(pc) - xy).norm() <= options_.max_reprojection_px) {
          model_.observations.push_back({image, p, xy, feat});
        }
      }
      return true;
    }
    return false;
  }

  // Local bundle adjustment after registering `image` (the scheme of
  // COLMAP's mapper): it and the registered images sharing the most tie
  // points with it vary, with every point they observe; the other images
  // observing those points are held and hold the datum; intrinsics are held.
  // Solved on a copy holding only that neighbourhood, so its cost does not
  // grow with the model; observations it rejects are dropped here too.
  void LocalAdjust(int image) {
    const int window = options_.local_adjust_images;
    if (window <= 0 || image < 0) return;
    std::map<int, int> shared;  // registered image -> tie points shared with `image`
    for (size_t f = 0; f < tracks_.track_of[image].size(); ++f) {
      const int t = tracks_.track_of[image][f];
      if (t < 0 || point_of_track_[t] < 0) continue;
      for (const TrackElement& e : tracks_.tracks[t]) {
        if (e.image != image && model_.images[e.image].registered) ++shared[e.image];
      }
    }
    std::vector<std::pair<int, int>> ranked;
    for (const auto& [other, count] : shared) ranked.push_back({count, other});
    std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    std::vector<char> adjusted(model_.images.size(), 0);
    adjusted[image] = 1;
    for (size_t k = 0; k < ranked.size() && static_cast<int>(k) + 1 < window; ++k) adjusted[ranked[k].second] = 1;
    std::vector<char> local_point(model_.points.size(), 0);
    for (const Observation& obs : model_.observations) {
      if (adjusted[obs.image]) local_point[obs.point] = 1;
    }
    // The neighbourhood as a model of its own.
    SparseModel local;
    local.cameras = model_.cameras;
    std::vector<int> image_to_local(model_.images.size(), -1), point_to_local(model_.points.size(), -1);
    std::vector<int> image_of_local, point_of_local;
    std::vector<size_t> observation_of_local;
    for (size_t k = 0; k < model_.observations.size(); ++k) {
      Observation obs = model_.observations[k];
      if (!local_point[obs.point] || !model_.images[obs.image].registered) continue;
      if (image_to_local[obs.image] < 0) {
        image_to_local[obs.image] = static_cast<int>(local.images.size());
        local.images.push_back(model_.images[obs.image]);
        image_of_local.push_back(obs.image);
      }
      if (point_to_local[obs.point] < 0) {
        point_to_local[obs.point] = static_cast<int>(local.points.size());
        local.points.push_back(model_.points[obs.point]);
        point_of_local.push_back(obs.point);
      }
      obs.image = image_to_local[obs.image];
      obs.point = point_to_local[obs.point];
      local.observations.push_back(obs);
      observation_of_local.push_back(k);
    }
    BundleOptions o;
    o.held_poses.assign(local.images.size(), 0);
    int held = 0;
    for (size_t li = 0; li < local.images.size(); ++li) {
      o.held_poses[li] = !adjusted[image_of_local[li]];
      held += o.held_poses[li];
    }
    if (held < 2) return;  // nothing around it to hold the datum (a small model: the global one runs)
    // One solve of a few iterations: the neighbourhood starts close (PnP and
    // triangulation) and the next global adjustment finishes the job.
    o.loss = LossType::kHuber;
    o.loss_scale_px = 1.0;
    o.max_iterations = options_.local_adjust_iterations;
    o.function_tolerance = 1e-4;
    o.refine_intrinsics = IntrinsicsRefinement::kNone;
    o.compute_diagnostics = false;
    o.num_threads = options_.num_threads;
    const auto start = std::chrono::steady_clock::now();
    AdjustBundle(&local, o);
    local_adjustment_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++local_adjustments_;
    for (size_t li = 0; li < local.images.size(); ++li) {
      if (!o.held_poses[li]) model_.images[image_of_local[li]].pose = local.images[li].pose;
    }
    for (size_t lp = 0; lp < local.points.size(); ++lp) model_.points[point_of_local[lp]].position = local.points[lp].position;
    // Observations the adjusted neighbourhood cannot explain are dropped
    // (without a second solve).
    const std::vector<double> errors = ReprojectionErrors(local);
    std::vector<char> drop(model_.observations.size(), 0);
    bool any = false;
    for (size_t k = 0; k < errors.size(); ++k) {
      if (!(errors[k] <= options_.max_reprojection_px)) drop[observation_of_local[k]] = any = true;
    }
    if (!any) return;
    std::vector<Observation> observations;
    observations.reserve(model_.observations.size());
    for (size_t k = 0; k < model_.observations.size(); ++k) {
      if (!drop[k]) observations.push_back(model_.observations[k]);
    }
    model_.observations.swap(observations);
  }

  void GlobalAdjust(bool final_round) {
    if (options_.gps_priors) {
      if (anchored_at_ == 0) AnchorToGps();
      if (anchored_at_ > 0) SetPriors();
    }
    BundleOptions o = MapperBundleOptions(final_round ? 100 : 40);
    const int n = NumRegistered();
    const bool hold_focal = n >= 5 && HoldFocal();
    focal_held_ = hold_focal;  // the last adjustment's, which the model leaves with
    if (final_round && !hold_focal) {
      o.refine_intrinsics = IntrinsicsRefinement::kAll;
    } else if (final_round) {
      o.refine_intrinsics = IntrinsicsRefinement::kList;
      o.refine_params = {"cx", "cy", "k1", "k2", "k3", "p1", "p2"};
    } else if (n >= 5) {
      o.refine_intrinsics = IntrinsicsRefinement::kList;
      o.refine_params = hold_focal ? std::vector<std::string>{"k1", "k2"} : std::vector<std::string>{"f", "k1", "k2"};
    } else {
      o.refine_intrinsics = IntrinsicsRefinement::kNone;
    }
    o.min_images_to_refine_intrinsics = 3;
    o.focal_prior_px = options_.focal_prior_px;
    if (!final_round && options_.iterative_above_images > 0 && n > options_.iterative_above_images) {
      o.linear_solver = LinearSolverChoice::kIterativeSchur;
    }
    AdjustGlobally(o);
    DeregisterAgainstGps();
    // Then tracks that can be triangulated now.
    DropPointsWithoutTwoObservations();
    for (size_t t = 0; t < tracks_.tracks.size(); ++t) {
      if (point_of_track_[t] < 0) TriangulateTrack(static_cast<int>(t));
    }
  }

  // One global adjustment of the model, counted and timed.
  BundleSummary AdjustGlobally(const BundleOptions& o) {
    const auto start = std::chrono::steady_clock::now();
    const BundleSummary summary = AdjustBundle(&model_, o);
    adjustment_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    adjustment_iterations_ += summary.iterations;
    ++adjustments_;
    return summary;
  }

  // The start from the photos' GPS and attitude (MapperOptions::
  // start_from_priors). False, with nothing registered, where fewer than 3
  // photos state both or fewer than 3 keep enough tie points.
  bool StartFromPriors() {
    std::vector<int> placed;
    std::vector<double> sigmas;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (!gps_[i] || !priors_.attitude[i] || features_[i].keypoints.empty()) continue;
      Image& image = model_.images[i];
      image.pose.centre_in_world = *gps_[i];
      image.pose.cam_from_world = *priors_.attitude[i];
      image.registered = true;
      has_prior_[i] = 1;
      placed.push_back(static_cast<int>(i));
      sigmas.push_back(SigmaH(static_cast<int>(i)));
    }
    if (placed.size() < 3) {
      for (int i : placed) model_.images[i].registered = false;
      return false;
    }
    anchor_threshold_m_ = AnchorThreshold(sigmas);
    anchored_at_ = static_cast<int>(placed.size());
    from_priors_ = true;
    for (double px : {100.0, 20.0, options_.max_reprojection_px}) {
      triangulation_px_ = px;
      for (size_t t = 0; t < tracks_.tracks.size(); ++t) {
        if (point_of_track_[t] < 0) TriangulateTrack(static_cast<int>(t));
      }
      SetPriors();
      BundleOptions o = MapperBundleOptions(40);
      o.loss_scale_px = std::max(1.0, px / 10.0);
      o.outlier_threshold_px = px;
      o.refine_intrinsics = IntrinsicsRefinement::kNone;
      const BundleSummary summary = AdjustGlobally(o);
      DropPointsWithoutTwoObservations();
      char text[200];
      std::snprintf(text, sizeof text, "from the photos' GPS and attitude: %d photos, %d points, RMS %.2f px at %.0f px",
                    NumRegistered(), NumLivePoints(), summary.final_rms_px, px);
      ReportProgress(options_.progress, 0.1, text);
    }
    triangulation_px_ = options_.max_reprojection_px;
    // Photos that kept too few tie points are taken out (PnP may bring them
    // back).
    std::vector<int> observations(model_.images.size(), 0);
    for (const Observation& obs : model_.observations) ++observations[obs.image];
    for (int i : placed) {
      model_.images[i].registered = observations[i] >= options_.min_pnp_inliers;
      if (model_.images[i].registered) status_[i] = {true, "", observations[i], observations[i]};
    }
    std::vector<Observation> kept;
    for (const Observation& obs : model_.observations) {
      if (model_.images[obs.image].registered) kept.push_back(obs);
    }
    model_.observations.swap(kept);
    DropPointsWithoutTwoObservations();
    if (NumRegistered() >= 3) return true;
    for (int i : placed) status_[i] = ImageRegistration();
    for (Image& image : model_.images) image.registered = false;
    model_.points.clear();
    model_.observations.clear();
    std::fill(point_of_track_.begin(), point_of_track_.end(), -1);
    anchored_at_ = 0;
    from_priors_ = false;
    return false;
  }

  // Points left with fewer than two observations are dropped (their tracks
  // may be triangulated again).
  void DropPointsWithoutTwoObservations() {
    const std::vector<int> per_point = model_.ObservationsPerPoint();
    std::vector<Observation> kept;
    for (const Observation& obs : model_.observations) {
      if (per_point[obs.point] >= 2) kept.push_back(obs);
    }
    model_.observations.swap(kept);
    for (size_t t = 0; t < point_of_track_.size(); ++t) {
      const int p = point_of_track_[t];
      if (p >= 0 && per_point[p] < 2) point_of_track_[t] = -1;
    }
  }

  // Moves the model into the GPS frame (see the header) once the registered
  // images with GPS number gps_prior_min_images and span the block: across
  // the flight line a tenth of its length, so that the similarity's roll
  // about that line is determined. The fit is robust (a threshold of 3
  // sigma of the fixes, at least 10 m: anchor_threshold_m_) and must keep
  // three quarters of them.
  void AnchorToGps() {
    std::vector<Eigen::Vector3d> from, to;
    std::vector<double> sigmas;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (!model_.images[i].registered || !gps_[i]) continue;
      from.push_back(model_.images[i].pose.centre_in_world);
      to.push_back(*gps_[i]);
      sigmas.push_back(SigmaH(static_cast<int>(i)));
    }
    if (static_cast<int>(from.size()) < std::max(3, options_.gps_prior_min_images)) return;
    if (!(AcrossSpreadRatio(to) > 0.01)) return;
    const double threshold = AnchorThreshold(sigmas);
    const auto fit = FitSimilarityRobust(from, to, threshold, 3);
    if (!fit || 4 * fit->num_inliers < 3 * static_cast<int>(from.size())) {
      if (fit) {
        char text[200];
        std::snprintf(text, sizeof text, "not moved into the GPS frame at %d images: %d of %d fixes within %.0f m",
                      NumRegistered(), fit->num_inliers, static_cast<int>(from.size()), threshold);
        ReportProgress(options_.progress, static_cast<double>(NumRegistered()) / model_.images.size(), text);
      }
      return;
    }
    anchor_threshold_m_ = threshold;
    const Similarity& s = fit->transform;
    for (Image& image : model_.images) {
      image.pose.centre_in_world = s.Apply(image.pose.centre_in_world);
      image.pose.cam_from_world = (image.pose.cam_from_world * s.rotation.conjugate()).normalized();
    }
    for (Point& point : model_.points) point.position = s.Apply(point.position);
    anchored_at_ = NumRegistered();
    char text[200];
    std::snprintf(text, sizeof text,
                  "model moved into the GPS frame at %d images (%d fixes, RMS %.2f m); GPS fixes are priors from now",
                  anchored_at_, fit->num_inliers, fit->rms_m);
    ReportProgress(options_.progress, static_cast<double>(NumRegistered()) / model_.images.size(), text);
  }

  // A fix enters as a prior where the anchored model puts its camera within
  // the anchoring's threshold of it when it first could (a fix that jumps,
  // or a false registration, is left to the GPS check); once in, it stays
  // while its photo is registered, so that one adjustment's excursion does
  // not drop priors and let the block drift further. Photos placed by their
  // priors (the start from them) hold theirs from the start.
  bool PriorUsable(int image) const {
    return gps_[image] && (has_prior_[image] || (model_.images[image].pose.centre_in_world - *gps_[image]).norm() <=
                                                     anchor_threshold_m_);
  }
  double SigmaH(int image) const {
    return priors_.gps_sigma_h_m[image] > 0.0 ? priors_.gps_sigma_h_m[image] : 5.0;
  }
  double SigmaV(int image) const {
    return priors_.gps_sigma_v_m[image] > 0.0 ? priors_.gps_sigma_v_m[image] : 10.0;
  }

  // The anchored model's priors and rolling shutters on its registered
  // images (an image registered since the last adjustment gets them here).
  void SetPriors() {
    for (size_t i = 0; i < model_.images.size(); ++i) {
      Image& image = model_.images[i];
      image.gps_prior.reset();
      image.rolling_shutter = priors_.rolling_shutter[i];
      if (!image.registered) has_prior_[i] = 0;
      if (!image.registered || !PriorUsable(static_cast<int>(i))) continue;
      has_prior_[i] = 1;
      PositionPrior prior;
      prior.position = *gps_[i];
      prior.sigma_h_m = SigmaH(static_cast<int>(i));
      prior.sigma_v_m = SigmaV(static_cast<int>(i));
      image.gps_prior = prior;
    }
  }

  // What every global adjustment of the mapper shares: Huber screening, then
  // least squares (MapperOptions::global_adjust_screening), outliers beyond
  // max_reprojection_px; started from the photos' priors, their tilt held to
  // the stated attitudes' sigma.
  BundleOptions MapperBundleOptions(int max_iterations) const {
    BundleOptions o;
    o.loss = LossType::kHuber;
    o.loss_scale_px = 1.0;
    o.outlier_threshold_px = options_.max_reprojection_px;
    o.max_outlier_rounds = 2;
    o.num_threads = options_.num_threads;
    o.max_iterations = max_iterations;
    o.least_squares_after_screening = options_.global_adjust_screening;
    if (from_priors_) {
      o.attitude_prior_sigma_deg = priors_.attitude_sigma_deg;
      for (size_t i = 0; i < model_.images.size(); ++i) {
        const auto& q = priors_.attitude[i];
        // The stated down direction in the camera frame; none without one.
        o.attitude_prior_down_in_camera.push_back(q ? Eigen::Vector3d(*q * Eigen::Vector3d(0, 0, -1))
                                                    : Eigen::Vector3d::Zero());
      }
    }
    return o;
  }

  // Nadir photos of flat ground at one altitude (block_geometry.h, measured
  // along the block's mean optical axis; flat: the depths within each photo
  // lie on a plane to kPlanarRoughnessRatio): the image scale is f over the
  // depth, and the depth is the model's own, so the focal length is not in
  // the photos at all. Refined, it wanders wherever the slightest systematic
  // pulls it (on crop rows, from 520 to 982 px against a 10 % EXIF prior,
  // which weighs nothing against 10^5 observations) and bends the model
  // with it. Held at its EXIF / certificate value there (set back to it if
  // an earlier round moved it); the georeference decides with GPS and
  // control whether the block determines it. Without a measured value for
  // every camera there is nothing to hold it at.
  bool HoldFocal() {
    std::vector<char> used(model_.cameras.size(), 0);
    for (const Image& image : model_.images) {
      if (image.registered) used[image.camera] = 1;
    }
    for (size_t c = 0; c < used.size(); ++c) {
      if (used[c] && !(c < options_.focal_prior_px.size() && options_.focal_prior_px[c] > 0.0)) return false;
    }
    // The axes' mean as the vertical: a first strip's centres lie along a
    // line, which MeasureViewingGeometry cannot call nadir yet, but the
    // focal length wanders from the first adjustment that frees it.
    const ViewingGeometry view = MeasureViewingGeometry(model_);
    if (view.images < 3 || !(view.mean_axis.norm() > 0.0) || view.spread_deg > 15.0) return false;
    const BlockGeometry g = MeasureBlockGeometry(model_, view.mean_axis);
    if (!(g.roughness_ratio < kPlanarRoughnessRatio && g.height_variation_ratio < 0.05 && g.tilt_p90_deg < 15.0)) {
      return false;
    }
    for (size_t c = 0; c < used.size(); ++c) {
      if (!used[c]) continue;
      Camera& camera = model_.cameras[c];
      camera.params[camera.info().focal_params.at(0)] = options_.focal_prior_px[c];
    }
    return true;
  }

  // Registrations that disagree with their GPS (see the header). Returns
  // how many images were de-registered.
  int DeregisterAgainstGps() {
    if (!(options_.gps_check_m > 0.0)) return 0;
    std::vector<int> images;
    std::vector<Eigen::Vector3d> from, to;
    for (size_t i = 0; i < model_.images.size(); ++i) {
      if (!model_.images[i].registered || !gps_[i]) continue;
      images.push_back(static_cast<int>(i));
      from.push_back(model_.images[i].pose.centre_in_world);
      to.push_back(*gps_[i]);
    }
    if (images.size() < 6) return 0;
    // The block's vertical: a nadir block's mean optical axis, else its
    // gimbal pitches'; without either, no vertical to level by (yet).
    const ViewingGeometry view = MeasureViewingGeometry(model_);
    Eigen::Vector3d down = view.mean_axis;
    if (!view.nadir) {
      if (gimbal_.empty()) return 0;
      const GimbalVertical vertical = MeasureGimbalVertical(model_, gimbal_);
      if (!vertical.usable) return 0;
      down = vertical.down_in_model;
    }
    const auto fit = FitLevelledSimilarity(from, to, down, options_.gps_check_m);
    if (!fit || 2 * fit->num_inliers <= static_cast<int>(images.size())) return 0;  // the GPS as a whole disagrees
    const double limit = std::max(options_.gps_check_m, 5.0 * fit->rms_m);
    int removed = 0;
    for (size_t k = 0; k < images.size(); ++k) {
      const double distance = (fit->transform.Apply(from[k]) - to[k]).head<2>().norm();
      if (distance <= limit || !GpsAgreesWithNeighbours(images[k])) continue;
      Deregister(images[k], distance);
      ++removed;
    }
    return removed;
  }

  // Whether an image's GPS position is where its capture-order neighbours'
  // put it: within max(5 m, half the median spacing between consecutive
  // fixes) of the midpoint of the two beside it, or of the extrapolation of
  // the two before or the two after (a strip's end). Without neighbours:
  // false (nothing says the fix is right).
  bool GpsAgreesWithNeighbours(int image) const {
    const int n = static_cast<int>(gps_.size());
    auto at = [&](int j) -> const std::optional<Eigen::Vector3d>& {
      static const std::optional<Eigen::Vector3d> none;
      return j >= 0 && j < n ? gps_[j] : none;
    };
    std::vector<double> spacing;
    for (int j = 1; j < n; ++j) {
      if (gps_[j] && gps_[j - 1]) spacing.push_back((*gps_[j] - *gps_[j - 1]).head<2>().norm());
    }
    if (spacing.empty()) return false;
    std::nth_element(spacing.begin(), spacing.begin() + spacing.size() / 2, spacing.end());
    const double tolerance = std::max(5.0, 0.5 * spacing[spacing.size() / 2]);
    const Eigen::Vector2d g = at(image)->head<2>();
    std::vector<Eigen::Vector2d> predictions;
    if (at(image - 1) && at(image + 1)) predictions.push_back(0.5 * (at(image - 1)->head<2>() + at(image + 1)->head<2>()));
    if (at(image - 1) && at(image - 2)) predictions.push_back(2.0 * at(image - 1)->head<2>() - at(image - 2)->head<2>());
    if (at(image + 1) && at(image + 2)) predictions.push_back(2.0 * at(image + 1)->head<2>() - at(image + 2)->head<2>());
    for (const Eigen::Vector2d& p : predictions) {
      if ((p - g).norm() <= tolerance) return true;
    }
    return false;
  }

  void Deregister(int image, double distance_m) {
    model_.images[image].registered = false;
    std::vector<Observation> kept;
    kept.reserve(model_.observations.size());
    for (const Observation& obs : model_.observations) {
      if (obs.image != image) kept.push_back(obs);
    }
    model_.observations.swap(kept);
    ++gps_strikes_[image];
    char text[300];
    std::snprintf(text, sizeof text,
                  "registered %.0f m from its GPS position, which agrees with its neighbours' in capture order: "
                  "a false registration (repetitive texture?), de-registered%s",
                  distance_m, gps_strikes_[image] >= 2 ? " twice, left out" : "");
    status_[image].registered = false;
    status_[image].why_not = text;
    ReportProgress(options_.progress, static_cast<double>(NumRegistered()) / model_.images.size(),
                   model_.images[image].name + ": " + text);
  }

  // Removes points without two observations and renumbers.
  void Compact() {
    const std::vector<int> per_point = model_.ObservationsPerPoint();
    std::vector<char> keep(model_.points.size());
    for (size_t p = 0; p < keep.size(); ++p) keep[p] = per_point[p] >= 2;
    model_.KeepPoints(keep);
    for (size_t p = 0; p < model_.points.size(); ++p) model_.points[p].id = static_cast<int>(p) + 1;
  }

  const std::vector<ImageFeatures>& features_;
  const std::vector<PairMatches>& matches_;
  MapperOptions options_;
  SparseModel model_;
  Tracks tracks_;
  std::vector<int> point_of_track_;
  std::vector<ImageRegistration> status_;
  std::vector<int> failures_;
  std::vector<int> gps_strikes_;  // de-registrations against the GPS, per image
  std::map<int, bool> has_pair_;
  std::vector<std::optional<Eigen::Vector3d>> gps_;
  std::map<std::string, GimbalAttitude> gimbal_;  // by image name
  MapperPriors priors_;
  bool from_priors_ = false;  // started from the photos' GPS and attitude
  std::vector<char> has_prior_;  // per image: its fix is a prior while it stays registered
  double triangulation_px_ = 4.0;  // a triangulated view's largest reprojection error
  int anchored_at_ = 0;  // registered images when the model moved into the GPS frame
  double anchor_threshold_m_ = 0.0;
  int adjustments_ = 0;
  int adjustment_iterations_ = 0;
  bool focal_held_ = false;
  double adjustment_s_ = 0.0;
  int local_adjustments_ = 0;
  double local_adjustment_s_ = 0.0;
};

// The similarity from a model's frame to the GPS frame: robust over the
// registered images with GPS, or, where their positions lie along a line
// (a single strip), levelled by the mean optical axis and fitted in plan.
std::optional<Similarity> GpsFromModel(const SparseModel& model,
                                       const std::vector<std::optional<Eigen::Vector3d>>& gps) {
  std::vector<Eigen::Vector3d> from, to;
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < model.images.size(); ++i) {
    if (!model.images[i].registered || i >= gps.size() || !gps[i]) continue;
    from.push_back(model.images[i].pose.centre_in_world);
    to.push_back(*gps[i]);
    axis += model.images[i].pose.cam_from_world.conjugate() * Eigen::Vector3d::UnitZ();
  }
  if (from.size() < 3) return std::nullopt;
  const double across = AcrossSpreadRatio(to);
  if (!(across >= 0.0)) return std::nullopt;
  if (across > 0.01) {  // across-strip spread above a tenth of the length
    const auto fit = FitSimilarityRobust(from, to, 15.0, 3);
    if (fit && fit->num_inliers >= 3) return fit->transform;
    return std::nullopt;
  }
  const auto fit = FitLevelledSimilarity(from, to, axis.normalized(), 15.0);
  if (fit && fit->num_inliers >= 2) return fit->transform;
  return std::nullopt;
}

// Further components among the photos the main model left out (see the
// header).
void AddComponents(const std::vector<std::string>& names, const std::vector<int>& camera_of_image,
                   const std::vector<ImageFeatures>& features, const std::vector<PairMatches>& matches,
                   const MapperOptions& options, const std::vector<std::optional<Eigen::Vector3d>>& gps,
                   const MapperPriors& priors, MapperResult* result) {
  const size_t n = names.size();
  const std::set<std::string> struck(result->gps_deregistered.begin(), result->gps_deregistered.end());
  std::set<int> tried;  // images an earlier attempt registered (placed or not): not tried again
  std::optional<Similarity> gps_from_main = GpsFromModel(result->model, gps);
  while (true) {
    std::vector<int> left;
    for (size_t i = 0; i < n; ++i) {
      if (!result->model.images[i].registered && !struck.count(names[i]) && !tried.count(static_cast<int>(i)) &&
          !features[i].keypoints.empty()) {
        left.push_back(static_cast<int>(i));
      }
    }
    if (static_cast<int>(left.size()) < kMinComponentImages) return;
    std::vector<int> local(n, -1);
    for (size_t k = 0; k < left.size(); ++k) local[left[k]] = static_cast<int>(k);
    std::vector<std::string> sub_names;
    std::vector<int> sub_cameras;
    std::vector<ImageFeatures> sub_features;
    std::vector<std::optional<Eigen::Vector3d>> sub_gps;
    MapperPriors sub_priors;
    auto at = [](const auto& v, int i) { return static_cast<size_t>(i) < v.size() ? v[i] : std::decay_t<decltype(v[i])>{}; };
    for (int i : left) {
      sub_names.push_back(names[i]);
      sub_cameras.push_back(camera_of_image[i]);
      sub_features.push_back(features[i]);
      sub_gps.push_back(at(gps, i));
      sub_priors.gps_sigma_h_m.push_back(at(priors.gps_sigma_h_m, i));
      sub_priors.gps_sigma_v_m.push_back(at(priors.gps_sigma_v_m, i));
      sub_priors.rolling_shutter.push_back(at(priors.rolling_shutter, i));
    }
    std::vector<PairMatches> sub_matches;
    for (const PairMatches& m : matches) {
      if (local[m.i] < 0 || local[m.j] < 0) continue;
      PairMatches copy = m;
      copy.i = local[m.i];
      copy.j = local[m.j];
      sub_matches.push_back(std::move(copy));
    }
    if (sub_matches.empty()) return;
    MapperOptions sub_options = options;
    sub_options.progress = nullptr;
    Mapper mapper(sub_names, sub_cameras, result->model.cameras, sub_features, sub_matches, sub_options, sub_gps, {},
                  sub_priors);
    MapperResult sub = mapper.Run();
    std::vector<int> members;
    for (size_t k = 0; k < left.size(); ++k) {
      if (sub.model.images[k].registered) members.push_back(static_cast<int>(k));
    }
    if (members.empty()) return;
    if (static_cast<int>(members.size()) < kMinComponentImages) {
      // Nothing more to build from these photos; try the rest without them.
      for (int k : members) tried.insert(left[k]);
      if (sub.initial_pair.empty()) return;  // no pair to start from among them at all
      continue;
    }
    for (int k : members) tried.insert(left[k]);
    const int index = static_cast<int>(result->component_images.size());
    const std::optional<Similarity> gps_from_sub = GpsFromModel(sub.model, sub_gps);
    std::vector<std::string> member_names;
    for (int k : members) member_names.push_back(sub_names[k]);
    if (!gps_from_main || !gps_from_sub) {
      const std::string why =
          "in a separate group of " + std::to_string(members.size()) +
          " photos that share tie points with each other but none with the main model; without GPS on 3 or "
          "more photos of both there is nothing to place it by (" + JoinNames(member_names, 5) + ")";
      for (int k : members) result->images[left[k]].why_not = why;
      continue;
    }
    // main <- GPS <- sub
    const Similarity main_from_gps = gps_from_main->Inverse();
    const Similarity& s1 = *gps_from_sub;
    const Eigen::Quaterniond rotation = main_from_gps.rotation * s1.rotation;
    auto place = [&](const Eigen::Vector3d& x) { return main_from_gps.Apply(s1.Apply(x)); };
    for (int k : members) {
      Image& image = result->model.images[left[k]];
      const Pose& pose = sub.model.images[k].pose;
      image.pose.centre_in_world = place(pose.centre_in_world);
      image.pose.cam_from_world = (pose.cam_from_world * rotation.conjugate()).normalized();
      image.registered = true;
      result->images[left[k]] = sub.images[k];
      result->images[left[k]].registered = true;
      result->component[left[k]] = index;
    }
    const int offset = static_cast<int>(result->model.points.size());
    for (Point p : sub.model.points) {
      p.position = place(p.position);
      p.id = static_cast<int>(result->model.points.size()) + 1;
      result->model.points.push_back(p);
    }
    for (Observation obs : sub.model.observations) {
      if (!sub.model.images[obs.image].registered) continue;
      obs.image = left[obs.image];
      obs.point += offset;
      result->model.observations.push_back(obs);
    }
    result->component_images.push_back(static_cast<int>(members.size()));
    ReportProgress(options.progress, 1.0,
                   "a further component of " + std::to_string(members.size()) +
                       " photos with no tie points to the main model, placed by GPS: " + JoinNames(member_names, 5));
  }
}

}  // namespace

MapperResult ReconstructIncremental(const std::vector<std::string>& names,
                                    const std::vector<int>& camera_of_image,
                                    const std::vector<Camera>& cameras,
                                    const std::vector<ImageFeatures>& features,
                                    const std::vector<PairMatches>& matches,
                                    const MapperOptions& options,
                                    const std::vector<std::optional<Eigen::Vector3d>>& gps_enu,
                                    const std::map<std::string, GimbalAttitude>& gimbal,
                                    const MapperPriors& priors) {
  AEROTRI_CHECK(names.size() == camera_of_image.size() && names.size() == features.size());
  Mapper mapper(names, camera_of_image, cameras, features, matches, options, gps_enu, gimbal, priors);
  MapperResult result = mapper.Run();
  result.component.assign(names.size(), -1);
  int main_images = 0;
  for (size_t i = 0; i < names.size(); ++i) {
    if (result.model.images[i].registered) {
      result.component[i] = 0;
      ++main_images;
    }
  }
  result.component_images = {main_images};
  if (main_images >= 2) AddComponents(names, camera_of_image, features, matches, options, gps_enu, priors, &result);
  return result;
}

}  // namespace aerotri
