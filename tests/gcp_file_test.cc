// SPDX-License-Identifier: BSD-3-Clause
#include "georef/gcp_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include <algorithm>
#include <fstream>

#include "georef/crs.h"
#include "libphoto/base/error.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

void Write(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(GcpFile, ReadsOdmFormatWithNamesSigmasAndComments) {
  testing::TempDir dir;
  Write(dir / "gcp_list.txt",
        "EPSG:32632+5773\n"
        "# surveyed 2026-05-02\n"
        "384902.84 5150696.35 449.91 1024.5 768.5 IMG_0001.JPG GCP1 sigma_h=0.02 sigma_v=0.04\n"
        "\n"
        "384902.84 5150696.35 449.91 100 200.25 IMG_0002.JPG GCP1\n"
        "384950.00 5150700.00 451.00 10 20 IMG_0002.JPG GCP2 some_extra\n"
        "384990.00 5150710.00 452.00 30 40 IMG_0003.JPG\n");
  const GcpFile file = ReadGcpFile(dir / "gcp_list.txt", PixelOrigin::kCorner);
  EXPECT_EQ(file.crs, "EPSG:32632+5773");
  ASSERT_EQ(file.points.size(), 3u);
  const GroundPoint& g1 = file.points[0];
  EXPECT_EQ(g1.name, "GCP1");
  ASSERT_EQ(g1.measurements.size(), 2u);
  // Corner origin: (1024.5, 768.5) is the centre of pixel (1024, 768).
  EXPECT_DOUBLE_EQ(g1.measurements[0].xy_px.x(), 1024.0);
  EXPECT_DOUBLE_EQ(g1.measurements[0].xy_px.y(), 768.0);
  EXPECT_EQ(g1.measurements[1].line, 5);
  EXPECT_DOUBLE_EQ(*g1.sigma_h_m, 0.02);
  EXPECT_DOUBLE_EQ(*g1.sigma_v_m, 0.04);
  EXPECT_FALSE(file.points[1].sigma_h_m.has_value());
  EXPECT_EQ(file.points[2].measurements[0].image, "IMG_0003.JPG");

  // The default is OpenDroneMap's: integers at pixel centres.
  const GcpFile centre = ReadGcpFile(dir / "gcp_list.txt");
  EXPECT_DOUBLE_EQ(centre.points[0].measurements[0].xy_px.x(), 1024.5);
}

// OpenDroneMap reads gcp_list.txt through OpenSfM, whose normalised image
// coordinates are n = (x + 0.5 - w/2) / max(w, h) (OpenSfM
// features.normalized_image_coordinates). aerotri's pixel p (top-left pixel
// centre at 0) is the same point when (p - (w - 1)/2) / max(w, h) == n: the
// default reading must satisfy that for every value; corner origin must
// satisfy COLMAP's n = (x - w/2) / max(w, h).
TEST(GcpFile, PixelConventionMatchesOpenSfmAndColmap) {
  testing::TempDir dir;
  constexpr int kWidth = 4000, kHeight = 3000;
  Write(dir / "gcp_list.txt",
        "EPSG:32632\n"
        "1 2 3 0 0 a.jpg P\n"
        "1 2 3 1999.5 1499.5 b.jpg P\n"
        "1 2 3 3999 2999 c.jpg P\n"
        "1 2 3 123.25 2048.75 d.jpg P\n");
  const double s = std::max(kWidth, kHeight);
  const GcpFile odm = ReadGcpFile(dir / "gcp_list.txt");
  const GcpFile colmap = ReadGcpFile(dir / "gcp_list.txt", PixelOrigin::kCorner);
  const double raw[4][2] = {{0, 0}, {1999.5, 1499.5}, {3999, 2999}, {123.25, 2048.75}};
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d p = odm.points[0].measurements[k].xy_px;
    EXPECT_NEAR((p.x() - (kWidth - 1) / 2.0) / s, (raw[k][0] + 0.5 - kWidth / 2.0) / s, 1e-15);
    EXPECT_NEAR((p.y() - (kHeight - 1) / 2.0) / s, (raw[k][1] + 0.5 - kHeight / 2.0) / s, 1e-15);
    const Eigen::Vector2d c = colmap.points[0].measurements[k].xy_px;
    EXPECT_NEAR((c.x() - (kWidth - 1) / 2.0) / s, (raw[k][0] - kWidth / 2.0) / s, 1e-15);
    EXPECT_NEAR((c.y() - (kHeight - 1) / 2.0) / s, (raw[k][1] - kHeight / 2.0) / s, 1e-15);
  }
  // The image centre: (w - 1)/2 in OpenDroneMap's file is the optical centre
  // of an ideal camera.
  EXPECT_DOUBLE_EQ(odm.points[0].measurements[1].xy_px.x(), (kWidth - 1) / 2.0);
}

TEST(GcpFile, WriteThenReadRoundTrips) {
  testing::TempDir dir;
  GcpFile file;
  file.crs = "EPSG:32632";
  GroundPoint p;
  p.name = "A";
  p.xyz = {384902.8374, 5150696.3462, 500.25};
  p.sigma_h_m = 0.015;
  p.measurements.push_back({"x.jpg", {10.25, 20.75}, 0});
  file.points.push_back(p);
  WriteGcpFile(file, dir / "out.txt");
  const GcpFile again = ReadGcpFile(dir / "out.txt");
  ASSERT_EQ(again.points.size(), 1u);
  EXPECT_LT((again.points[0].xyz - p.xyz).norm(), 1e-6);
  EXPECT_LT((again.points[0].measurements[0].xy_px - p.measurements[0].xy_px).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(*again.points[0].sigma_h_m, 0.015);
}

// A point surveyed in plan only: geo_z 'nan' (any case) or '-'; written
// back as 'nan' and read again.
TEST(GcpFile, HorizontalOnlyPointsHaveNoHeight) {
  testing::TempDir dir;
  Write(dir / "gcp_list.txt",
        "EPSG:32632\n"
        "384902.84 5150696.35 NaN 1024.5 768.5 IMG_0001.JPG H1\n"
        "384902.84 5150696.35 nan 100 200 IMG_0002.JPG H1\n"
        "384950.00 5150700.00 - 10 20 IMG_0002.JPG H2\n"
        "384990.00 5150710.00 452.00 30 40 IMG_0003.JPG G3\n");
  const GcpFile file = ReadGcpFile(dir / "gcp_list.txt");
  ASSERT_EQ(file.points.size(), 3u);
  EXPECT_TRUE(file.points[0].horizontal_only);
  EXPECT_TRUE(std::isnan(file.points[0].xyz.z()));
  EXPECT_EQ(file.points[0].measurements.size(), 2u);
  EXPECT_TRUE(file.points[1].horizontal_only);
  EXPECT_FALSE(file.points[2].horizontal_only);
  EXPECT_DOUBLE_EQ(file.points[2].xyz.z(), 452.0);
  WriteGcpFile(file, dir / "out.txt");
  const GcpFile again = ReadGcpFile(dir / "out.txt");
  ASSERT_EQ(again.points.size(), 3u);
  EXPECT_TRUE(again.points[0].horizontal_only);
  EXPECT_TRUE(again.points[1].horizontal_only);
  EXPECT_NEAR(again.points[1].xyz.x(), 384950.0, 1e-6);
}

TEST(GcpFile, BadLinesNameFileLineAndExpectation) {
  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"EPSG:32632\n1 2 3 4 5\n", 2, "expected at least 6 columns"},
      {"EPSG:32632\n1 2 x 4 5 a.jpg\n", 2, "expected a number for geo_z (column 3) or 'nan' (no surveyed height), got 'x'"},
      {"EPSG:32632\n1 2 nan 4 5 a.jpg P\n1 2 3 4 5 b.jpg P\n", 3, "other coordinates here than on line 2"},
      {"EPSG:32632\n\n1 2 3 -4 5 a.jpg\n", 3, "expected pixel coordinates >= -0.5"},
      {"EPSG:32632\n1 2 3 4 5 a.jpg P sigma_h=-1\n", 2, "positive number of metres for sigma_h"},
      {"EPSG:32632\n1 2 3 4 5 a.jpg P\n1 2 4 4 5 b.jpg P\n", 3, "other coordinates here than on line 2"},
      {"EPSG:32632\n1 2 3 4 5 a.jpg P sigma_px=0\n", 2, "positive number of pixels for sigma_px, got '0'"},
      {"EPSG:32632\n1 2 3 4 5 a.jpg P sigma_x=0.1 sigma_z=0.2\n", 2,
       "expected sigma_x, sigma_y and sigma_z together, got 2 of them"},
      {"1 2 3 4 5 a.jpg\n", 1, "expected a CRS on the first line"},
      {"EPSG:32632\n384902.84 5150696.35 449.91 4 5 a.jpg P\n384902.84 5150696.352 449.91 4 5 b.jpg P\n", 3,
       "point 'P' has other coordinates here than on line 2"},
      {"EPSG:32632\n# surveyed, but nothing measured yet\n", 1, "no point lines after the CRS line"},
      {"\n# only a comment\n", 0, "empty file"},
  };
  testing::TempDir dir;
  for (const Case& c : cases) {
    Write(dir / "gcp_list.txt", c.text);
    try {
      ReadGcpFile(dir / "gcp_list.txt");
      ADD_FAILURE() << "accepted: " << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("gcp_list.txt"), std::string::npos);
    }
  }
  EXPECT_THROW(ReadGcpFile(dir / "absent.txt"), IoError);
}


// The stochastic model in the file: per-axis survey sigmas for a point and
// an image sigma per measurement, read and written back.
TEST(GcpFile, ReadsAndWritesPerAxisAndPerMeasurementSigmas) {
  testing::TempDir dir;
  Write(dir / "gcp_list.txt",
        "EPSG:32632\n"
        "100 200 30 10 20 a.jpg P1 sigma_x=0.02 sigma_y=0.03 sigma_z=0.04 sigma_px=0.5\n"
        "100 200 30 11 21 b.jpg P1\n");
  const GcpFile file = ReadGcpFile(dir / "gcp_list.txt");
  ASSERT_EQ(file.points.size(), 1u);
  const GroundPoint& p = file.points[0];
  ASSERT_TRUE(p.sigma_xyz_m.has_value());
  EXPECT_EQ(*p.sigma_xyz_m, Eigen::Vector3d(0.02, 0.03, 0.04));
  ASSERT_EQ(p.measurements.size(), 2u);
  EXPECT_EQ(p.measurements[0].sigma_px, 0.5);
  EXPECT_FALSE(p.measurements[1].sigma_px.has_value());
  WriteGcpFile(file, dir / "again.txt");
  const GcpFile again = ReadGcpFile(dir / "again.txt");
  EXPECT_EQ(*again.points[0].sigma_xyz_m, *p.sigma_xyz_m);
  EXPECT_EQ(again.points[0].measurements[0].sigma_px, 0.5);
  EXPECT_FALSE(again.points[0].measurements[1].sigma_px.has_value());
}

// Files as spreadsheets and old tools write them: a UTF-8 byte-order mark,
// CR-only or CR LF line endings, numbers with a leading '+'.
TEST(GcpFile, ReadsBomCrOnlyAndPlusSigns) {
  testing::TempDir dir;
  const std::string body = "EPSG:32632\r+384944.8 5150695.5 +510.5 602.9 704.8 IMG_0008.JPG GCP1\r"
                           "384950.0 5150700.0 511.0 10 20 IMG_0009.JPG GCP2\r";
  Write(dir / "bom_cr.txt", "\xEF\xBB\xBF" + body);
  const GcpFile f = ReadGcpFile(dir / "bom_cr.txt");
  EXPECT_EQ(f.crs, "EPSG:32632");
  ASSERT_EQ(f.points.size(), 2u);
  EXPECT_DOUBLE_EQ(f.points[0].xyz.x(), 384944.8);
  EXPECT_DOUBLE_EQ(f.points[0].xyz.z(), 510.5);
  EXPECT_EQ(f.points[1].measurements[0].line, 3);
  std::string crlf = body;
  for (size_t k = 0; (k = crlf.find('\r', k)) != std::string::npos; k += 2) crlf.insert(k + 1, "\n");
  Write(dir / "crlf.txt", crlf);
  const GcpFile g = ReadGcpFile(dir / "crlf.txt");
  ASSERT_EQ(g.points.size(), 2u);
  EXPECT_EQ(g.points[1].measurements[0].line, 3);
  // A sign alone, or two, is still not a number.
  Write(dir / "bad.txt", "EPSG:32632\n+-5 1 2 3 4 a.jpg\n");
  EXPECT_THROW(ReadGcpFile(dir / "bad.txt"), ParseError);
}

GcpFile PointsAt(const std::string& path, const std::string& crs,
                 const std::vector<std::pair<std::string, Eigen::Vector3d>>& points) {
  GcpFile file;
  file.path = path;
  file.crs = crs;
  for (const auto& [name, xyz] : points) {
    GroundPoint p;
    p.name = name;
    p.xyz = xyz;
    file.points.push_back(p);
  }
  return file;
}

TEST(GcpFile, ReadsCoordinatesOnlyFilesWithSigmas) {
  testing::TempDir dir;
  Write(dir / "coords.txt",
        "EPSG:32632\n"
        "# from the rover, 2026-05-02\n"
        "GCP1 384902.84 5150696.35 449.91 sigma_h=0.02 sigma_v=0.04\n"
        "GCP2 384950.00 5150700.00 nan\n"
        "GCP3 +384990.00 5150710.00 452.00 sigma_x=0.01 sigma_y=0.02 sigma_z=0.03\n");
  const GcpFile file = ReadGcpFile(dir / "coords.txt");
  EXPECT_TRUE(file.coordinates_only);
  ASSERT_EQ(file.points.size(), 3u);
  EXPECT_EQ(file.points[0].name, "GCP1");
  EXPECT_DOUBLE_EQ(file.points[0].xyz.y(), 5150696.35);
  EXPECT_DOUBLE_EQ(*file.points[0].sigma_h_m, 0.02);
  EXPECT_DOUBLE_EQ(*file.points[0].sigma_v_m, 0.04);
  EXPECT_TRUE(file.points[1].horizontal_only);
  EXPECT_FALSE(file.points[0].horizontal_only);
  EXPECT_DOUBLE_EQ(file.points[2].xyz.x(), 384990.0);
  EXPECT_DOUBLE_EQ(file.points[2].sigma_xyz_m->z(), 0.03);
  for (const GroundPoint& p : file.points) EXPECT_TRUE(p.measurements.empty());
  EXPECT_EQ(file.points[2].first_line, 5);
}

TEST(GcpFile, ReadsPix4dCsvWithAndWithoutAccuracies) {
  testing::TempDir dir;
  Write(dir / "pix4d.csv",
        "EPSG:32632\r\n"
        "label,x,y,z,acc_h,acc_v\r\n"
        "A1,384902.84,5150696.35,449.91,0.02,0.05\r\n"
        "A2, 384950.00, 5150700.00, 451.00\r\n"
        "A3,384990.00,5150710.00,452.00,,0.03\r\n");
  const GcpFile file = ReadGcpFile(dir / "pix4d.csv");
  EXPECT_TRUE(file.coordinates_only);
  ASSERT_EQ(file.points.size(), 3u);
  EXPECT_DOUBLE_EQ(*file.points[0].sigma_h_m, 0.02);
  EXPECT_DOUBLE_EQ(*file.points[0].sigma_v_m, 0.05);
  EXPECT_FALSE(file.points[1].sigma_h_m.has_value());
  EXPECT_DOUBLE_EQ(file.points[1].xyz.x(), 384950.0);
  EXPECT_FALSE(file.points[2].sigma_h_m.has_value());
  EXPECT_DOUBLE_EQ(*file.points[2].sigma_v_m, 0.03);
}

TEST(GcpFile, CoordinatesOnlyErrorsNameLineAndValue) {
  testing::TempDir dir;
  const auto error_of = [&](const std::string& body) {
    Write(dir / "bad.txt", "EPSG:32632\n" + body);
    try {
      ReadGcpFile(dir / "bad.txt");
    } catch (const ParseError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(error_of("GCP1 384902 5150696 449\nGCP1 384903 5150696 449\n"),
              ::testing::AllOf(::testing::HasSubstr("bad.txt:3"), ::testing::HasSubstr("listed twice"),
                               ::testing::HasSubstr("line 2")));
  EXPECT_THAT(error_of("GCP1 384902 north 449\n"),
              ::testing::AllOf(::testing::HasSubstr("bad.txt:2"), ::testing::HasSubstr("'north'"),
                               ::testing::HasSubstr("for y")));
  EXPECT_THAT(error_of("GCP1 384902 5150696 449\n384902 5150696 449 10 20 IMG_1.JPG GCP2\n"),
              ::testing::AllOf(::testing::HasSubstr("bad.txt:3"), ::testing::HasSubstr("pixel columns")));
  EXPECT_THAT(error_of("A1,384902,5150696,449,-0.02\n"),
              ::testing::AllOf(::testing::HasSubstr("bad.txt:2"), ::testing::HasSubstr("acc_h"),
                               ::testing::HasSubstr("'-0.02'")));
  EXPECT_THAT(error_of("GCP1 384902 5150696 449 sigma_h=0\n"),
              ::testing::AllOf(::testing::HasSubstr("bad.txt:2"), ::testing::HasSubstr("sigma_h")));
  // A file of marks stays one: its reader is unchanged.
  Write(dir / "marks.txt", "EPSG:32632\n384902 5150696 449 10 20 IMG_1.JPG GCP1\n");
  EXPECT_FALSE(ReadGcpFile(dir / "marks.txt").coordinates_only);
}

TEST(CheckChecksIndependent, TheControlFileAsTheCheckFileIsAUsageError) {
  const GcpFile control = PointsAt("gcp.txt", "EPSG:32632",
                                   {{"A", {384900, 5150600, 510}}, {"B", {385000, 5150700, 512}}});
  try {
    CheckChecksIndependent(control, control, 0.02, 0.03);
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("2 of its 2 check points are control points of gcp.txt too: A (the same "
                                         "name), B (the same name)"),
              std::string::npos)
        << e.what();
  }
}

TEST(CheckChecksIndependent, ThePointUnderAnotherNameInAnotherCrsIsFoundAndAPointBesideItIsNot) {
  const Eigen::Vector3d a(384900, 5150600, 510);
  const GcpFile control = PointsAt("gcp.txt", "EPSG:32632", {{"A", a}, {"B", {385000, 5150700, 512}}});
  // A as longitude, latitude, within 1 cm; and a target 0.5 m beside B.
  const Geodetic g = Crs::FromString("EPSG:32632").ToGeodetic(a + Eigen::Vector3d(0.005, -0.005, 0.01));
  const GcpFile same = PointsAt("checks.txt", "EPSG:4326", {{"CP1", {g.lon_deg, g.lat_deg, g.h_m}}});
  EXPECT_THROW(CheckChecksIndependent(control, same, 0.02, 0.03), UsageError);
  const GcpFile beside = PointsAt("checks.txt", "EPSG:32632", {{"CP2", {385000.5, 5150700, 512}}});
  EXPECT_NO_THROW(CheckChecksIndependent(control, beside, 0.02, 0.03));
  // The same plan position, 1 m higher (another target on a pole): independent.
  const GcpFile above = PointsAt("checks.txt", "EPSG:32632", {{"CP3", {384900, 5150600, 511}}});
  EXPECT_NO_THROW(CheckChecksIndependent(control, above, 0.02, 0.03));
}

}  // namespace
}  // namespace aerotri
