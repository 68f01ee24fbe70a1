// SPDX-License-Identifier: BSD-3-Clause
#pragma once

// Point clouds in the output CRS, written as LAS 1.4 and PLY, atomically.
//
// LAS 1.4 (ASPRS R15, 2019): point data record format 7 (XYZ, RGB, GPS time),
// the CRS as OGC WKT in a LASF_Projection VLR (record 2112) with the WKT bit
// of the global encoding set; scale 0.001 (millimetre) and offsets at the
// cloud's minimum, so integer coordinates stay small. Colours are 16-bit
// (8-bit x 257), the ASPRS classification per point (CrsCloud::classes;
// 1, unclassified, when absent).
// PLY: binary little-endian, double x y z in the output CRS, uchar RGB, the
// CRS named in a comment.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace aerotri {

struct CrsCloud {
  std::vector<Eigen::Vector3d> xyz;  // output CRS
  std::vector<std::array<std::uint8_t, 3>> rgb;
  std::vector<std::uint8_t> classes;  // ASPRS classes (LAS only); empty: all 1
  std::string crs_wkt;   // OGC WKT (WKT1 for LAS readers of today)
  std::string crs_name;  // for humans (PLY comment)
};

void WriteLas(const CrsCloud& cloud, const std::filesystem::path& path);
void WritePly(const CrsCloud& cloud, const std::filesystem::path& path);

// Reads LAS 1.2-1.4 point formats 0-3 and 6-8 (XYZ, classes, RGB where
// present, the WKT VLR where present). Throws ParseError for anything else.
CrsCloud ReadLas(const std::filesystem::path& path);

}  // namespace aerotri
