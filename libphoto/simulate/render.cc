// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/simulate/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "libphoto/base/parallel.h"
#include "libphoto/simulate/synthetic_survey.h"

namespace aerotri {
namespace {

// Integer hash to [0, 1) (a 2D variant of the PCG output permutation).
double Hash(std::int64_t x, std::int64_t y, std::uint32_t salt) {
  std::uint64_t h = static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15ULL ^
                    (static_cast<std::uint64_t>(y) + 0x632BE59BD9B4E019ULL + salt) * 0xC2B2AE3D27D4EB4FULL;
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ULL;
  h ^= h >> 32;
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

double Smooth(double t) { return t * t * (3.0 - 2.0 * t); }

// Value noise in [0, 1] with the given wavelength (m).
double ValueNoise(double x, double y, double wavelength, std::uint32_t salt) {
  const double fx = x / wavelength, fy = y / wavelength;
  const double x0 = std::floor(fx), y0 = std::floor(fy);
  const double tx = Smooth(fx - x0), ty = Smooth(fy - y0);
  const auto ix = static_cast<std::int64_t>(x0), iy = static_cast<std::int64_t>(y0);
  const double a = Hash(ix, iy, salt), b = Hash(ix + 1, iy, salt);
  const double c = Hash(ix, iy + 1, salt), d = Hash(ix + 1, iy + 1, salt);
  return (a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty;
}

// Farmland. Fields on a 60 m grid with wavy borders; each is bare tilled
// soil (one in five) or a crop in rows along east or north (a little
// rotated), 0.6-0.9 m apart, of plants set at a regular spacing along the
// row (0.25-0.35 m, a few centimetres of jitter); tramlines every 18 m. What
// is unique is little: the plants' jitter and the fields' borders.
Eigen::Vector3d CropRowAlbedo(double e, double n) {
  const double we = e + 8.0 * (ValueNoise(e, n, 30.0, 401) - 0.5);
  const double wn = n + 8.0 * (ValueNoise(e, n, 30.0, 402) - 0.5);
  const auto fi = static_cast<std::int64_t>(std::floor(we / 60.0));
  const auto fj = static_cast<std::int64_t>(std::floor(wn / 60.0));
  const Eigen::Vector3d soil = Eigen::Vector3d(0.52, 0.42, 0.30) * (0.85 + 0.3 * Hash(fi, fj, 403));
  const double light = 0.9 + 0.2 * ValueNoise(e, n, 25.0, 404);
  if (Hash(fi, fj, 405) < 0.2) {  // bare tilled soil: furrows 0.3 m apart
    const double furrow = 0.5 + 0.5 * std::sin(2.0 * M_PI * e / 0.3);
    const double clods = ValueNoise(e, n, 0.2, 406);
    return (soil * light * (0.85 + 0.1 * furrow + 0.08 * clods)).cwiseMin(1.0);
  }
  const double angle = (Hash(fi, fj, 407) < 0.5 ? 0.0 : 0.5 * M_PI) + 0.1 * (Hash(fi, fj, 408) - 0.5);
  const double row_spacing = 0.6 + 0.3 * Hash(fi, fj, 409);
  const double plant_spacing = 0.25 + 0.1 * Hash(fi, fj, 410);
  const double across = e * std::cos(angle) + n * std::sin(angle);
  const double along = -e * std::sin(angle) + n * std::cos(angle);
  if (std::abs(std::remainder(across, 18.0)) < 0.25) return soil * light * 0.9;  // tramline
  // The nearest plant: its row, its slot along the row, its jitter.
  const double row = std::round(across / row_spacing);
  const double shifted = along + 0.5 * plant_spacing * row;  // rows staggered
  const double slot = std::round(shifted / plant_spacing);
  const auto r = static_cast<std::int64_t>(row), k = static_cast<std::int64_t>(slot);
  const double du = across - row * row_spacing - 0.04 * (Hash(r, k, 411) - 0.5);
  const double dv = shifted - slot * plant_spacing - 0.04 * (Hash(r, k, 412) - 0.5);
  const double radius = (0.35 + 0.1 * Hash(fi, fj, 413)) * std::min(row_spacing, 2.0 * plant_spacing) *
                        (0.85 + 0.3 * Hash(r, k, 414));
  const double d2 = (du * du + dv * dv) / (radius * radius);
  const double canopy = std::clamp((1.0 - d2) / 0.3, 0.0, 1.0);
  const Eigen::Vector3d leaf = Eigen::Vector3d(0.22, 0.42, 0.12) * (0.85 + 0.3 * Hash(fi, fj, 415));
  return ((1.0 - canopy) * soil + canopy * leaf) * light;
}

}  // namespace

Eigen::Vector3d GroundAlbedo(double e, double n, const std::vector<GroundTarget>& targets, GroundCover cover) {
  for (const GroundTarget& t : targets) {
    const double dx = e - t.east_north.x(), dy = n - t.east_north.y();
    const double half = 0.5 * t.size_m;
    if (std::abs(dx) <= half && std::abs(dy) <= half) {
      const Eigen::Vector3d white(0.95, 0.95, 0.95), black(0.05, 0.05, 0.05);
      if (t.pattern == TargetPattern::kCross) {
        // Bars 0.15 of the side wide, reaching 0.85 of the way to the edge.
        const bool bar = (std::abs(dx) < 0.15 * half && std::abs(dy) < 0.85 * half) ||
                         (std::abs(dy) < 0.15 * half && std::abs(dx) < 0.85 * half);
        return bar ? white : black;
      }
      if (t.pattern == TargetPattern::kBullseye) {
        const double r = std::hypot(dx, dy);
        return r < 0.7 * half && r >= 0.25 * half ? white : black;
      }
      // A white border frame then a 2x2 checker: the centre is a sharp corner.
      if (std::abs(dx) > 0.8 * half || std::abs(dy) > 0.8 * half) return white;
      return ((dx >= 0) == (dy >= 0)) ? Eigen::Vector3d(0.05, 0.05, 0.05)
                                      : Eigen::Vector3d(0.95, 0.95, 0.95);
    }
  }
  if (cover == GroundCover::kCropRows) return CropRowAlbedo(e, n);
  // Fields and soil at large scale, detail at every scale below.
  const double field = ValueNoise(e, n, 40.0, 1);
  const double moisture = ValueNoise(e, n, 17.0, 2);
  Eigen::Vector3d base = (1.0 - field) * Eigen::Vector3d(0.32, 0.45, 0.18) +  // grass
                         field * Eigen::Vector3d(0.55, 0.45, 0.32);            // soil
  base *= 0.75 + 0.5 * moisture;
  double detail = 0.0, weight = 0.0;
  double amp = 1.0;
  for (double w = 6.4; w >= 0.1; w *= 0.5) {
    detail += amp * ValueNoise(e, n, w, 10 + static_cast<std::uint32_t>(w * 100));
    weight += amp;
    amp *= 0.8;
  }
  detail /= weight;  // ~[0.2, 0.8]
  // Scattered stones: dark or bright blobs ~0.3-0.8 m on a jittered 2.5 m grid.
  const double cell = 2.5;
  const auto cx = static_cast<std::int64_t>(std::floor(e / cell));
  const auto cy = static_cast<std::int64_t>(std::floor(n / cell));
  double blob = 0.0;
  for (std::int64_t j = cy - 1; j <= cy + 1; ++j) {
    for (std::int64_t i = cx - 1; i <= cx + 1; ++i) {
      if (Hash(i, j, 77) > 0.55) continue;
      const double px = (i + Hash(i, j, 78)) * cell, py = (j + Hash(i, j, 79)) * cell;
      const double r = 0.15 + 0.3 * Hash(i, j, 80);
      const double d2 = ((e - px) * (e - px) + (n - py) * (n - py)) / (r * r);
      if (d2 < 1.0) blob += (Hash(i, j, 81) > 0.5 ? 0.5 : -0.5) * (1.0 - d2);
    }
  }
  const double shade = std::clamp(0.35 + 1.1 * detail + blob, 0.05, 1.6);
  return (base * shade).cwiseMin(1.0).cwiseMax(0.0);
}

std::optional<Eigen::Vector3d> IntersectTerrain(const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                                                double relief_m) {
  if (d.z() >= -1e-6) return std::nullopt;
  double z = TerrainHeight(c.x(), c.y(), relief_m);
  Eigen::Vector3d x = c;
  for (int it = 0; it < 30; ++it) {
    const double t = (z - c.z()) / d.z();
    x = c + t * d;
    const double z_new = TerrainHeight(x.x(), x.y(), relief_m);
    if (std::abs(z_new - z) < 1e-5) return Eigen::Vector3d(x.x(), x.y(), z_new);
    z = z_new;
  }
  return std::nullopt;
}

double BoxBuilding::RoofHeight(double relief_m) const {
  return TerrainHeight(centre.x(), centre.y(), relief_m) + height_m;
}

namespace {

// Roof: red-brown tiles with texture at every scale (so that matching finds
// points on it); walls: grey render with streaks.
Eigen::Vector3d RoofAlbedo(double e, double n) {
  const double tiles = 0.8 + 0.2 * std::sin(n * 2.0 * M_PI / 0.6);
  const double detail = 0.5 * ValueNoise(e, n, 0.3, 201) + 0.3 * ValueNoise(e, n, 1.1, 202) + 0.2 * ValueNoise(e, n, 3.0, 203);
  return (Eigen::Vector3d(0.62, 0.30, 0.22) * tiles * (0.6 + 0.8 * detail)).cwiseMin(1.0);
}

Eigen::Vector3d WallAlbedo(double along, double z) {
  const double detail = 0.6 * ValueNoise(along, z, 0.4, 301) + 0.4 * ValueNoise(along, z, 1.5, 302);
  return Eigen::Vector3d(0.6, 0.6, 0.58) * (0.6 + 0.7 * detail);
}

}  // namespace

double SceneHeight(double e, double n, double relief_m, const std::vector<BoxBuilding>& buildings) {
  for (const BoxBuilding& b : buildings) {
    if (b.Contains(e, n)) return b.RoofHeight(relief_m);
  }
  return TerrainHeight(e, n, relief_m);
}

Eigen::Vector3d SceneAlbedoFromAbove(double e, double n, const std::vector<GroundTarget>& targets,
                                     const std::vector<BoxBuilding>& buildings, GroundCover cover) {
  for (const BoxBuilding& b : buildings) {
    if (b.Contains(e, n)) return RoofAlbedo(e, n);
  }
  return GroundAlbedo(e, n, targets, cover);
}

namespace {

// Whether (east, north) lies on a target or within a tenth of its side of it.
bool NearTarget(double e, double n, const std::vector<GroundTarget>& targets) {
  for (const GroundTarget& t : targets) {
    const double reach = 0.6 * t.size_m;
    if (std::abs(e - t.east_north.x()) <= reach && std::abs(n - t.east_north.y()) <= reach) return true;
  }
  return false;
}

// The colour where a ray first meets the scene (terrain or a building), or
// nothing when it misses; *near_target: the ray meets the ground near a
// target (where the pixel is sampled finer).
std::optional<Eigen::Vector3d> TraceScene(const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                                          const RenderOptions& o, bool* near_target = nullptr) {
  const auto ground = IntersectTerrain(c, d, o.relief_m);
  double t_best = ground ? (*ground - c).dot(d) / d.squaredNorm() : std::numeric_limits<double>::infinity();
  std::optional<Eigen::Vector3d> colour;
  if (ground) colour = GroundAlbedo(ground->x(), ground->y(), o.targets, o.cover);
  if (ground && near_target && NearTarget(ground->x(), ground->y(), o.targets)) *near_target = true;
  for (const BoxBuilding& b : o.buildings) {
    const double roof = b.RoofHeight(o.relief_m);
    const Eigen::Vector3d lo(b.centre.x() - b.half_size.x(), b.centre.y() - b.half_size.y(), roof - b.height_m - 50.0);
    const Eigen::Vector3d hi(b.centre.x() + b.half_size.x(), b.centre.y() + b.half_size.y(), roof);
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    int axis = -1;
    for (int k = 0; k < 3; ++k) {
      if (std::abs(d[k]) < 1e-12) {
        if (c[k] < lo[k] || c[k] > hi[k]) t0 = t1 + 1.0;
        continue;
      }
      double a = (lo[k] - c[k]) / d[k], z = (hi[k] - c[k]) / d[k];
      if (a > z) std::swap(a, z);
      if (a > t0) t0 = a, axis = k;
      t1 = std::min(t1, z);
    }
    if (axis < 0 || t0 > t1 || t0 >= t_best) continue;
    t_best = t0;
    const Eigen::Vector3d p = c + t0 * d;
    colour = axis == 2 ? RoofAlbedo(p.x(), p.y()) : WallAlbedo(axis == 0 ? p.y() : p.x(), p.z());
  }
  return colour;
}

}  // namespace

cv::Mat RenderImage(const Camera& camera, const Pose& pose, const RenderOptions& options) {
  cv::Mat image(camera.height, camera.width, CV_8UC3);
  const int ss = std::max(1, options.supersample);
  const Eigen::Matrix3d world_from_cam = pose.cam_from_world.conjugate().toRotationMatrix();
  const unsigned threads = ThreadCount(options.num_threads);
  auto render_rows = [&](int first, int step) {
    std::mt19937 rng(options.seed * 7919u + first);
    std::normal_distribution<double> noise(0.0, options.noise_dn);
    for (int y = first; y < camera.height; y += step) {
      for (int x = 0; x < camera.width; ++x) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int n = 0;
        bool near_target = false;
        // A pixel near a target is sampled 8 x 8: with 2 x 2, an edge along a
        // pixel row has three shades, and the targets' true centres (the
        // marking tests' truth) would be rendered up to a quarter pixel off.
        for (int pass = 0, grid = ss; pass < 2; ++pass, grid = std::max(ss, options.target_supersample)) {
          if (pass == 1) {
            if (!near_target || grid == ss) break;
            sum.setZero();
            n = 0;
          }
          for (int sy = 0; sy < grid; ++sy) {
            for (int sx = 0; sx < grid; ++sx) {
              const Eigen::Vector2d xy(x - 0.5 + (sx + 0.5) / grid, y - 0.5 + (sy + 0.5) / grid);
              const auto ray = camera.RayFromImage(xy);
              if (!ray) continue;
              const Eigen::Vector3d centre =
                  options.rolling_shutter
                      ? Eigen::Vector3d(pose.centre_in_world + options.rolling_shutter->CentreShift(xy.y(), camera.height))
                      : pose.centre_in_world;
              const auto colour = TraceScene(centre, world_from_cam * *ray, options, &near_target);
              if (!colour) continue;
              sum += *colour;
              ++n;
            }
          }
        }
        const Eigen::Vector3d rgb = n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d(0.6, 0.7, 0.9);
        cv::Vec3b& px = image.at<cv::Vec3b>(y, x);
        for (int k = 0; k < 3; ++k) {
          px[2 - k] = cv::saturate_cast<std::uint8_t>(255.0 * rgb[k] + noise(rng));
        }
      }
    }
  };
  // Thread t renders rows t, t + threads, ...; each with its own noise stream.
  ParallelFor(threads, threads, [&](size_t t) { render_rows(static_cast<int>(t), static_cast<int>(threads)); });
  return image;
}

}  // namespace aerotri
