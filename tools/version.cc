// SPDX-License-Identifier: BSD-3-Clause
// The version line: aerotri and every dependency's version. Kept apart from
// tool_context.cc because it links GDAL, PROJ and OpenCV, which the light
// `aerotri` front (bal) does not load.
#include <CLI/CLI.hpp>
#include <bzlib.h>
#include <gdal.h>
#include <proj.h>

#include <CLI/Version.hpp>
#include <Eigen/Core>
#include <GeographicLib/Config.h>
#include <ceres/version.h>
#include <nlohmann/json.hpp>
#include <opencv2/core/version.hpp>
#include <sstream>

#include "tools/tool_context.h"
#include "tools/version.h"

namespace aerotri {

std::string VersionString() {
  // libbz2 reports "1.0.8, 13-Jul-2019": keep the version, drop the date.
  std::string bzip2 = BZ2_bzlibVersion();
  bzip2 = bzip2.substr(0, bzip2.find(','));
  std::ostringstream out;
  out << "aerotri " << kAerotriVersion << " (ceres " << CERES_VERSION_STRING << ", eigen "
      << EIGEN_WORLD_VERSION << "." << EIGEN_MAJOR_VERSION << "." << EIGEN_MINOR_VERSION
      << ", opencv " << CV_VERSION << ", proj " << proj_info().version << ", gdal "
      << GDALVersionInfo("RELEASE_NAME") << ", geographiclib "
      << GEOGRAPHICLIB_VERSION_STRING << ", cli11 " << CLI11_VERSION << ", nlohmann-json "
      << NLOHMANN_JSON_VERSION_MAJOR << "." << NLOHMANN_JSON_VERSION_MINOR << "."
      << NLOHMANN_JSON_VERSION_PATCH << ", bzip2 " << bzip2 << ")";
  return out.str();
}

}  // namespace aerotri
