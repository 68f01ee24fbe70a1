// SPDX-License-Identifier: BSD-3-Clause
// Dense matching on rendered pairs with known terrain, and the work-sharing
// loop it runs on.
#include "libphoto/dense/dense_stereo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <stdexcept>
#include <thread>
#include <vector>

#include "libphoto/base/error.h"
#include "libphoto/base/parallel.h"
#include "libphoto/simulate/render.h"
#include "libphoto/simulate/synthetic_survey.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

constexpr double kRelief = 12.0;
constexpr double kDeg = M_PI / 180.0;

// A camera at centre whose optical axis is z_axis and whose image x axis is
// x_axis (both in ENU, orthonormal).
Pose Looking(const Eigen::Vector3d& centre, const Eigen::Vector3d& x_axis, const Eigen::Vector3d& z_axis) {
  Eigen::Matrix3d world_from_cam;
  world_from_cam.col(0) = x_axis.normalized();
  world_from_cam.col(2) = z_axis.normalized();
  world_from_cam.col(1) = world_from_cam.col(2).cross(world_from_cam.col(0));
  Pose pose;
  pose.cam_from_world = Eigen::Quaterniond(world_from_cam.transpose());
  pose.centre_in_world = centre;
  return pose;
}

// Two registered images and the terrain points both see (the sparse model
// that dense matching starts from).
SparseModel TwoViewModel(const Pose& a, const Pose& b) {
  SparseModel model;
  model.cameras.push_back(Camera::Create(CameraModelId::kPinhole, 700.0, 800, 600));
  const Camera& cam = model.cameras[0];
  for (const Pose* pose : {&a, &b}) {
    Image image;
    image.id = static_cast<int>(model.images.size()) + 1;
    image.name = image.id == 1 ? "a.png" : "b.png";
    image.pose = *pose;
    model.images.push_back(image);
  }
  for (double e = -60; e <= 60; e += 4) {
    for (double n = -60; n <= 60; n += 4) {
      const Eigen::Vector3d x(e, n, TerrainHeight(e, n, kRelief));
      std::vector<Eigen::Vector2d> seen;
      for (const Image& image : model.images) {
        const Eigen::Vector3d pc = image.pose.CamFromWorld(x);
        if (pc.z() <= 0) break;
        const Eigen::Vector2d xy = cam.ImageFromCamera(pc);
        if (xy.x() < 0 || xy.y() < 0 || xy.x() > cam.width - 1 || xy.y() > cam.height - 1) break;
        seen.push_back(xy);
      }
      if (seen.size() != 2) continue;
      Point p;
      p.id = static_cast<int>(model.points.size()) + 1;
      p.position = x;
      model.points.push_back(p);
      for (int k = 0; k < 2; ++k) {
        model.observations.push_back({k, static_cast<int>(model.points.size()) - 1, seen[k], -1});
      }
    }
  }
  return model;
}

DenseCloud Densify(const SparseModel& model, const std::filesystem::path& dir, DenseSummary* summary) {
  RenderOptions render;
  render.relief_m = kRelief;
  std::map<int, cv::Mat> images;
  for (size_t i = 0; i < model.images.size(); ++i) {
    images[static_cast<int>(i)] = RenderImage(model.cameras[0], model.images[i].pose, render);
  }
  DenseOptions o;
  o.min_views = 1;  // one pair: each image's depth map against the other
  o.work_dir = dir;
  return ComputeDenseCloud(model, [&](int i) { return images.at(i).clone(); }, o, nullptr, summary);
}

// The dense cloud of a two-photo model (each photo's depth map against the
// other), with the number of sparse points the pair started from.
struct PairRun {
  size_t sparse_points = 0;
  DenseSummary summary;
  DenseCloud cloud;
};
PairRun DensifyPair(const Pose& a, const Pose& b) {
  const SparseModel model = TwoViewModel(a, b);
  testing::TempDir dir;
  PairRun run;
  run.sparse_points = model.points.size();
  if (run.sparse_points > 0) run.cloud = Densify(model, dir.path() / "depth", &run.summary);
  return run;
}

// A cloud's east coordinates and height errors against the terrain, each
// sorted (for its extent and error percentiles).
struct SortedCloud {
  std::vector<double> east, error;
};
SortedCloud Sorted(const DenseCloud& cloud) {
  SortedCloud out;
  for (const Eigen::Vector3d& x : cloud.positions) {
    out.east.push_back(x.x());
    out.error.push_back(std::abs(x.z() - TerrainHeight(x.x(), x.y(), kRelief)));
  }
  std::sort(out.east.begin(), out.east.end());
  std::sort(out.error.begin(), out.error.end());
  return out;
}

TEST(Dense, ConvergentPairGivesTheTerrainHeight) {
  // Two cameras 24 m apart at 80 m, each tilted 12 degrees towards the other:
  // the rectified views are centred differently (disparities offset by a few
  // hundred pixels), which depth from disparity must undo.
  const double t = 12.0 * kDeg;
  const Pose a = Looking({-12, 0, 80}, {std::cos(t), 0, std::sin(t)}, {std::sin(t), 0, -std::cos(t)});
  const Pose b = Looking({12, 0, 80}, {std::cos(t), 0, -std::sin(t)}, {-std::sin(t), 0, -std::cos(t)});
  const PairRun run = DensifyPair(a, b);
  ASSERT_GE(run.sparse_points, 100u);
  EXPECT_EQ(run.summary.pairs, 2);
  ASSERT_GT(run.cloud.positions.size(), 50000u);
  std::vector<double> error;
  for (const Eigen::Vector3d& x : run.cloud.positions) {
    error.push_back(std::abs(x.z() - TerrainHeight(x.x(), x.y(), kRelief)));
  }
  std::sort(error.begin(), error.end());
  const double gsd = 80.0 / 700.0;
  // Sub-pixel disparity at 24 m baseline and 80 m range: depth noise of a
  // few centimetres; a wrong disparity offset puts the terrain metres off.
  EXPECT_LT(error[error.size() / 2], 0.5 * gsd);
  EXPECT_LT(error[error.size() * 9 / 10], 2.0 * gsd);
}

TEST(Dense, PairAlongThePhotosYAxisKeepsTheWholeWidthAcrossIt) {
  // Nadir photos 800 x 600 px flown along their y axis (north, 20 m apart at
  // 80 m): rectification turns them by 90 degrees. Their ground footprint
  // across the flight is 80 * 800 / 700 = 91 m wide; a rectified frame of
  // the photos' own size (800 along the baseline, 600 across) kept 69 m of
  // it and lost a band on each side, the block's rim in a survey.
  const Pose a = Looking({0, -10, 80}, {1, 0, 0}, {0, 0, -1});
  const Pose b = Looking({0, 10, 80}, {1, 0, 0}, {0, 0, -1});
  const PairRun run = DensifyPair(a, b);
  ASSERT_GE(run.sparse_points, 100u);
  EXPECT_EQ(run.summary.pairs, 2);
  ASSERT_GT(run.cloud.positions.size(), 50000u);
  const SortedCloud sorted = Sorted(run.cloud);
  const std::vector<double>& east = sorted.east;
  const std::vector<double>& error = sorted.error;
  const double across = east[east.size() * 999 / 1000] - east[east.size() / 1000];
  const double footprint = 80.0 * 800.0 / 700.0;  // at the terrain's mean height 0
  std::printf("across the flight: %.1f m of the %.1f m footprint\n", across, footprint);
  EXPECT_GT(across, 0.9 * footprint);
  EXPECT_LT(across, 1.2 * footprint);  // relief widens it a little, nothing more
  // The margins' black is never matched: the surface stays right to its
  // edges, within a fraction of a pixel of disparity (0.46 m of depth per
  // pixel at this baseline).
  const double per_px = 80.0 * 80.0 / (20.0 * 700.0);
  std::printf("height error: median %.3f m, 99th percentile %.3f m\n", error[error.size() / 2],
              error[error.size() * 99 / 100]);
  EXPECT_LT(error[error.size() / 2], 0.2 * per_px);
  EXPECT_LT(error[error.size() * 99 / 100], 1.0 * per_px);
}

TEST(Dense, PhotosWhoseOnlyNeighbourIsWideAreMatched) {
  // Nadir photos 60 m apart at 80 m (41 degrees: a fixed-wing's sparse
  // return strip): no neighbour at the preferred 3-25 degrees, so the wide
  // one is taken rather than none. Its disparities are some 500 px in
  // 800 px wide photos: the search must start near them, not at 0 in a's
  // own frame, or SGBM leaves no column to match.
  const Pose a = Looking({-30, 0, 80}, {1, 0, 0}, {0, 0, -1});
  const Pose b = Looking({30, 0, 80}, {1, 0, 0}, {0, 0, -1});
  const PairRun run = DensifyPair(a, b);
  ASSERT_GE(run.sparse_points, 30u);
  EXPECT_EQ(run.summary.pairs, 2);
  EXPECT_EQ(run.summary.pairs_failed, 0);
  // The overlap is 80 * 800 / 700 - 60 = 31 m wide: most of it is matched.
  ASSERT_GT(run.cloud.positions.size(), 20000u);
  const SortedCloud sorted = Sorted(run.cloud);
  const std::vector<double>& east = sorted.east;
  const std::vector<double>& error = sorted.error;
  const double width = east[east.size() * 99 / 100] - east[east.size() / 100];
  const double per_px = 80.0 * 80.0 / (60.0 * 700.0);  // depth per pixel of disparity
  std::printf("overlap matched %.1f m wide; height error median %.3f m, 90th percentile %.3f m\n", width,
              error[error.size() / 2], error[error.size() * 9 / 10]);
  EXPECT_GT(width, 0.7 * (80.0 * 800.0 / 700.0 - 60.0));
  EXPECT_LT(error[error.size() / 2], 0.5 * per_px);
  EXPECT_LT(error[error.size() * 9 / 10], 2.0 * per_px);
}

TEST(Dense, PairMovingAlongItsViewIsNotMatched) {
  // Forward motion (a ground-level walk): the epipole lies in the image and
  // rectification would leave nothing to match; the pair is set aside and
  // the cloud is empty, without a crash or a half-matched pair.
  const Eigen::Vector3d view(0, std::cos(45 * kDeg), -std::sin(45 * kDeg));
  const Pose a = Looking({0, -70, 60}, {1, 0, 0}, view);
  const Pose b = Looking({0, -50, 60}, {1, 0, 0}, view);
  const PairRun run = DensifyPair(a, b);
  ASSERT_GE(run.sparse_points, 100u);
  EXPECT_EQ(run.summary.pairs + run.summary.pairs_failed, 0);
  EXPECT_TRUE(run.cloud.positions.empty());
}

// The fusion rules on depth maps of known content (voxel 0.1 m):
//  - two maps on one surface, 0.1 m apart in height (one voxel): they
//    agree, the surface is kept;
//  - a blunder of one map 3 m above where the other map has points: no
//    agreement, dropped;
//  - ground only one map saw (a block's rim): nothing to disagree with, kept;
//  - with single_map_where_alone off, that rim is dropped.
TEST(DenseFusion, AgreementWithinAVoxelAndALoneMapStands) {
  testing::TempDir dir;
  const double res = 0.1;
  std::vector<Eigen::Vector3d> a, b;
  for (double x = 0.05; x < 10.0; x += 0.1) {
    for (double y = 0.05; y < 4.0; y += 0.1) {
      a.emplace_back(x, y, 0.05);         // the surface, whole strip
      if (x < 5.0) b.emplace_back(x, y, 0.15);  // one voxel higher, first half
    }
  }
  for (double x = 1.05; x < 2.0; x += 0.1) b.emplace_back(x, 2.05, 3.05);  // blunder over shared ground
  WriteDepthMap(dir.path() / "a.pts", a, {});
  WriteDepthMap(dir.path() / "b.pts", b, {});
  DenseOptions o;
  DenseSummary summary;
  const DenseCloud cloud = FuseDepthMaps({dir.path() / "a.pts", dir.path() / "b.pts"}, res, o, &summary);
  int shared = 0, rim = 0, blunder = 0;
  for (const Eigen::Vector3d& p : cloud.positions) {
    if (p.z() > 1.0) {
      ++blunder;
    } else if (p.x() < 4.8) {
      ++shared;
    } else if (p.x() > 6.4) {
      ++rim;  // beyond the coarse cells (1.6 m) that b reaches
    }
  }
  EXPECT_EQ(blunder, 0);
  EXPECT_GE(shared, 2 * 48 * 40 * 9 / 10);  // both maps' voxels, nearly all
  EXPECT_GE(rim, 36 * 40 * 9 / 10);
  o.single_map_where_alone = false;
  const DenseCloud strict = FuseDepthMaps({dir.path() / "a.pts", dir.path() / "b.pts"}, res, o, &summary);
  for (const Eigen::Vector3d& p : strict.positions) EXPECT_LT(p.x(), 5.1);
  o.agreement_voxels = 0;
  const DenseCloud exact = FuseDepthMaps({dir.path() / "a.pts", dir.path() / "b.pts"}, res, o, &summary);
  EXPECT_TRUE(exact.positions.empty()) << exact.positions.size();
}

// Depth maps filed by fusion tile (as the dense stage writes them) fuse to
// exactly the cloud of the same maps unfiled, and so do maps filed for
// another grid (read whole): the tile table only saves reading.
TEST(DenseFusion, TiledDepthMapsFuseToTheSameCloud) {
  testing::TempDir dir;
  const double res = 0.05;
  std::vector<Eigen::Vector3d> a, b;
  std::vector<std::array<std::uint8_t, 3>> colours;
  std::uint32_t state = 7;
  auto noise = [&]() {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) / double(1 << 24) - 0.5;
  };
  for (double x = -30.0; x < 45.0; x += 0.06) {   // across tile boundaries at 0 and 25.6 m,
    for (double y = -4.0; y < 30.0; y += (x < 0 ? 0.5 : 0.07)) {  // negative coordinates included
      const double z = 0.3 * std::sin(0.2 * x) + 0.2 * std::cos(0.3 * y);
      a.emplace_back(x + 0.01 * noise(), y + 0.01 * noise(), z + 0.02 * noise());
      b.emplace_back(x + 0.01 * noise(), y + 0.01 * noise(), z + 0.02 * noise());
      colours.push_back({static_cast<std::uint8_t>(x + 100), static_cast<std::uint8_t>(y + 100), 9});
    }
  }
  DenseOptions o;
  o.tile_voxels = 512;  // 25.6 m tiles: several, in both signs
  const std::vector<std::filesystem::path> plain = {dir.path() / "a.pts", dir.path() / "b.pts"};
  const std::vector<std::filesystem::path> tiled = {dir.path() / "a_t.pts", dir.path() / "b_t.pts"};
  const std::vector<std::filesystem::path> other = {dir.path() / "a_o.pts", dir.path() / "b_o.pts"};
  WriteDepthMap(plain[0], a, colours);
  WriteDepthMap(plain[1], b, colours);
  WriteDepthMap(tiled[0], a, colours, res, o.tile_voxels);
  WriteDepthMap(tiled[1], b, colours, res, o.tile_voxels);
  WriteDepthMap(other[0], a, colours, res, 64);
  WriteDepthMap(other[1], b, colours, res, 64);
  DenseSummary s_plain, s_tiled, s_other;
  const DenseCloud c_plain = FuseDepthMaps(plain, res, o, &s_plain);
  const DenseCloud c_tiled = FuseDepthMaps(tiled, res, o, &s_tiled);
  const DenseCloud c_other = FuseDepthMaps(other, res, o, &s_other);
  ASSERT_GT(c_plain.positions.size(), 100000u);
  EXPECT_GE(s_plain.tiles, 6);
  for (const DenseCloud* c : {&c_tiled, &c_other}) {
    ASSERT_EQ(c->positions.size(), c_plain.positions.size());
    for (size_t k = 0; k < c->positions.size(); ++k) {
      ASSERT_EQ(c->positions[k], c_plain.positions[k]) << k;
      ASSERT_EQ(c->colours[k], c_plain.colours[k]) << k;
      ASSERT_EQ(c->views[k], c_plain.views[k]) << k;
    }
  }
  // A file cut short is named, not fused.
  std::filesystem::resize_file(tiled[0], std::filesystem::file_size(tiled[0]) - 100);
  EXPECT_THROW(FuseDepthMaps(tiled, res, o, &s_tiled), IoError);
}

// The dense work in shares, as a split workflow's jobs run it (the depth
// maps in 3 shares, then the fusion in 3): the shares' tiles, in share
// order, are the cloud of one ComputeDenseCloud, point for point.
TEST(DenseShares, DepthAndFusionInSharesGiveTheSameCloudAsOneRun) {
  SyntheticSurveyOptions so;
  so.seed = 5;
  so.area_width_m = 60.0;
  so.area_height_m = 45.0;
  so.flight_height_m = 50.0;
  so.width = 320;
  so.height = 240;
  so.brown_params = {240.0, 161.0, 119.0, -0.08, 0.05, -0.01, 0.0005, -0.0003};
  so.num_tie_points = 1500;
  const SparseModel model = MakeSyntheticSurvey(so).truth;
  ASSERT_GE(model.images.size(), 8u);
  RenderOptions render;
  render.relief_m = so.relief_m;
  std::map<int, cv::Mat> images;
  for (size_t i = 0; i < model.images.size(); ++i) {
    images[static_cast<int>(i)] = RenderImage(model.cameras[model.images[i].camera], model.images[i].pose, render);
  }
  auto load = [&](int i) { return images.at(i).clone(); };
  testing::TempDir dir;
  DenseOptions o;
  o.resolution_m = 0.4;
  o.tile_voxels = 32;  // 12.8 m: several fusion tiles over the block
  o.work_dir = dir.path() / "whole";
  DenseSummary whole_summary;
  const DenseCloud whole = ComputeDenseCloud(model, load, o, nullptr, &whole_summary);
  std::printf("%zu images, %d pairs, %zu points in %d tiles\n", model.images.size(), whole_summary.pairs,
              whole.positions.size(), whole_summary.tiles);
  ASSERT_GT(whole.positions.size(), 10000u);
  ASSERT_GE(whole_summary.tiles, 6);

  o.work_dir = dir.path() / "shared";
  constexpr int kShares = 3;
  DenseSummary depth;
  for (int k = 0; k < kShares; ++k) {
    DenseSummary s;
    ComputeDepthMaps(model, load, o, DenseShare{k, kShares}, nullptr, &s);
    EXPECT_GT(s.pairs, 0) << "share " << k;
    depth.pairs += s.pairs;
    depth.pairs_failed += s.pairs_failed;
    depth.depth_points += s.depth_points;
  }
  EXPECT_EQ(depth.pairs, whole_summary.pairs);
  EXPECT_EQ(depth.pairs_failed, whole_summary.pairs_failed);
  EXPECT_EQ(depth.depth_points, whole_summary.depth_points);
  DenseCloud shared;
  int tiles = 0;
  std::vector<long long> points_of_share;
  for (int k = 0; k < kShares; ++k) {
    DenseSummary s;
    FusedTileSink sink;
    sink.consume = [&](DenseCloud&& part) {
      shared.positions.insert(shared.positions.end(), part.positions.begin(), part.positions.end());
      shared.colours.insert(shared.colours.end(), part.colours.begin(), part.colours.end());
      shared.views.insert(shared.views.end(), part.views.begin(), part.views.end());
    };
    FuseModelDepthMaps(model, o, DenseShare{k, kShares}, nullptr, sink, &s);
    tiles += s.tiles;
    points_of_share.push_back(s.fused_points);
  }
  EXPECT_EQ(tiles, whole_summary.tiles);
  // Balanced by their depth points: no share is empty or holds nearly all.
  for (long long n : points_of_share) {
    EXPECT_GT(n, static_cast<long long>(whole.positions.size()) / (3 * kShares));
    EXPECT_LT(n, static_cast<long long>(whole.positions.size()) * 2 / kShares);
  }
  ASSERT_EQ(shared.positions.size(), whole.positions.size());
  for (size_t k = 0; k < whole.positions.size(); ++k) {
    ASSERT_EQ(shared.positions[k], whole.positions[k]) << k;
    ASSERT_EQ(shared.colours[k], whole.colours[k]) << k;
  }
  EXPECT_THROW(ComputeDepthMaps(model, load, o, DenseShare{3, 3}, nullptr, nullptr), InvalidArgument);
}

TEST(ParallelFor, RunsEveryIndexOnce) {
  std::vector<std::atomic<int>> hits(1000);
  ParallelFor(hits.size(), 2, [&](size_t k) { ++hits[k]; });
  for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
  ParallelFor(0, 2, [&](size_t) { FAIL() << "no index to run"; });
}

TEST(ParallelFor, AWorkerFailureReachesTheCaller) {
  // Thrown in whichever thread draws index 7: rethrown here, not std::terminate.
  std::atomic<int> ran{0};
  EXPECT_THROW(ParallelFor(100, 2,
                           [&](size_t k) {
                             ++ran;
                             std::this_thread::sleep_for(std::chrono::milliseconds(1));
                             if (k == 7) throw IoError("x.jpg", "cannot decode");
                           }),
               IoError);
  EXPECT_LT(ran.load(), 100);  // the hand-out stopped
}

}  // namespace
}  // namespace aerotri
