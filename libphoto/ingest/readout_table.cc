// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ingest/readout_table.h"

#include <algorithm>
#include <cctype>
#include <limits>

namespace aerotri {
namespace {

// OpenDroneMap's rolling-shutter database (opendm/rollingshutter.py,
// RS_DATABASE), whose figures were measured by filming a flashing screen
// (github.com/OpenDroneMap/RSCalibration). Rows with a megapixel bound read
// the sensor in two modes: below the bound, the faster one.
struct Row {
  const char* make_model;  // lower case, "make model"
  double readout_ms;
  double below_megapixels;  // this row applies below this capture size
};
constexpr double kAny = std::numeric_limits<double>::infinity();
constexpr Row kRows[] = {
    {"dji phantom vision fc200", 74, kAny},  // Phantom 2 Vision
    {"dji fc300s", 33, kAny},                // Phantom 3 Advanced
    {"dji fc300c", 33, kAny},                // Phantom 3 Standard
    {"dji fc300x", 33, kAny},                // Phantom 3 Professional
    {"dji fc330", 33, kAny},                 // Phantom 4
    {"dji fc6310", 33, kAny},                // Phantom 4 Professional
    {"dji fc7203", 20, kAny},                // Mavic Mini
    {"dji fc3170", 27, kAny},                // Mavic Air 2
    {"dji fc3411", 32, kAny},                // Air 2S
    {"hasselblad l1d-20c", 47, 17},          // Mavic 2 Pro, 16:10 (16.8 MP)
    {"hasselblad l1d-20c", 56, kAny},        // Mavic 2 Pro, 3:2 and 4:3
    {"dji fc3582", 26, 48},                  // Mini 3 Pro, 12 MP
    {"dji fc3582", 60, kAny},                // Mini 3 Pro, 48 MP
    {"dji fc350", 30, kAny},                 // Inspire 1
    {"yuneec e90", 44, kAny},
    {"gopro hero4 black", 30, kAny},
    {"gopro hero8 black", 17, kAny},
};
constexpr const char* kSource =
    "OpenDroneMap's rolling-shutter database (opendm/rollingshutter.py), measured with a flashing screen "
    "(OpenDroneMap/RSCalibration)";

std::string Trimmed(const std::string& s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

}  // namespace

std::optional<KnownReadout> KnownCameraReadout(const std::string& make, const std::string& model,
                                               double megapixels) {
  const std::string camera = Trimmed(Trimmed(make) + " " + Trimmed(model));
  std::string key = camera;
  std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const Row& row : kRows) {
    if (key != row.make_model || !(megapixels < row.below_megapixels)) continue;
    return KnownReadout{row.readout_ms * 1e-3, camera, kSource};
  }
  return std::nullopt;
}

}  // namespace aerotri
