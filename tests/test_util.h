// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Small helpers shared by the test executables.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include "libphoto/model/sparse_model.h"

namespace aerotri::testing {

// The shared real data folder (../shared/data beside the checkout), or empty
// when it is absent: tests that need it call GTEST_SKIP().
inline std::filesystem::path SharedData(const std::string& sub) {
  const std::filesystem::path path = std::filesystem::path(AEROTRI_SHARED_DATA) / sub;
  return std::filesystem::exists(path) ? path : std::filesystem::path();
}

// A fresh temporary folder per test, removed by the destructor.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("aerotri_") + (info ? info->test_suite_name() : "t") + "_" +
                       (info ? info->name() : "x") + "_" + std::to_string(::getpid());
    for (char& c : name) {
      if (c == '/') c = '_';
    }
    path_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// A GPS prior on every image: its true centre plus Gaussian noise of sigma_h
// east and north and sigma_v up, stated with those sigmas.
inline void AddGpsPriors(SparseModel* model, const SparseModel& truth, std::mt19937& rng, double sigma_h,
                         double sigma_v) {
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < model->images.size(); ++i) {
    PositionPrior prior;
    prior.position = truth.images[i].pose.centre_in_world +
                     Eigen::Vector3d(sigma_h * g(rng), sigma_h * g(rng), sigma_v * g(rng));
    prior.sigma_h_m = sigma_h;
    prior.sigma_v_m = sigma_v;
    model->images[i].gps_prior = prior;
  }
}

// Perturbs every pose, point and the intrinsics' focal length: the initial
// guess of an adjustment test.
inline void Perturb(SparseModel* model, std::mt19937& rng, double centre_m, double rotation_deg,
                    double point_m, double focal_rel) {
  std::normal_distribution<double> g(0.0, 1.0);
  for (Image& image : model->images) {
    image.pose.centre_in_world += centre_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
    const Eigen::Vector3d axis = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    image.pose.cam_from_world =
        (image.pose.cam_from_world *
         Eigen::Quaterniond(Eigen::AngleAxisd(rotation_deg * M_PI / 180.0 * g(rng), axis)))
            .normalized();
  }
  for (Point& point : model->points) {
    point.position += point_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
  }
  for (Camera& camera : model->cameras) {
    for (int i : camera.info().focal_params) camera.params[i] *= 1.0 + focal_rel;
  }
}

// RMS distance between corresponding points after the best similarity
// (Umeyama) maps a onto b.
inline double AlignedRms(const std::vector<Eigen::Vector3d>& a,
                         const std::vector<Eigen::Vector3d>& b) {
  Eigen::Matrix3Xd ma(3, a.size()), mb(3, b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ma.col(i) = a[i];
    mb.col(i) = b[i];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(ma, mb, true);
  const Eigen::Matrix3Xd mapped = (t.topLeftCorner<3, 3>() * ma).colwise() + t.topRightCorner<3, 1>();
  return std::sqrt((mapped - mb).squaredNorm() / a.size());
}

}  // namespace aerotri::testing
