// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/simulate/synthetic_georef.h"

#include <random>

#include "georef/crs.h"

namespace aerotri {

SyntheticGeoref MakeSyntheticGeoref(const SyntheticSurveyOptions& survey_options,
                                    const SyntheticGeorefOptions& options) {
  SyntheticGeoref out;
  out.survey = MakeSyntheticSurvey(survey_options);
  const LocalFrame frame(options.origin);
  const Crs crs = Crs::FromString(options.crs);
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> g(0.0, 1.0);

  const size_t num_images = out.survey.truth.images.size();
  for (size_t i = 0; i < num_images; ++i) {
    const Image& image = out.survey.truth.images[i];
    const double along = num_images > 1 ? static_cast<double>(i) / static_cast<double>(num_images - 1) : 0.0;
    const Eigen::Vector3d noisy =
        image.pose.centre_in_world + along * options.gps_drift_m +
        Eigen::Vector3d(options.gps_sigma_h_m * g(rng), options.gps_sigma_h_m * g(rng),
                        options.gps_sigma_v_m * g(rng));
    GpsFix fix;
    fix.time_s = options.start_time_s + options.seconds_per_photo * static_cast<double>(i);
    fix.position = frame.GeodeticFromEnu(noisy);
    fix.sigma_h_m = options.gps_sigma_h_m;
    fix.sigma_v_m = options.gps_sigma_v_m;
    fix.source = "simulated";
    out.gps[image.name] = fix;
  }

  out.control.crs = out.checks.crs = options.crs;
  out.control.path = "simulated_gcp_list.txt";
  out.checks.path = "simulated_checkpoints.txt";
  const SparseModel& observed = out.survey.observed;
  std::vector<int> keep(observed.points.size(), -1);
  for (size_t p = 0; p < observed.points.size(); ++p) {
    const Point& point = observed.points[p];
    if (point.role == PointRole::kTie) continue;
    GroundPoint ground;
    ground.name = point.name;
    const Eigen::Vector3d surveyed =
        point.position + options.gcp_noise_m * Eigen::Vector3d(g(rng), g(rng), g(rng));
    ground.xyz = crs.FromGeodetic(frame.GeodeticFromEnu(surveyed));
    for (const Observation& obs : observed.observations) {
      if (obs.point == static_cast<int>(p)) {
        ground.measurements.push_back({observed.images[obs.image].name, obs.xy, 0});
      }
    }
    (point.role == PointRole::kControl ? out.control : out.checks).points.push_back(ground);
  }

  // The tie-point model alone.
  SparseModel& m = out.tie_model;
  m.cameras = observed.cameras;
  m.images = observed.images;
  for (size_t p = 0; p < observed.points.size(); ++p) {
    if (observed.points[p].role != PointRole::kTie) continue;
    keep[p] = static_cast<int>(m.points.size());
    m.points.push_back(observed.points[p]);
  }
  for (Observation obs : observed.observations) {
    if (keep[obs.point] < 0) continue;
    obs.point = keep[obs.point];
    m.observations.push_back(obs);
  }
  return out;
}

}  // namespace aerotri
