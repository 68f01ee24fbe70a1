// SPDX-License-Identifier: BSD-3-Clause
// Merging the parts of a split survey: parts in frames of their own, sharing
// photos at the seams, become one model in the first part's frame, with
// every photo once and every tie point seen in two parts once.
#include "libphoto/pipeline/survey_split.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "libphoto/simulate/synthetic_survey.h"

namespace aerotri {
namespace {

// The part of `model` holding the photos whose centre lies in [x0, x1) east,
// with its tie points' observations in those photos, moved into another
// frame by the similarity (s, R, t): what a part's own reconstruction gives.
SparseModel Part(const SparseModel& model, double x0, double x1, double s, const Eigen::Quaterniond& r,
                 const Eigen::Vector3d& t) {
  SparseModel part;
  part.cameras = model.cameras;
  std::vector<int> image_map(model.images.size(), -1);
  for (size_t i = 0; i < model.images.size(); ++i) {
    const double x = model.images[i].pose.centre_in_world.x();
    if (x < x0 || x >= x1) continue;
    Image im = model.images[i];
    im.pose.centre_in_world = s * (r * im.pose.centre_in_world) + t;
    im.pose.cam_from_world = im.pose.cam_from_world * r.conjugate();
    image_map[i] = static_cast<int>(part.images.size());
    part.images.push_back(im);
  }
  std::map<int, std::vector<Observation>> seen;
  for (const Observation& obs : model.observations) {
    if (image_map[obs.image] >= 0 && model.points[obs.point].role == PointRole::kTie) seen[obs.point].push_back(obs);
  }
  for (const auto& [p, observations] : seen) {
    if (observations.size() < 2) continue;
    Point point = model.points[p];
    point.position = s * (r * point.position) + t;
    const int index = static_cast<int>(part.points.size());
    part.points.push_back(point);
    for (Observation obs : observations) {
      obs.image = image_map[obs.image];
      obs.point = index;
      part.observations.push_back(obs);
    }
  }
  return part;
}

// A block of tie points only, and the east extent of its camera centres.
SyntheticSurvey TieBlock(std::uint32_t seed, int ties, double* lo, double* hi) {
  SyntheticSurveyOptions so;
  so.seed = seed;
  so.num_tie_points = ties;
  so.num_control_points = 0;
  so.num_check_points = 0;
  SyntheticSurvey survey = MakeSyntheticSurvey(so);
  *lo = 1e300;
  *hi = -1e300;
  for (const Image& im : survey.observed.images) {
    *lo = std::min(*lo, im.pose.centre_in_world.x());
    *hi = std::max(*hi, im.pose.centre_in_world.x());
  }
  return survey;
}

TEST(SurveySplit, PartsInTheirOwnFramesMergeIntoOneModel) {
  double lo = 0.0, hi = 0.0;
  const SyntheticSurvey survey = TieBlock(3, 1500, &lo, &hi);
  const SparseModel& truth = survey.observed;
  const double third = (hi - lo) / 3.0, seam = 0.3 * third;
  const Eigen::Quaterniond r1(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 1.0).normalized()));
  const Eigen::Quaterniond r2(Eigen::AngleAxisd(-1.9, Eigen::Vector3d(0.5, 0.1, 1.0).normalized()));
  // Part 1 in the survey's frame; parts 2 and 3 turned, scaled and moved.
  const std::vector<SparseModel> parts = {
      Part(truth, lo - 1.0, lo + third + seam, 1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()),
      Part(truth, lo + 2 * third - seam, hi + 1.0, 0.37, r2, Eigen::Vector3d(-40.0, 7.0, 3.0)),
      Part(truth, lo + third - seam, lo + 2 * third + seam, 2.5, r1, Eigen::Vector3d(100.0, -20.0, 5.0))};
  std::map<std::string, int> camera_of_image;
  for (const Image& im : truth.images) camera_of_image[im.name] = 0;
  MergeSummary summary;
  const SparseModel merged = MergePartModels(parts, truth.cameras, camera_of_image, &summary);
  // The middle part links to the first, then the last to them (not in file order).
  EXPECT_TRUE(summary.unlinked_parts.empty());
  ASSERT_EQ(summary.seam_rms_m.size(), 2u);
  for (double rms : summary.seam_rms_m) EXPECT_LT(rms, 1e-6);
  // Every photo once, where the survey has it.
  ASSERT_EQ(merged.images.size(), truth.images.size());
  std::map<std::string, const Image*> truth_image;
  for (const Image& im : truth.images) truth_image[im.name] = &im;
  std::set<std::string> names;
  for (const Image& im : merged.images) {
    EXPECT_TRUE(names.insert(im.name).second) << im.name;
    const Image& t = *truth_image.at(im.name);
    EXPECT_LT((im.pose.centre_in_world - t.pose.centre_in_world).norm(), 1e-6) << im.name;
    EXPECT_LT(im.pose.cam_from_world.angularDistance(t.pose.cam_from_world), 1e-9) << im.name;
  }
  EXPECT_GT(summary.shared_images, 0);
  // Every tie point seen by two photos of a part is one point, in place, with
  // each of its observations once; the points seen across a seam were joined.
  std::set<int> in_some_part;  // truth point ids (Part keeps them)
  for (const SparseModel& part : parts) {
    for (const Point& p : part.points) in_some_part.insert(p.id);
  }
  EXPECT_EQ(merged.points.size(), in_some_part.size());
  EXPECT_GT(summary.merged_points, 0);
  std::set<std::tuple<int, double, double>> measured;
  for (const Observation& obs : merged.observations) {
    EXPECT_TRUE(measured.insert({obs.image, obs.xy.x(), obs.xy.y()}).second);
  }
  double worst = 0.0;
  for (const Point& p : merged.points) {
    // The merged point keeps the first part's position: the truth, moved back.
    double best = 1e300;
    for (const Point& t : truth.points) best = std::min(best, (t.position - p.position).norm());
    worst = std::max(worst, best);
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(SurveySplit, APartSharingTooFewPhotosIsNamedNotPlaced) {
  double lo = 0.0, hi = 0.0;
  const SyntheticSurvey survey = TieBlock(4, 600, &lo, &hi);
  const double mid = 0.5 * (lo + hi);
  const std::vector<SparseModel> parts = {
      Part(survey.observed, lo - 1.0, mid, 1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero()),
      Part(survey.observed, mid, hi + 1.0, 1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero())};
  std::map<std::string, int> camera_of_image;
  for (const Image& im : survey.observed.images) camera_of_image[im.name] = 0;
  MergeSummary summary;
  MergePartModels(parts, survey.observed.cameras, camera_of_image, &summary);
  EXPECT_EQ(summary.unlinked_parts, std::vector<std::string>{"2"});
}

}  // namespace
}  // namespace aerotri
