// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/colmap_text.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>
#include <unordered_map>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {
namespace {

constexpr double kPixelShift = 0.5;  // COLMAP centre of top-left pixel

struct Line {
  int number = 0;
  std::vector<std::string> tokens;
};

// Non-empty, non-comment lines of a file, split on whitespace.
std::vector<Line> ReadLines(const std::filesystem::path& path) {
  const std::string text = ReadTextFile(path);
  std::vector<Line> lines;
  std::istringstream in(text);
  std::string raw;
  int number = 0;
  while (std::getline(in, raw)) {
    ++number;
    const size_t first = raw.find_first_not_of(" \t\r");
    if (first == std::string::npos || raw[first] == '#') {
      // images.txt has an (often empty) 2D-point line after every image line:
      // keep empty lines there, which the caller pairs up.
      if (first == std::string::npos && path.filename() == "images.txt") {
        lines.push_back({number, {}});
      }
      continue;
    }
    Line line;
    line.number = number;
    std::istringstream tokens(raw);
    std::string token;
    while (tokens >> token) line.tokens.push_back(token);
    lines.push_back(line);
  }
  return lines;
}

double Number(const std::filesystem::path& path, const Line& line, size_t i, const char* what) {
  if (i >= line.tokens.size()) {
    throw ParseError(path.string(), line.number,
                     std::string("expected ") + what + " in column " + std::to_string(i + 1) +
                         ", but the line has " + std::to_string(line.tokens.size()) + " columns");
  }
  double value = 0.0;
  const std::string& t = line.tokens[i];
  const auto [next, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (ec != std::errc() || next != t.data() + t.size() || !std::isfinite(value)) {
    throw ParseError(path.string(), line.number,
                     std::string("expected a number for ") + what + ", got '" + t + "'");
  }
  return value;
}

long Integer(const std::filesystem::path& path, const Line& line, size_t i, const char* what) {
  const double v = Number(path, line, i, what);
  // Ids, sizes and indices are ints: a value outside their range (1e20 as a
  // camera id) is refused here, before a conversion that would be undefined.
  if (v != std::floor(v) || !(std::abs(v) <= 2147483647.0)) {
    throw ParseError(path.string(), line.number, std::string("expected an integer (at most 2147483647 in magnitude) for ") +
                                                     what + ", got '" + line.tokens[i] + "'");
  }
  return static_cast<long>(v);
}

Camera CameraFromColmap(const std::filesystem::path& path, const Line& line) {
  Camera camera;
  camera.id = static_cast<int>(Integer(path, line, 0, "CAMERA_ID"));
  if (line.tokens.size() < 2) throw ParseError(path.string(), line.number, "expected MODEL");
  const std::string model = line.tokens[1];
  camera.width = static_cast<int>(Integer(path, line, 2, "WIDTH"));
  camera.height = static_cast<int>(Integer(path, line, 3, "HEIGHT"));
  std::vector<double> p;
  for (size_t i = 4; i < line.tokens.size(); ++i) p.push_back(Number(path, line, i, "PARAMS[]"));
  auto need = [&](size_t n) {
    if (p.size() != n) {
      throw ParseError(path.string(), line.number,
                       model + " expects " + std::to_string(n) + " parameters, got " +
                           std::to_string(p.size()));
    }
  };
  auto focal = [&](double fx, double fy) {
    if (std::abs(fx - fy) > 1e-3 * std::max(fx, fy)) {
      throw ParseError(path.string(), line.number,
                       "camera " + std::to_string(camera.id) + ": fx " + std::to_string(fx) +
                           " and fy " + std::to_string(fy) +
                           " differ; aerotri's models have one focal length (square pixels)");
    }
    return 0.5 * (fx + fy);
  };
  auto brown = [&](double f, double cx, double cy, double k1, double k2, double k3, double p1,
                   double p2) {
    camera.model = CameraModelId::kBrown;
    camera.params = {f, cx - kPixelShift, cy - kPixelShift, k1, k2, k3, p1, p2};
  };
  if (model == "SIMPLE_PINHOLE") {
    need(3);
    camera.model = CameraModelId::kPinhole;
    camera.params = {p[0], p[1] - kPixelShift, p[2] - kPixelShift};
  } else if (model == "PINHOLE") {
    need(4);
    camera.model = CameraModelId::kPinhole;
    camera.params = {focal(p[0], p[1]), p[2] - kPixelShift, p[3] - kPixelShift};
  } else if (model == "SIMPLE_RADIAL") {
    need(4);
    brown(p[0], p[1], p[2], p[3], 0, 0, 0, 0);
  } else if (model == "RADIAL") {
    need(5);
    brown(p[0], p[1], p[2], p[3], p[4], 0, 0, 0);
  } else if (model == "OPENCV") {
    need(8);
    brown(focal(p[0], p[1]), p[2], p[3], p[4], p[5], 0, p[6], p[7]);
  } else if (model == "FULL_OPENCV") {
    need(12);
    if (p[9] != 0.0 || p[10] != 0.0 || p[11] != 0.0) {
      throw ParseError(path.string(), line.number,
                       "FULL_OPENCV with rational terms k4..k6 is not supported (expected 0)");
    }
    brown(focal(p[0], p[1]), p[2], p[3], p[4], p[5], p[8], p[6], p[7]);
  } else {
    throw ParseError(path.string(), line.number,
                     "camera model '" + model + "' is not supported; expected SIMPLE_PINHOLE, "
                     "PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV or FULL_OPENCV");
  }
  return camera;
}

std::string CameraToColmap(const Camera& c) {
  std::ostringstream out;
  out << std::setprecision(17) << c.id << " ";
  const auto& p = c.params;
  switch (c.model) {
    case CameraModelId::kPinhole:
      out << "SIMPLE_PINHOLE " << c.width << " " << c.height << " " << p[0] << " "
          << p[1] + kPixelShift << " " << p[2] + kPixelShift;
      break;
    case CameraModelId::kBrown:
      out << "FULL_OPENCV " << c.width << " " << c.height << " " << p[0] << " " << p[0] << " "
          << p[1] + kPixelShift << " " << p[2] + kPixelShift << " " << p[3] << " " << p[4] << " "
          << p[6] << " " << p[7] << " " << p[5] << " 0 0 0";
      break;
    case CameraModelId::kSnavely:
      // Pixels measured from the image centre: principal point at 0 in
      // aerotri is 0.5 in COLMAP's convention.
      out << "RADIAL " << c.width << " " << c.height << " " << p[0] << " " << kPixelShift << " "
          << kPixelShift << " " << p[1] << " " << p[2];
      break;
  }
  return out.str();
}

// rolling_shutter.txt, where it exists: each listed image's motion.
void ReadRollingShutters(const std::filesystem::path& path, const std::unordered_map<long, int>& image_by_id,
                         SparseModel* model) {
  if (!std::filesystem::exists(path)) return;
  for (const Line& line : ReadLines(path)) {
    if (line.tokens.size() < 6) {
      throw ParseError(path.string(), line.number,
                       "expected 'IMAGE_ID READOUT_TIME_S VX VY VZ NAME', got " + std::to_string(line.tokens.size()) +
                           " columns");
    }
    const long id = Integer(path, line, 0, "IMAGE_ID");
    const auto image = image_by_id.find(id);
    if (image == image_by_id.end()) {
      throw ParseError(path.string(), line.number, "refers to image " + std::to_string(id) + ", not in images.txt");
    }
    RollingShutterMotion motion;
    motion.readout_time_s = Number(path, line, 1, "READOUT_TIME_S");
    if (motion.readout_time_s < 0.0 || motion.readout_time_s > 1.0) {
      throw ParseError(path.string(), line.number,
                       "expected a readout time from 0 to 1 s, got " + line.tokens[1]);
    }
    for (int k = 0; k < 3; ++k) motion.velocity[k] = Number(path, line, 2 + k, "VX VY VZ");
    Image& target = model->images[image->second];
    if (target.rolling_shutter) {
      throw ParseError(path.string(), line.number, "image " + std::to_string(id) + " appears twice");
    }
    target.rolling_shutter = motion;
  }
}

}  // namespace

SparseModel ReadColmapText(const std::filesystem::path& dir) {
  for (const char* name : {"cameras.txt", "images.txt", "points3D.txt"}) {
    if (!std::filesystem::exists(dir / name)) {
      throw IoError((dir / name).string(), "missing: a COLMAP text model needs cameras.txt, "
                                           "images.txt and points3D.txt");
    }
  }
  SparseModel model;
  std::unordered_map<long, int> camera_index, image_index, point_index;

  const auto cameras_path = dir / "cameras.txt";
  for (const Line& line : ReadLines(cameras_path)) {
    Camera camera = CameraFromColmap(cameras_path, line);
    if (camera_index.count(camera.id)) {
      throw ParseError(cameras_path.string(), line.number,
                       "camera id " + std::to_string(camera.id) + " appears twice");
    }
    camera_index[camera.id] = static_cast<int>(model.cameras.size());
    model.cameras.push_back(camera);
  }

  // points3D first, so images can refer to them by index.
  const auto points_path = dir / "points3D.txt";
  struct TrackEntry {
    long image_id;
    long point2d_idx;
  };
  std::vector<std::vector<TrackEntry>> tracks;
  std::vector<int> point_lines;
  for (const Line& line : ReadLines(points_path)) {
    Point point;
    const long id = Integer(points_path, line, 0, "POINT3D_ID");
    point.id = static_cast<int>(id);
    for (int k = 0; k < 3; ++k) point.position[k] = Number(points_path, line, 1 + k, "X Y Z");
    for (int k = 0; k < 3; ++k) {
      const long c = Integer(points_path, line, 4 + k, "R G B");
      if (c < 0 || c > 255) {
        throw ParseError(points_path.string(), line.number,
                         "expected a colour in [0, 255], got " + std::to_string(c));
      }
      point.color[k] = static_cast<std::uint8_t>(c);
    }
    Number(points_path, line, 7, "ERROR");
    if ((line.tokens.size() - 8) % 2 != 0) {
      throw ParseError(points_path.string(), line.number,
                       "expected TRACK[] as (IMAGE_ID, POINT2D_IDX) pairs, got an odd count");
    }
    std::vector<TrackEntry> track;
    for (size_t i = 8; i + 1 < line.tokens.size(); i += 2) {
      track.push_back({Integer(points_path, line, i, "IMAGE_ID"),
                       Integer(points_path, line, i + 1, "POINT2D_IDX")});
    }
    if (point_index.count(id)) {
      throw ParseError(points_path.string(), line.number,
                       "point id " + std::to_string(id) + " appears twice");
    }
    point_index[id] = static_cast<int>(model.points.size());
    model.points.push_back(point);
    tracks.push_back(track);
    point_lines.push_back(line.number);
  }

  const auto images_path = dir / "images.txt";
  const std::vector<Line> lines = ReadLines(images_path);
  // (image index, point2d idx) -> observation, for checking tracks.
  std::map<std::pair<int, long>, int> observation_of;
  for (size_t i = 0; i < lines.size(); ++i) {
    const Line& line = lines[i];
    if (line.tokens.empty()) continue;  // stray empty line
    if (line.tokens.size() < 10) {
      throw ParseError(images_path.string(), line.number,
                       "expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', got " +
                           std::to_string(line.tokens.size()) + " columns");
    }
    Image image;
    image.id = static_cast<int>(Integer(images_path, line, 0, "IMAGE_ID"));
    const Eigen::Quaterniond q(Number(images_path, line, 1, "QW"), Number(images_path, line, 2, "QX"),
                               Number(images_path, line, 3, "QY"), Number(images_path, line, 4, "QZ"));
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      throw ParseError(images_path.string(), line.number,
                       "expected a unit quaternion, got norm " + std::to_string(q.norm()));
    }
    const Eigen::Vector3d t(Number(images_path, line, 5, "TX"), Number(images_path, line, 6, "TY"),
                            Number(images_path, line, 7, "TZ"));
    image.pose = Pose::FromRotationTranslation(q, t);
    const long camera_id = Integer(images_path, line, 8, "CAMERA_ID");
    const auto cam = camera_index.find(camera_id);
    if (cam == camera_index.end()) {
      throw ParseError(images_path.string(), line.number,
                       "refers to camera " + std::to_string(camera_id) + ", not in cameras.txt");
    }
    image.camera = cam->second;
    std::string name = line.tokens[9];
    for (size_t k = 10; k < line.tokens.size(); ++k) name += " " + line.tokens[k];
    image.name = name;
    const int index = static_cast<int>(model.images.size());
    model.images.push_back(image);

    // The next line holds POINTS2D[] as (X, Y, POINT3D_ID).
    if (i + 1 >= lines.size()) break;
    const Line& pts = lines[++i];
    if (pts.tokens.size() % 3 != 0) {
      throw ParseError(images_path.string(), pts.number,
                       "expected POINTS2D[] as (X, Y, POINT3D_ID) triples, got " +
                           std::to_string(pts.tokens.size()) + " values");
    }
    for (size_t k = 0; k < pts.tokens.size(); k += 3) {
      const long point_id = Integer(images_path, pts, k + 2, "POINT3D_ID");
      if (point_id < 0) continue;
      const auto p = point_index.find(point_id);
      if (p == point_index.end()) {
        throw ParseError(images_path.string(), pts.number,
                         "2D point " + std::to_string(k / 3) + " refers to 3D point " +
                             std::to_string(point_id) + ", not in points3D.txt");
      }
      Observation obs;
      obs.image = index;
      obs.point = p->second;
      obs.xy = Eigen::Vector2d(Number(images_path, pts, k, "X") - kPixelShift,
                               Number(images_path, pts, k + 1, "Y") - kPixelShift);
      obs.keypoint = static_cast<int>(k / 3);
      observation_of[{index, static_cast<long>(k / 3)}] = static_cast<int>(model.observations.size());
      model.observations.push_back(obs);
    }
  }
  std::unordered_map<long, int> image_by_id;
  for (size_t i = 0; i < model.images.size(); ++i) image_by_id[model.images[i].id] = static_cast<int>(i);
  for (size_t p = 0; p < tracks.size(); ++p) {
    for (const TrackEntry& entry : tracks[p]) {
      const auto img = image_by_id.find(entry.image_id);
      if (img == image_by_id.end() ||
          !observation_of.count({img->second, entry.point2d_idx})) {
        throw ParseError(points_path.string(), point_lines[p],
                         "track entry (" + std::to_string(entry.image_id) + ", " +
                             std::to_string(entry.point2d_idx) +
                             ") has no matching 2D point in images.txt");
      }
    }
  }
  ReadRollingShutters(dir / "rolling_shutter.txt", image_by_id, &model);
  return model;
}

void WriteColmapText(const SparseModel& model, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  WriteFileAtomically(dir / "cameras.txt", [&](std::ostream& out) {
    out << "# Camera list with one line of data per camera:\n"
           "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
           "# Number of cameras: "
        << model.cameras.size() << "\n";
    for (const Camera& c : model.cameras) out << CameraToColmap(c) << "\n";
  });
  // Per image: its observations in keypoint order, numbered 0..n-1.
  std::vector<std::vector<int>> obs_of_image(model.images.size());
  for (size_t o = 0; o < model.observations.size(); ++o) {
    obs_of_image[model.observations[o].image].push_back(static_cast<int>(o));
  }
  std::vector<std::pair<int, int>> point2d_of(model.observations.size());  // (image id, idx)
  WriteFileAtomically(dir / "images.txt", [&](std::ostream& out) {
    out << "# Image list with two lines of data per image:\n"
           "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
           "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
           "# Number of images: "
        << model.images.size() << "\n"
        << std::setprecision(17);
    for (size_t i = 0; i < model.images.size(); ++i) {
      const Image& image = model.images[i];
      const Eigen::Quaterniond& q = image.pose.cam_from_world;
      const Eigen::Vector3d t = image.pose.Translation();
      out << image.id << " " << q.w() << " " << q.x() << " " << q.y() << " " << q.z() << " "
          << t.x() << " " << t.y() << " " << t.z() << " " << model.cameras[image.camera].id << " "
          << image.name << "\n";
      int idx = 0;
      bool first = true;
      for (int o : obs_of_image[i]) {
        const Observation& obs = model.observations[o];
        out << (first ? "" : " ") << obs.xy.x() + kPixelShift << " " << obs.xy.y() + kPixelShift
            << " " << model.points[obs.point].id;
        point2d_of[o] = {image.id, idx++};
        first = false;
      }
      out << "\n";
    }
  });
  std::vector<std::vector<int>> obs_of_point(model.points.size());
  for (size_t o = 0; o < model.observations.size(); ++o) {
    obs_of_point[model.observations[o].point].push_back(static_cast<int>(o));
  }
  WriteFileAtomically(dir / "points3D.txt", [&](std::ostream& out) {
    out << "# 3D point list with one line of data per point:\n"
           "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
           "# Number of points: "
        << model.points.size() << "\n"
        << std::setprecision(17);
    for (size_t p = 0; p < model.points.size(); ++p) {
      const Point& point = model.points[p];
      double err = 0.0;
      for (int o : obs_of_point[p]) {
        const Observation& obs = model.observations[o];
        const Image& image = model.images[obs.image];
        err += (model.cameras[image.camera].ImageFromCamera(image.pose.CamFromWorld(point.position)) -
                obs.xy)
                   .norm();
      }
      if (!obs_of_point[p].empty()) err /= static_cast<double>(obs_of_point[p].size());
      out << point.id << " " << point.position.x() << " " << point.position.y() << " "
          << point.position.z() << " " << int(point.color[0]) << " " << int(point.color[1]) << " "
          << int(point.color[2]) << " " << err;
      for (int o : obs_of_point[p]) {
        out << " " << point2d_of[o].first << " " << point2d_of[o].second;
      }
      out << "\n";
    }
  });
  const auto motion_path = dir / "rolling_shutter.txt";
  const bool any_rolling = std::any_of(model.images.begin(), model.images.end(),
                                       [](const Image& image) { return image.rolling_shutter.has_value(); });
  if (!any_rolling) {
    std::filesystem::remove(motion_path);  // an earlier model's motion is not this one's
    return;
  }
  WriteFileAtomically(motion_path, [&](std::ostream& out) {
    out << "# Rolling-shutter photos (aerotri), one line each; the others are global shutters':\n"
           "#   IMAGE_ID, READOUT_TIME_S (first row to last), VX, VY, VZ (camera velocity, m/s, in the model's "
           "frame), NAME\n"
        << std::setprecision(17);
    for (const Image& image : model.images) {
      if (!image.rolling_shutter) continue;
      const Eigen::Vector3d& v = image.rolling_shutter->velocity;
      out << image.id << " " << image.rolling_shutter->readout_time_s << " " << v.x() << " " << v.y() << " " << v.z()
          << " " << image.name << "\n";
    }
  });
}

}  // namespace aerotri
