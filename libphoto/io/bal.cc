// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/bal.h"

#include <Eigen/Geometry>
#include <cmath>
#include <iomanip>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"
#include "libphoto/io/compressed_file.h"
#include "libphoto/io/text_scanner.h"

namespace aerotri {
namespace {

const Eigen::Matrix3d kFlipYZ = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();

Eigen::Matrix3d RotationFromAngleAxis(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-16) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

}  // namespace

SparseModel ReadBalProblem(const std::filesystem::path& path) {
  if (std::filesystem::is_directory(path)) {
    throw IoError(path.string(), "is a folder, expected a BAL problem file (.txt or .txt.bz2)");
  }
  const std::string text = ReadMaybeCompressedFile(path);
  TextScanner in(text, path.string());

  const std::int64_t num_cameras = in.Integer("the number of cameras");
  const std::int64_t num_points = in.Integer("the number of points");
  const std::int64_t num_observations = in.Integer("the number of observations");
  if (num_cameras <= 0 || num_points <= 0 || num_observations <= 0 ||
      num_cameras > 10'000'000 || num_points > 100'000'000 ||
      num_observations > 1'000'000'000) {
    throw ParseError(path.string(), 1,
                     "expected positive counts 'num_cameras num_points num_observations', got " +
                         std::to_string(num_cameras) + " " + std::to_string(num_points) + " " +
                         std::to_string(num_observations));
  }

  // Counts against the bytes that hold them, before any allocation: an
  // observation takes at least 8 characters ("c p x y" and separators), a
  // camera 18 (9 numbers), a point 6 (3 numbers).
  // (Small files go on to the line-by-line errors, which say more.)
  const double needed = 8.0 * num_observations + 18.0 * num_cameras + 6.0 * num_points;
  if (needed > static_cast<double>(text.size()) && needed > 1e6) {
    throw ParseError(path.string(), 1,
                     "the header announces " + std::to_string(num_cameras) + " cameras, " +
                         std::to_string(num_points) + " points and " + std::to_string(num_observations) +
                         " observations, which need at least " + std::to_string(static_cast<long long>(needed)) +
                         " characters; the file has " + std::to_string(text.size()) +
                         " (truncated, or a wrong header)");
  }

  SparseModel model;
  model.observations.resize(num_observations);
  for (std::int64_t i = 0; i < num_observations; ++i) {
    Observation& obs = model.observations[i];
    const std::int64_t camera = in.Integer("an observation's camera index");
    const int line = in.line();
    const std::int64_t point = in.Integer("an observation's point index");
    if (camera < 0 || camera >= num_cameras || point < 0 || point >= num_points) {
      throw ParseError(path.string(), line,
                       "observation " + std::to_string(i) + " refers to camera " +
                           std::to_string(camera) + " / point " + std::to_string(point) +
                           ", expected camera in [0, " + std::to_string(num_cameras) +
                           ") and point in [0, " + std::to_string(num_points) + ")");
    }
    obs.image = static_cast<int>(camera);
    obs.point = static_cast<int>(point);
    obs.xy.x() = in.Double("an observation's x");
    obs.xy.y() = -in.Double("an observation's y");
    if (!obs.xy.allFinite()) {
      throw ParseError(path.string(), in.line(), "observation " + std::to_string(i) +
                                                     " has a non-finite pixel coordinate");
    }
  }

  model.cameras.resize(num_cameras);
  model.images.resize(num_cameras);
  for (std::int64_t c = 0; c < num_cameras; ++c) {
    double v[9];
    int focal_line = 0;
    for (int k = 0; k < 9; ++k) {
      v[k] = in.Double("a camera parameter");
      if (k == 6) focal_line = in.line();
      if (!std::isfinite(v[k])) {
        throw ParseError(path.string(), in.line(),
                         "camera " + std::to_string(c) + " has a non-finite parameter");
      }
    }
    if (!(v[6] > 0.0)) {
      throw ParseError(path.string(), focal_line,
                       "camera " + std::to_string(c) + ": expected a positive focal length, got " +
                           std::to_string(v[6]));
    }
    const Eigen::Matrix3d r_bal = RotationFromAngleAxis(Eigen::Vector3d(v[0], v[1], v[2]));
    const Eigen::Vector3d t_bal(v[3], v[4], v[5]);
    Image& image = model.images[c];
    image.id = static_cast<int>(c);
    image.name = "camera_" + std::to_string(c);
    image.camera = static_cast<int>(c);
    image.pose.cam_from_world = Eigen::Quaterniond(kFlipYZ * r_bal).normalized();
    image.pose.centre_in_world = -(r_bal.transpose() * t_bal);
    Camera& camera = model.cameras[c];
    camera.id = static_cast<int>(c);
    camera.model = CameraModelId::kSnavely;
    camera.params = {v[6], v[7], v[8]};
  }

  model.points.resize(num_points);
  for (std::int64_t p = 0; p < num_points; ++p) {
    Point& point = model.points[p];
    point.id = static_cast<int>(p);
    for (int k = 0; k < 3; ++k) point.position[k] = in.Double("a point coordinate");
    if (!point.position.allFinite()) {
      throw ParseError(path.string(), in.line(),
                       "point " + std::to_string(p) + " has a non-finite coordinate");
    }
  }
  if (!in.AtEnd()) {
    throw ParseError(path.string(), in.line(),
                     "expected the end of the file after " + std::to_string(num_points) +
                         " points, found more data");
  }
  return model;
}

void WriteBalProblem(const SparseModel& model, const std::filesystem::path& path) {
  for (const Camera& camera : model.cameras) {
    if (camera.model != CameraModelId::kSnavely) {
      throw InvalidArgument("BAL output needs SNAVELY cameras; camera " +
                            std::to_string(camera.id) + " is " + camera.info().name);
    }
  }
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << std::setprecision(17);
    out << model.images.size() << " " << model.points.size() << " "
        << model.observations.size() << "\n";
    for (const Observation& obs : model.observations) {
      out << obs.image << " " << obs.point << " " << obs.xy.x() << " " << -obs.xy.y() << "\n";
    }
    for (const Image& image : model.images) {
      const Eigen::Matrix3d r_bal = kFlipYZ * image.pose.cam_from_world.toRotationMatrix();
      const Eigen::AngleAxisd aa(r_bal);
      const Eigen::Vector3d w = aa.angle() * aa.axis();
      const Eigen::Vector3d t = -(r_bal * image.pose.centre_in_world);
      const Camera& camera = model.cameras[image.camera];
      for (int k = 0; k < 3; ++k) out << w[k] << "\n";
      for (int k = 0; k < 3; ++k) out << t[k] << "\n";
      for (double p : camera.params) out << p << "\n";
    }
    for (const Point& point : model.points) {
      for (int k = 0; k < 3; ++k) out << point.position[k] << "\n";
    }
  });
}

}  // namespace aerotri
