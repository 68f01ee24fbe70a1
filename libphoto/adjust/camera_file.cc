// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/adjust/camera_file.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "libphoto/base/error.h"

namespace aerotri {
namespace {

std::optional<double> Number(const std::string& text) {
  double v = 0.0;
  const char* begin = text.data() + (!text.empty() && text[0] == '+' ? 1 : 0);
  const auto [end, ec] = std::from_chars(begin, text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace

CameraFile ReadCameraFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw IoError(path.string(), "cannot open the camera file");
  CameraFile file;
  file.path = path.string();
  static const std::vector<std::string> kNames = {"f", "x0", "y0", "cx", "cy", "k1", "k2", "k3", "p1", "p2"};
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string word; words >> word;) w.push_back(word);
    if (w.empty()) continue;
    if (w[0] == "units") {
      if (w.size() != 2 || (w[1] != "mm" && w[1] != "px")) {
        throw ParseError(file.path, number, "expected 'units mm' or 'units px'");
      }
      file.millimetres = w[1] == "mm";
      continue;
    }
    if (w[0] == "pixel_size_mm") {
      const auto v = w.size() == 2 ? Number(w[1]) : std::nullopt;
      if (!v || *v <= 0.0) throw ParseError(file.path, number, "expected a positive pixel size in mm");
      file.pixel_size_mm = *v;
      continue;
    }
    if (w[0] == "width" || w[0] == "height") {
      const auto v = w.size() == 2 ? Number(w[1]) : std::nullopt;
      if (!v || *v < 1.0 || *v != std::floor(*v) || *v > 1e6) {
        throw ParseError(file.path, number, "expected '" + w[0] + " N' with N a whole number of pixels, got '" +
                                                line + "'");
      }
      (w[0] == "width" ? file.width : file.height) = static_cast<int>(*v);
      if (!file.size_line) file.size_line = number;
      continue;
    }
    if (std::find(kNames.begin(), kNames.end(), w[0]) == kNames.end()) {
      throw ParseError(file.path, number, "unknown parameter '" + w[0] +
                                              "'; expected units, pixel_size_mm, width, height, f, x0, y0, cx, cy, "
                                              "k1, k2, k3, p1 or p2");
    }
    CameraFileValue v;
    v.name = w[0];
    v.line = number;
    const auto value = w.size() >= 2 ? Number(w[1]) : std::nullopt;
    if (!value) throw ParseError(file.path, number, "expected a number after '" + w[0] + "'");
    v.value = *value;
    if (w.size() == 3 && w[2] == "fixed") {
      v.fixed = true;
    } else if (w.size() == 4 && w[2] == "sigma") {
      const auto s = Number(w[3]);
      if (!s || *s <= 0.0) throw ParseError(file.path, number, "expected a positive sigma, got '" + w[3] + "'");
      v.sigma = *s;
    } else if (w.size() != 2) {
      throw ParseError(file.path, number, "expected '" + w[0] + " VALUE', '" + w[0] + " VALUE sigma S' or '" + w[0] +
                                              " VALUE fixed'");
    }
    for (const CameraFileValue& other : file.values) {
      if (other.name == v.name) {
        throw ParseError(file.path, number, "'" + v.name + "' is given twice (also on line " +
                                                std::to_string(other.line) + ")");
      }
    }
    file.values.push_back(v);
  }
  for (const CameraFileValue& v : file.values) {
    const bool mm_only = v.name == "x0" || v.name == "y0";
    const bool px_only = v.name == "cx" || v.name == "cy";
    if (file.millimetres && px_only) {
      throw ParseError(file.path, v.line, "'" + v.name + "' is a pixel coordinate; with 'units mm' give x0 / y0");
    }
    if (!file.millimetres && mm_only) {
      throw ParseError(file.path, v.line, "'" + v.name + "' is in millimetres; add 'units mm' and pixel_size_mm, "
                                                          "or give cx / cy in pixels");
    }
  }
  if (file.millimetres && !(file.pixel_size_mm > 0.0)) {
    throw ParseError(file.path, 0, "'units mm' needs pixel_size_mm");
  }
  if ((file.width > 0) != (file.height > 0)) {
    throw ParseError(file.path, file.size_line, "expected both 'width' and 'height' (pixels), or neither");
  }
  return file;
}

Camera CameraFile::ToCamera() const {
  if (width <= 0) {
    throw InvalidArgument(path + ": the camera file needs 'width' and 'height' (pixels) to adjust from "
                                 "measurements alone");
  }
  const auto f = std::find_if(values.begin(), values.end(), [](const CameraFileValue& v) { return v.name == "f"; });
  if (f == values.end()) {
    throw InvalidArgument(path + ": the camera file needs 'f' (the camera constant) to adjust from measurements "
                                 "alone");
  }
  const double focal_px = f->value / (millimetres ? pixel_size_mm : 1.0);
  SparseModel model;
  model.cameras.push_back(Camera::Create(CameraModelId::kBrown, focal_px, width, height, 1));
  BundleOptions unused;
  ApplyCameraFile(*this, &model, &unused);
  return model.cameras[0];
}

void ApplyCameraFile(const CameraFile& file, SparseModel* model, BundleOptions* options,
                     const std::vector<double>& full_from_working) {
  for (size_t c = 0; c < model->cameras.size(); ++c) {
    Camera& camera = model->cameras[c];
    const CameraModelInfo& info = camera.info();
    const double scale = c < full_from_working.size() && full_from_working[c] > 0.0 ? full_from_working[c] : 1.0;
    // Millimetres or full-resolution pixels per working pixel.
    const double pix = (file.millimetres ? file.pixel_size_mm : 1.0) * scale;
    // The working size is rounded: up to a working pixel either way.
    const double slack = std::max(1.0, scale);
    if (file.width > 0 && (std::abs(camera.width * scale - file.width) > slack ||
                           std::abs(camera.height * scale - file.height) > slack)) {
      throw InvalidArgument(file.path + ":" + std::to_string(file.size_line) + ": the certificate is for " +
                            std::to_string(file.width) + " x " + std::to_string(file.height) + " px images; camera " +
                            std::to_string(camera.id) + " is " + std::to_string(std::lround(camera.width * scale)) +
                            " x " + std::to_string(std::lround(camera.height * scale)) + " px");
    }
    for (const CameraFileValue& v : file.values) {
      // In pixels, with the parameter it sets.
      std::string name = v.name;
      double value = v.value, sigma = v.sigma.value_or(0.0);
      if (v.name == "f") {
        value /= pix;
        sigma /= pix;
      } else if (v.name == "cx" || v.name == "cy") {
        value = (value + 0.5) / scale - 0.5;  // pixel centres at integers, both resolutions
        sigma /= scale;
      } else if (v.name == "x0") {
        name = "cx";
        value = 0.5 * (camera.width - 1) + v.value / pix;
        sigma /= pix;
      } else if (v.name == "y0") {
        name = "cy";
        value = 0.5 * (camera.height - 1) - v.value / pix;  // y up
        sigma /= pix;
      }
      const auto it = std::find(info.param_names.begin(), info.param_names.end(), name);
      if (it == info.param_names.end()) {
        throw InvalidArgument(file.path + ":" + std::to_string(v.line) + ": camera " + std::to_string(camera.id) +
                              " (" + info.name + ") has no parameter '" + name + "'");
      }
      const int index = static_cast<int>(it - info.param_names.begin());
      camera.params[index] = value;
      if (v.fixed) options->held_params.push_back({static_cast<int>(c), index});
      if (v.sigma) options->intrinsics_priors.push_back({static_cast<int>(c), index, value, sigma});
    }
  }
}

}  // namespace aerotri
