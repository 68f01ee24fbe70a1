// SPDX-License-Identifier: BSD-3-Clause
#include "georef/tie_point_file.h"

#include <charconv>
#include <cmath>
#include <map>
#include <sstream>
#include <utility>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {
namespace {

std::optional<double> ParseNumber(const std::string& token) {
  double value = 0.0;
  const char* begin = token.data() + (token.size() > 1 && token[0] == '+' ? 1 : 0);
  const char* end = token.data() + token.size();
  const auto [next, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || next != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

}  // namespace

TiePointFile ReadTiePointFile(const std::filesystem::path& path, PixelOrigin origin) {
  std::string text = ReadTextFile(path);
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
  for (char& c : text) {
    if (c == '\r') c = '\n';  // CR LF becomes an empty line, skipped
  }
  TiePointFile file;
  file.path = path.string();
  const std::string& p = file.path;
  const double shift = origin == PixelOrigin::kCorner ? 0.5 : 0.0;
  const double edge = origin == PixelOrigin::kCentre ? -0.5 : 0.0;
  std::map<std::pair<std::string, std::string>, int> seen;  // (image, point) -> line
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::istringstream words(line);
    std::vector<std::string> cols;
    for (std::string w; words >> w;) cols.push_back(w);
    if (cols.empty() || cols[0][0] == '#') continue;
    if (cols.size() < 4 || cols.size() > 5) {
      throw ParseError(p, number, "expected 'image_name point_name im_x im_y [sigma_px=S]', got " +
                                      std::to_string(cols.size()) + " columns");
    }
    TieMeasurement m;
    m.image = cols[0];
    m.point = cols[1];
    m.line = number;
    const auto x = ParseNumber(cols[2]);
    const auto y = ParseNumber(cols[3]);
    if (!x || !y) {
      throw ParseError(p, number, "expected pixel coordinates im_x im_y (columns 3 and 4), got '" + cols[2] +
                                      "' '" + cols[3] + "'");
    }
    if (*x < edge || *y < edge) {
      throw ParseError(p, number, std::string("expected pixel coordinates >= ") +
                                      (edge < 0 ? "-0.5 (the top-left pixel's outer edge)" : "0") + ", got " +
                                      cols[2] + " " + cols[3]);
    }
    m.xy_px = {*x - shift, *y - shift};
    if (cols.size() == 5) {
      const std::string& extra = cols[4];
      const auto value = extra.rfind("sigma_px=", 0) == 0 ? ParseNumber(extra.substr(9)) : std::nullopt;
      if (!value || !(*value > 0.0)) {
        throw ParseError(p, number, "expected sigma_px=S with S a positive number of pixels, got '" + extra + "'");
      }
      m.sigma_px = *value;
    }
    const auto [it, inserted] = seen.emplace(std::make_pair(m.image, m.point), number);
    if (!inserted) {
      throw ParseError(p, number, "point '" + m.point + "' is measured twice in image '" + m.image +
                                      "' (also on line " + std::to_string(it->second) + ")");
    }
    file.measurements.push_back(std::move(m));
  }
  if (file.measurements.empty()) throw ParseError(p, number, "expected tie-point measurements, found none");
  return file;
}

}  // namespace aerotri
