// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/simulate/synthetic_survey.h"

#include <cmath>
#include <random>
#include <string>

#include "libphoto/base/error.h"

namespace aerotri {

double TerrainHeight(double east_m, double north_m, double relief_m) {
  // A few smooth undulations plus a gentle slope: enough relief to make the
  // geometry three-dimensional, smooth enough to be sampled by a DEM.
  return relief_m * (0.45 * std::sin(east_m / 37.0) * std::cos(north_m / 53.0) +
                     0.30 * std::sin((east_m + 2.0 * north_m) / 71.0) +
                     0.25 * std::cos(north_m / 23.0 - east_m / 97.0)) +
         0.02 * east_m;
}

namespace {

Eigen::Quaterniond NadirRotation(double heading_rad, double tilt_x_rad, double tilt_y_rad) {
  // Camera x = east, y = south, z = down for heading 0 (flying east, image
  // top towards north); heading rotates about the up axis.
  Eigen::Matrix3d nadir;
  nadir << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Matrix3d heading =
      Eigen::AngleAxisd(heading_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d tilt =
      (Eigen::AngleAxisd(tilt_x_rad, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(tilt_y_rad, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  // cam_from_world = tilt (in camera) * nadir * heading^T
  return Eigen::Quaterniond(tilt * nadir * heading.transpose()).normalized();
}

}  // namespace

SyntheticSurvey MakeSyntheticSurvey(const SyntheticSurveyOptions& o) {
  if (!(o.area_width_m > 0 && o.area_height_m > 0 && o.flight_height_m > 0) ||
      !(o.forward_overlap > 0 && o.forward_overlap < 1) ||
      !(o.side_overlap > 0 && o.side_overlap < 1) || o.brown_params.size() != 8) {
    throw InvalidArgument("synthetic survey: extents and height must be > 0, overlaps in "
                          "(0, 1), and the Brown camera needs 8 parameters");
  }
  if (!(o.gimbal_pitch_deg >= -135.0 && o.gimbal_pitch_deg <= -45.0)) {
    throw InvalidArgument("synthetic survey: gimbal pitch " + std::to_string(o.gimbal_pitch_deg) +
                          " deg is outside [-135, -45] (-90 looks straight down; a survey camera looks at the ground)");
  }
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  SyntheticSurvey survey;
  SparseModel& truth = survey.truth;
  Camera camera;
  camera.id = 1;
  camera.model = CameraModelId::kBrown;
  camera.width = o.width;
  camera.height = o.height;
  camera.params = o.brown_params;
  truth.cameras.push_back(camera);

  const double f = o.brown_params[0];
  survey.gsd_m = o.flight_height_m / f;
  const double footprint_w = o.width * survey.gsd_m;   // along east (camera x)
  const double footprint_h = o.height * survey.gsd_m;  // along north
  // Strips run east-west; the image's short side (north) spans across strips.
  const double strip_spacing = footprint_h * (1.0 - o.side_overlap);
  const double shot_spacing = footprint_w * (1.0 - o.forward_overlap);
  const int num_strips =
      std::max(2, static_cast<int>(std::ceil(o.area_height_m / strip_spacing)) + 1);
  const int shots = std::max(2, static_cast<int>(std::ceil(o.area_width_m / shot_spacing)) + 1);
  const double deg = M_PI / 180.0;
  int image_id = 1;
  for (int s = 0; s < num_strips; ++s) {
    const double north = -0.5 * o.area_height_m + s * o.area_height_m / (num_strips - 1);
    for (int k = 0; k < shots; ++k) {
      const int kk = (s % 2 == 0) ? k : shots - 1 - k;  // lawn-mower
      const double east = -0.5 * o.area_width_m + kk * o.area_width_m / (shots - 1);
      Image image;
      image.id = image_id;
      char name[32];
      std::snprintf(name, sizeof(name), "IMG_%04d.JPG", image_id);
      image.name = name;
      ++image_id;
      image.camera = 0;
      const double heading = (s % 2 == 0 ? 0.0 : M_PI) + o.attitude_sigma_deg * deg * gauss(rng);
      // A lean towards the image's top (−y) turns the camera about its x axis.
      image.pose.cam_from_world =
          NadirRotation(heading, -(o.gimbal_pitch_deg + 90.0) * deg + o.attitude_sigma_deg * deg * gauss(rng),
                        o.attitude_sigma_deg * deg * gauss(rng));
      image.pose.centre_in_world =
          Eigen::Vector3d(east + 0.5 * gauss(rng), north + 0.5 * gauss(rng),
                          o.flight_height_m + 0.3 * gauss(rng));
      if (o.readout_time_s > 0.0) {
        image.rolling_shutter = RollingShutterMotion{
            o.readout_time_s, Eigen::Vector3d((s % 2 == 0 ? 1.0 : -1.0) * o.flight_speed_mps, 0.0, 0.0)};
      }
      truth.images.push_back(image);
    }
  }

  auto add_point = [&](double e, double n, PointRole role, const std::string& name) {
    Point point;
    point.id = static_cast<int>(truth.points.size()) + 1;
    point.position = Eigen::Vector3d(e, n, TerrainHeight(e, n, o.relief_m));
    point.role = role;
    point.name = name;
    const int shade = 60 + static_cast<int>(150 * uniform(rng));
    point.color = {static_cast<std::uint8_t>(shade), static_cast<std::uint8_t>(shade),
                   static_cast<std::uint8_t>(shade)};
    truth.points.push_back(point);
  };
  // Tie points over the ground the photos see: the area, and beyond its
  // northern and southern edges as far as the outer strips lean (oblique).
  const double lean_m = o.flight_height_m * std::tan(std::abs(o.gimbal_pitch_deg + 90.0) * deg);
  for (int i = 0; i < o.num_tie_points; ++i) {
    add_point((uniform(rng) - 0.5) * o.area_width_m * 1.05,
              (uniform(rng) - 0.5) * (o.area_height_m * 1.05 + 2.0 * lean_m), PointRole::kTie, "");
  }
  // Control on a ring around the border and the centre, check points in between
  // (how a surveyor would place them).
  const int nc = o.num_control_points;
  for (int i = 0; i < nc; ++i) {
    const double a = 2.0 * M_PI * i / std::max(1, nc - 1);
    const bool centre = (i == nc - 1);
    add_point(centre ? 0.0 : 0.42 * o.area_width_m * std::cos(a),
              centre ? 0.0 : 0.42 * o.area_height_m * std::sin(a), PointRole::kControl,
              "GCP" + std::to_string(i + 1));
  }
  for (int i = 0; i < o.num_check_points; ++i) {
    const double a = 2.0 * M_PI * (i + 0.5) / std::max(1, o.num_check_points);
    add_point(0.25 * o.area_width_m * std::cos(a), 0.25 * o.area_height_m * std::sin(a),
              PointRole::kCheck, "CHK" + std::to_string(i + 1));
  }

  // Exact observations: every point in front of the camera, inside the lens'
  // field of view (beyond it a polynomial distortion folds back into the
  // frame) and inside the frame.
  const double max_u = 0.6 * o.width / f, max_v = 0.6 * o.height / f;
  for (size_t i = 0; i < truth.images.size(); ++i) {
    const Image& image = truth.images[i];
    for (size_t p = 0; p < truth.points.size(); ++p) {
      const Eigen::Vector3d pc = image.pose.CamFromWorld(truth.points[p].position);
      if (pc.z() <= 1.0 || std::abs(pc.x()) > max_u * pc.z() ||
          std::abs(pc.y()) > max_v * pc.z()) {
        continue;
      }
      const Eigen::Vector2d xy = ProjectIntoImage(camera, image, truth.points[p].position);
      if (xy.x() < 0 || xy.y() < 0 || xy.x() > o.width - 1 || xy.y() > o.height - 1) continue;
      truth.observations.push_back({static_cast<int>(i), static_cast<int>(p), xy, -1});
    }
  }
  // Drop tie points seen fewer than twice (ground points keep their views).
  {
    const auto per_point = truth.ObservationsPerPoint();
    std::vector<char> keep(truth.points.size());
    for (size_t p = 0; p < keep.size(); ++p) keep[p] = truth.points[p].role != PointRole::kTie || per_point[p] >= 2;
    truth.KeepPoints(keep);
  }

  survey.observed = truth;
  for (Observation& obs : survey.observed.observations) {
    obs.xy += o.pixel_noise_px * Eigen::Vector2d(gauss(rng), gauss(rng));
  }
  return survey;
}

}  // namespace aerotri
