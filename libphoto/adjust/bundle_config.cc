// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/bundle_config.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <sstream>

namespace aerotri {
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

std::string ToString(BundleGauge gauge) {
  switch (gauge) {
    case BundleGauge::kPriors: return "priors";
    case BundleGauge::kFixedImage: return "fixed_image";
    case BundleGauge::kFreeNetwork: return "free_network";
    case BundleGauge::kHeldRotation: return "held_rotation";
    case BundleGauge::kHeldImages: return "held_images";
  }
  return "?";
}

std::vector<int> RefinedParams(const Camera& camera, const BundleOptions& options) {
  const CameraModelInfo& info = camera.info();
  std::vector<int> refined;
  switch (options.refine_intrinsics) {
    case IntrinsicsRefinement::kNone:
      break;
    case IntrinsicsRefinement::kFocal:
      refined = info.focal_params;
      break;
    case IntrinsicsRefinement::kFocalPrincipalPoint:
      refined = info.focal_params;
      refined.insert(refined.end(), info.principal_point_params.begin(), info.principal_point_params.end());
      break;
    case IntrinsicsRefinement::kAll:
      for (int i = 0; i < info.num_params(); ++i) refined.push_back(i);
      break;
    case IntrinsicsRefinement::kList:
      for (const std::string& name : options.refine_params) {
        const auto it = std::find(info.param_names.begin(), info.param_names.end(), Lower(name));
        if (it != info.param_names.end()) {
          refined.push_back(static_cast<int>(it - info.param_names.begin()));
        } else if (Lower(name) == "pp" || Lower(name) == "cx,cy") {
          refined.insert(refined.end(), info.principal_point_params.begin(), info.principal_point_params.end());
        }
        // A name the model lacks (e.g. k3 on a pinhole) is simply not refined.
      }
      break;
  }
  std::sort(refined.begin(), refined.end());
  refined.erase(std::unique(refined.begin(), refined.end()), refined.end());
  return refined;
}

bool PriorsFixDatum(const std::vector<Eigen::Vector3d>& positions) {
  if (positions.size() < 3) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : positions) mean += p;
  mean /= static_cast<double>(positions.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : positions) cov += (p - mean) * (p - mean).transpose();
  cov /= static_cast<double>(positions.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d ev = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  // ev ascending: ev(1) is the spread across the main direction.
  return ev(2) > 0.0 && ev(1) > 1e-2 * ev(2);
}

bool BundleConfig::AnyMerged() const {
  return std::any_of(merged.begin(), merged.end(), [](char m) { return m != 0; });
}

bool BundleConfig::HoldsRotationOf(int image) const {
  if (image >= 0 && image < static_cast<int>(held.size()) && held[image]) return true;
  return image >= 0 && image == image_a && (gauge == BundleGauge::kFixedImage || gauge == BundleGauge::kHeldRotation);
}

bool BundleConfig::HoldsCentreOf(int image) const {
  if (image >= 0 && image < static_cast<int>(held.size()) && held[image]) return true;
  return image >= 0 && image == image_a && gauge == BundleGauge::kFixedImage;
}

std::vector<int> BundleConfig::ConstantParams(const SparseModel& model, int c) const {
  std::vector<int> constant;
  for (int k = 0; k < model.cameras[c].info().num_params(); ++k) {
    if (!std::binary_search(refined[c].begin(), refined[c].end(), k)) constant.push_back(k);
  }
  return constant;
}

std::string BundleConfig::Describe(const SparseModel& model, int num_gps, int num_gcp, bool offset_estimated) const {
  std::ostringstream out;
  if (gauge == BundleGauge::kPriors) {
    out << "datum from priors (" << num_gps << " GPS, " << num_gcp << " GCP); no parameter held fixed";
    if (offset_estimated) out << "; GPS offset estimated, translation from the GCPs";
    return out.str();
  }
  if (gauge == BundleGauge::kHeldImages) {
    out << std::count(held.begin(), held.end(), 1) << " images held fixed (a local adjustment); they hold the datum";
    return out.str();
  }
  if (image_a < 0) return "";
  const std::string a = model.images[image_a].name;
  const std::string b = image_b >= 0 ? model.images[image_b].name : "";
  if (prior_positions.empty()) {
    out << "no priors: pose of image '" << a << "' held"
        << (gauge == BundleGauge::kFreeNetwork ? " (restored exactly after a free-network solve)" : " fixed")
        << "; scale held by the baseline '" << a << "'-'" << b
        << "' (restored exactly after the solve, reprojection being blind to scale)";
  } else {
    out << "priors too few or collinear (" << prior_positions.size() << "): rotation of image '" << a
        << "' held fixed";
    if (restore_scale) out << ", baseline '" << a << "'-'" << b << "' holds the scale";
  }
  return out.str();
}

BundleConfig ConfigureBundle(const SparseModel& model, const BundleOptions& options) {
  BundleConfig config;
  const auto per_point = model.ObservationsPerPoint();
  const size_t num_images = model.images.size();
  const auto use_point = [&](int index) {
    const Point& point = model.points[index];
    if (point.role == PointRole::kCheck) return options.check_points_in_bundle && per_point[index] >= 2;
    const bool anchored = point.role == PointRole::kControl && point.prior && options.use_gcp_priors;
    return per_point[index] >= 2 || (anchored && per_point[index] >= 1);
  };

  // Which images, camera groups and points take part.
  config.image_used.assign(num_images, 0);
  config.camera_used.assign(model.cameras.size(), 0);
  config.point_used.assign(model.points.size(), 0);
  for (const Observation& obs : model.observations) {
    const Image& image = model.images[obs.image];
    if (!image.registered || !use_point(obs.point)) continue;
    config.image_used[obs.image] = 1;
    config.camera_used[image.camera] = 1;
    config.point_used[obs.point] = 1;
    ++config.num_observations;
  }
  config.images_of_camera.assign(model.cameras.size(), 0);
  for (size_t i = 0; i < num_images; ++i) {
    if (!config.image_used[i]) continue;
    ++config.num_images;
    ++config.images_of_camera[model.images[i].camera];
  }
  for (size_t p = 0; p < model.points.size(); ++p) {
    config.num_points += config.point_used[p];
    if (model.points[p].role == PointRole::kTie && per_point[p] == 1) ++config.skipped_points;
  }

  // Priors and the gauge.
  for (size_t i = 0; i < num_images; ++i) {
    if (options.use_gps_priors && config.image_used[i] && model.images[i].gps_prior) {
      config.prior_positions.push_back(model.images[i].gps_prior->position);
    }
  }
  for (size_t p = 0; p < model.points.size(); ++p) {
    const Point& point = model.points[p];
    if (options.use_gcp_priors && config.point_used[p] && point.role == PointRole::kControl && point.prior) {
      config.prior_positions.push_back(point.prior->position);
    }
  }
  // Images the caller holds (only those taking part).
  config.held.assign(num_images, 0);
  std::vector<Eigen::Vector3d> held_centres;
  for (size_t i = 0; i < num_images && i < options.held_poses.size(); ++i) {
    if (!options.held_poses[i] || !config.image_used[i]) continue;
    config.held[i] = 1;
    held_centres.push_back(model.images[i].pose.centre_in_world);
  }
  const bool held_fix_datum = std::any_of(held_centres.begin(), held_centres.end(), [&](const Eigen::Vector3d& c) {
    return (c - held_centres[0]).norm() > 1e-9 * (1.0 + c.norm());
  });
  if (PriorsFixDatum(config.prior_positions)) {
    config.gauge = BundleGauge::kPriors;
  } else if (held_fix_datum) {
    config.gauge = BundleGauge::kHeldImages;
  } else {
    for (size_t i = 0; i < num_images && config.image_a < 0; ++i) {
      if (config.image_used[i]) config.image_a = static_cast<int>(i);
    }
    if (config.image_a >= 0) {
      const Eigen::Vector3d& ca = model.images[config.image_a].pose.centre_in_world;
      for (size_t i = 0; i < num_images; ++i) {
        if (!config.image_used[i] || static_cast<int>(i) == config.image_a) continue;
        const double len = (model.images[i].pose.centre_in_world - ca).norm();
        if (len > config.baseline_m) {
          config.baseline_m = len;
          config.image_b = static_cast<int>(i);
        }
      }
    }
    const bool a_own_group =
        config.image_a >= 0 && config.images_of_camera[model.images[config.image_a].camera] == 1;
    if (config.prior_positions.empty()) {
      config.gauge = a_own_group ? BundleGauge::kFreeNetwork : BundleGauge::kFixedImage;
    } else {
      config.gauge = BundleGauge::kHeldRotation;
    }
    bool distinct = false;
    for (const auto& p : config.prior_positions) distinct |= (p - config.prior_positions[0]).norm() > 1e-6;
    config.restore_scale = !distinct;
  }

  // The intrinsics that vary, per camera group.
  config.refined.resize(model.cameras.size());
  for (size_t c = 0; c < model.cameras.size(); ++c) {
    std::vector<int>& refined = config.refined[c];
    refined = RefinedParams(model.cameras[c], options);
    if (config.images_of_camera[c] < options.min_images_to_refine_intrinsics && !refined.empty()) {
      refined = model.cameras[c].info().focal_params;
    }
    for (const auto& [camera, param] : options.held_params) {
      if (camera == static_cast<int>(c)) refined.erase(std::remove(refined.begin(), refined.end(), param), refined.end());
    }
  }

  // Images whose pose and intrinsics are one block.
  config.merged.assign(num_images, 0);
  for (size_t i = 0; i < num_images; ++i) {
    if (!config.image_used[i]) continue;
    const Image& image = model.images[i];
    config.merged[i] = config.images_of_camera[image.camera] == 1 && !config.refined[image.camera].empty() &&
                       !(options.use_gps_priors && image.gps_prior) &&
                       !config.HoldsRotationOf(static_cast<int>(i));
  }
  return config;
}

}  // namespace aerotri
