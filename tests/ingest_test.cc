// SPDX-License-Identifier: BSD-3-Clause
// EXIF through GDAL (written by GDAL's JPEG driver, read back), GPS CSV files
// and altitude references, and focal length from EXIF.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "camera_models/exif_intrinsics.h"
#include "libphoto/base/error.h"
#include "libphoto/ingest/gps_sources.h"
#include "libphoto/ingest/ingest.h"
#include "libphoto/ingest/image_metadata.h"
#include "libphoto/ingest/readout_table.h"
#include "libphoto/io/image_writer.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

TEST(ImageMetadata, ExifGpsAndOpticsRoundTripThroughGdal) {
  testing::TempDir dir;
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  std::map<std::string, std::string> exif = {
      {"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"},
      {"EXIF_GPSLatitude", ExifDms(46.842609)}, {"EXIF_GPSLatitudeRef", "N"},
      {"EXIF_GPSLongitude", ExifDms(91.994561)}, {"EXIF_GPSLongitudeRef", "W"},
      {"EXIF_GPSAltitude", "(198.309)"}, {"EXIF_GPSAltitudeRef", "0x00"},
      {"EXIF_FocalLength", "(3.61)"}, {"EXIF_FocalLengthIn35mmFilm", "20"}};
  WriteJpegWithExif(dir / "a.jpg", image, exif);
  const ImageMetadata m = ReadImageMetadata(dir / "a.jpg");
  EXPECT_EQ(m.width, 64);
  EXPECT_EQ(m.height, 48);
  EXPECT_EQ(m.make, "DJI");
  ASSERT_TRUE(m.HasGps());
  // EXIF stores seconds to 1e-4": 3 mm.
  EXPECT_NEAR(*m.lat_deg, 46.842609, 1e-7);
  EXPECT_NEAR(*m.lon_deg, -91.994561, 1e-7);
  EXPECT_NEAR(*m.gps_altitude_m, 198.309, 1e-3);
  EXPECT_NEAR(*m.focal_mm, 3.61, 1e-6);
  // A known drone camera: 3.61 mm on a 6.17 mm wide sensor, 64 px wide.
  ExifOptics optics{m.make, m.model, m.focal_mm, m.focal_35mm, m.focal_plane_px_per_mm,
                    m.exif_pixel_width, m.width, m.height};
  const FocalEstimate f = FocalFromExif(optics);
  EXPECT_NEAR(f.focal_px, 3.61 / 6.17 * 64, 1e-9);
  EXPECT_NE(f.source.find("known sensor width"), std::string::npos);

  std::ofstream(dir / "broken.jpg") << "not an image";
  EXPECT_THROW(ReadImageMetadata(dir / "broken.jpg"), IoError);
}

// DJI gimbal angles written as an XMP segment beside the EXIF one, read back
// by GDAL's JPEG driver (which parses the segment itself): the angles to
// their two written decimals, the EXIF untouched, the pixels decodable.
TEST(ImageMetadata, GimbalXmpRoundTripsBesideTheExif) {
  testing::TempDir dir;
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  WriteJpegWithExif(dir / "g.jpg", image, {{"EXIF_Make", "DJI"}, {"EXIF_GPSAltitude", "(98.5)"}}, 90,
                    DjiGimbalXmp(-59.876, 171.234, 1.5));
  const ImageMetadata m = ReadImageMetadata(dir / "g.jpg");
  EXPECT_EQ(m.make, "DJI");
  ASSERT_TRUE(m.gps_altitude_m.has_value());
  EXPECT_NEAR(*m.gps_altitude_m, 98.5, 1e-9);
  ASSERT_TRUE(m.gimbal_pitch_deg && m.gimbal_yaw_deg && m.gimbal_roll_deg);
  EXPECT_NEAR(*m.gimbal_pitch_deg, -59.88, 1e-9);
  EXPECT_NEAR(*m.gimbal_yaw_deg, 171.23, 1e-9);
  EXPECT_NEAR(*m.gimbal_roll_deg, 1.5, 1e-9);
  const cv::Mat back = cv::imread((dir / "g.jpg").string());
  ASSERT_EQ(back.cols, 64);
  EXPECT_NEAR(back.at<cv::Vec3b>(10, 10)[2], 200, 3);
  // Without a packet there is no XMP.
  WriteJpegWithExif(dir / "plain.jpg", image, {{"EXIF_Make", "DJI"}});
  EXPECT_FALSE(ReadImageMetadata(dir / "plain.jpg").gimbal_pitch_deg.has_value());
  EXPECT_THROW(WriteJpegWithExif(dir / "big.jpg", image, {}, 90, std::string(70000, 'x')), InvalidArgument);
  EXPECT_FALSE(std::filesystem::exists(dir / "big.jpg"));
}

// What `aerotri simulate --readout-ms` writes, read back as a Sequoia's
// tags are: the readout in whole microseconds, the velocity's three values.
TEST(ImageMetadata, RollingShutterTagsRoundTripAsASequoiaWritesThem) {
  testing::TempDir dir;
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  WriteJpegWithExif(dir / "rs.jpg", image, {{"EXIF_Make", "Parrot"}}, 90,
                    RollingShutterXmp(0.0475, Eigen::Vector3d(2.09, 12.59, 0.0)));
  const ImageMetadata m = ReadImageMetadata(dir / "rs.jpg");
  ASSERT_EQ(m.xmp_sources, std::vector<std::string>{"Pix4D camera tags (Camera namespace)"});
  ASSERT_TRUE(m.line_readout_time_s.has_value());
  EXPECT_DOUBLE_EQ(*m.line_readout_time_s, 0.0475);
  EXPECT_EQ(m.imu_linear_velocity_mps, (std::vector<double>{2.09, 12.59, 0.0}));
  EXPECT_FALSE(m.camera_pitch_deg.has_value());
  // What the adjustment takes of them: the readout, the velocity east and north.
  const auto stated = RollingShutterStatedBy(m);
  ASSERT_TRUE(stated.has_value());
  EXPECT_DOUBLE_EQ(stated->readout_time_s, 0.0475);
  EXPECT_DOUBLE_EQ(stated->east_mps, 2.09);
  EXPECT_DOUBLE_EQ(stated->north_mps, 12.59);
  // A readout without a velocity states no motion; a velocity without a
  // readout states the motion, its readout left to be estimated (0).
  ImageMetadata readout_only = m;
  readout_only.imu_linear_velocity_mps.clear();
  EXPECT_FALSE(RollingShutterStatedBy(readout_only).has_value());
  ImageMetadata velocity_only = m;
  velocity_only.line_readout_time_s.reset();
  const auto moving = RollingShutterStatedBy(velocity_only);
  ASSERT_TRUE(moving.has_value());
  EXPECT_EQ(moving->readout_time_s, 0.0);
  EXPECT_DOUBLE_EQ(moving->north_mps, 12.59);
}

// Parrot Sequoia (the hard set's first photo, ../shared/data/hard_garfield):
// Pix4D's camera XMP tags as the camera wrote them, read as exiftool shows
// them, and its GPS accuracies become the photo's GPS sigmas.
TEST(ImageMetadata, ParrotSequoiaSaysItsAttitudeAccuracyReadoutAndCalibration) {
  const std::filesystem::path set = testing::SharedData("hard_garfield");
  if (set.empty()) GTEST_SKIP() << "../shared/data/hard_garfield is absent";
  const ImageMetadata m = ReadImageMetadata(set / "images" / "IMG_161122_163234_0000_RGB.JPG");
  ASSERT_EQ(m.xmp_sources, std::vector<std::string>{"Pix4D camera tags (Camera namespace)"});
  ASSERT_TRUE(m.camera_yaw_deg && m.camera_pitch_deg && m.camera_roll_deg);
  EXPECT_DOUBLE_EQ(*m.camera_yaw_deg, -16.7996);
  EXPECT_DOUBLE_EQ(*m.camera_pitch_deg, 5.1846);
  EXPECT_DOUBLE_EQ(*m.camera_roll_deg, 0.0154285);
  ASSERT_TRUE(m.gps_xy_accuracy_m && m.gps_z_accuracy_m && m.line_readout_time_s && m.perspective_focal_mm);
  EXPECT_DOUBLE_EQ(*m.gps_xy_accuracy_m, 2.301);
  EXPECT_DOUBLE_EQ(*m.gps_z_accuracy_m, 3.419);
  EXPECT_DOUBLE_EQ(*m.line_readout_time_s, 0.0475);  // 47500 us
  EXPECT_EQ(m.imu_linear_velocity_mps, (std::vector<double>{2.09, 12.59, 0.61}));
  // Flying north (the next photos' GPS lie 57 and 116 m north): the second
  // value is north, the first east.
  const auto shutter = RollingShutterStatedBy(m);
  ASSERT_TRUE(shutter.has_value());
  EXPECT_DOUBLE_EQ(shutter->north_mps, 12.59);
  EXPECT_DOUBLE_EQ(shutter->east_mps, 2.09);
  EXPECT_DOUBLE_EQ(*m.perspective_focal_mm, 4.812073);
  EXPECT_EQ(m.principal_point_mm, (std::vector<double>{3.042001, 2.280612}));
  EXPECT_EQ(m.perspective_distortion,
            (std::vector<double>{0.178441961, -0.4745818, 0.402026402, -0.000900784, -0.000653429}));
  EXPECT_FALSE(m.gimbal_pitch_deg.has_value());  // no DJI tags
  const auto sigmas = GpsSigmasStatedBy(m);
  ASSERT_TRUE(sigmas.has_value());
  EXPECT_DOUBLE_EQ(sigmas->h_m, 2.301);
  EXPECT_DOUBLE_EQ(sigmas->v_m, 3.419);
  EXPECT_EQ(sigmas->source, "exif+accuracy");
}

// The Sequoia's factory calibration becomes its camera group's initial
// intrinsics at the working size, and its focal length a measured one (the
// adjustments' prior). Expected from the tags by hand: EXIF's focal-plane
// resolution is 746.3 px/mm; f = 4.812073 mm x 746.3 = 3591.2 px, the
// principal point (3.042001, 2.280612) mm x 746.3 - 0.5 = (2269.8, 1701.5)
// px; at 1600 / 4608 of the size: f 1246.9, (787.8, 590.5).
TEST(Ingest, ParrotSequoiaFactoryCalibrationStartsItsCameraGroup) {
  const std::filesystem::path set = testing::SharedData("hard_garfield");
  if (set.empty()) GTEST_SKIP() << "../shared/data/hard_garfield is absent";
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "images");
  const std::string name = "IMG_161122_163234_0000_RGB.JPG";
  std::filesystem::create_symlink(set / "images" / name, dir / "images" / name);
  IngestOptions o;
  o.images_dir = dir / "images";
  o.max_dimension = 1600;
  const IngestRecord r = IngestSurveyImages(o, nullptr);
  ASSERT_EQ(r.groups.size(), 1u);
  const CameraGroup& g = r.groups[0];
  EXPECT_TRUE(g.calibration_stated);
  EXPECT_TRUE(g.focal_measured);
  EXPECT_NE(g.focal_source.find("Camera:PerspectiveFocalLength"), std::string::npos) << g.focal_source;
  const std::vector<double>& p = g.camera.params;
  EXPECT_NEAR(p[0], 1246.9, 0.1);
  EXPECT_NEAR(p[1], 787.8, 0.1);
  EXPECT_NEAR(p[2], 590.5, 0.1);
  EXPECT_DOUBLE_EQ(p[3], 0.178441961);  // k1 .. p2: unitless, unscaled
  EXPECT_DOUBLE_EQ(p[5], 0.402026402);
  EXPECT_DOUBLE_EQ(p[7], -0.000653429);
  // Round trip through ingest.json keeps it.
  const IngestRecord back = IngestRecordFromJson(ToJson(r), "ingest.json");
  EXPECT_TRUE(back.groups[0].calibration_stated);
  EXPECT_EQ(back.groups[0].camera.params, p);
}

// DJI's further drone-dji tags (as DJI's Mavic 3M image processing guide and
// ExifTool's DJI table name them), in a faithfully constructed packet: the
// aircraft's attitude and speeds, the factory calibration, RTK deviations
// (which win over any accuracy tag: they are the RTK solution's own).
TEST(ImageMetadata, DjiSaysItsFlightAttitudeSpeedsCalibrationAndRtkDeviations) {
  testing::TempDir dir;
  const std::string xmp =
      "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">"
      "<rdf:Description rdf:about=\"\" xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\" "
      "drone-dji:GimbalPitchDegree=\"-90.00\" drone-dji:GimbalYawDegree=\"+12.50\" drone-dji:GimbalRollDegree=\"+0.00\" "
      "drone-dji:FlightPitchDegree=\"-3.20\" drone-dji:FlightRollDegree=\"+1.10\" drone-dji:FlightYawDegree=\"+12.90\" "
      "drone-dji:FlightXSpeed=\"+9.8\" drone-dji:FlightYSpeed=\"-0.3\" drone-dji:FlightZSpeed=\"+0.1\" "
      "drone-dji:RtkFlag=\"50\" drone-dji:RtkStdLon=\"0.01163\" drone-dji:RtkStdLat=\"0.01041\" drone-dji:RtkStdHgt=\"0.02232\" "
      "drone-dji:CalibratedFocalLength=\"3666.666504\" drone-dji:CalibratedOpticalCenterX=\"2736.000000\" "
      "drone-dji:CalibratedOpticalCenterY=\"1824.000000\"/></rdf:RDF></x:xmpmeta>";
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  WriteJpegWithExif(dir / "d.jpg", image, {{"EXIF_Make", "DJI"}}, 90, xmp);
  const ImageMetadata m = ReadImageMetadata(dir / "d.jpg");
  EXPECT_EQ(m.xmp_sources, std::vector<std::string>{"DJI (drone-dji)"});
  ASSERT_TRUE(m.flight_pitch_deg && m.flight_roll_deg && m.flight_yaw_deg);
  EXPECT_DOUBLE_EQ(*m.flight_pitch_deg, -3.2);
  EXPECT_DOUBLE_EQ(*m.flight_roll_deg, 1.1);
  EXPECT_DOUBLE_EQ(*m.flight_yaw_deg, 12.9);
  ASSERT_TRUE(m.flight_speed_x_mps && m.flight_speed_y_mps && m.flight_speed_z_mps);
  EXPECT_DOUBLE_EQ(*m.flight_speed_x_mps, 9.8);
  EXPECT_DOUBLE_EQ(*m.flight_speed_y_mps, -0.3);
  ASSERT_TRUE(m.calibrated_focal_px && m.calibrated_cx_px && m.calibrated_cy_px);
  EXPECT_DOUBLE_EQ(*m.calibrated_focal_px, 3666.666504);
  EXPECT_DOUBLE_EQ(*m.calibrated_cy_px, 1824.0);
  const auto sigmas = GpsSigmasStatedBy(m);
  ASSERT_TRUE(sigmas.has_value());
  EXPECT_NEAR(sigmas->h_m, std::hypot(0.01041, 0.01163) / std::sqrt(2.0), 1e-12);
  EXPECT_DOUBLE_EQ(sigmas->v_m, 0.02232);
  EXPECT_EQ(sigmas->source, "exif+rtk");
  // The factory calibration: pixels from the image's corner, to aerotri's
  // pixel centres; no distortion stated.
  const auto calibration = CalibrationStatedBy(m, 0.0);
  ASSERT_TRUE(calibration.has_value());
  EXPECT_DOUBLE_EQ(calibration->focal_px, 3666.666504);
  EXPECT_DOUBLE_EQ(calibration->cx_px, 2735.5);
  EXPECT_DOUBLE_EQ(calibration->cy_px, 1823.5);
  EXPECT_TRUE(calibration->distortion.empty());
  // The speeds are the rolling shutter's motion: x north, y east (DJI's
  // N-E-D); a camera the known-camera table lacks has no readout.
  const auto shutter = RollingShutterStatedBy(m);
  ASSERT_TRUE(shutter.has_value());
  EXPECT_DOUBLE_EQ(shutter->north_mps, 9.8);
  EXPECT_DOUBLE_EQ(shutter->east_mps, -0.3);
  EXPECT_EQ(shutter->readout_time_s, 0.0);
  EXPECT_NE(shutter->source.find("drone-dji:FlightXSpeed (north)"), std::string::npos) << shutter->source;
  EXPECT_NE(shutter->source.find("not in the known-camera table"), std::string::npos) << shutter->source;
  // A Phantom 4 Pro's camera is in it: 33 ms, its source named.
  WriteJpegWithExif(dir / "p4p.jpg", image, {{"EXIF_Make", "DJI"}, {"EXIF_Model", "FC6310"}}, 90, xmp);
  const auto p4p = RollingShutterStatedBy(ReadImageMetadata(dir / "p4p.jpg"));
  ASSERT_TRUE(p4p.has_value());
  EXPECT_DOUBLE_EQ(p4p->readout_time_s, 0.033);
  EXPECT_NE(p4p->source.find("33 ms for the DJI FC6310 from OpenDroneMap's rolling-shutter database"),
            std::string::npos)
      << p4p->source;
  // A malformed number is no number, not a guess.
  WriteJpegWithExif(dir / "bad.jpg", image, {{"EXIF_Make", "DJI"}}, 90,
                    "<x:xmpmeta xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\" drone-dji:FlightXSpeed=\"9.8m\"/>");
  EXPECT_FALSE(ReadImageMetadata(dir / "bad.jpg").flight_speed_x_mps.has_value());
}

// The known-camera readout table: matched on make and model whatever their
// case and spacing, a two-mode sensor by the capture's size, an unknown
// camera not guessed.
TEST(KnownCameraReadout, MatchesMakeAndModelAndTheSensorsMode) {
  const auto p4 = KnownCameraReadout("DJI", "FC330", 12.0);
  ASSERT_TRUE(p4.has_value());
  EXPECT_DOUBLE_EQ(p4->readout_time_s, 0.033);
  EXPECT_EQ(p4->camera, "DJI FC330");
  EXPECT_NE(p4->source.find("RSCalibration"), std::string::npos);
  const auto spaced = KnownCameraReadout(" dji ", "fc3170 ", 12.0);
  ASSERT_TRUE(spaced.has_value());
  EXPECT_DOUBLE_EQ(spaced->readout_time_s, 0.027);
  // Mavic 2 Pro: 16:10 (16.8 MP) against 3:2 (19.9 MP); Mini 3 Pro: 12 MP against 48 MP.
  EXPECT_DOUBLE_EQ(KnownCameraReadout("Hasselblad", "L1D-20c", 16.8)->readout_time_s, 0.047);
  EXPECT_DOUBLE_EQ(KnownCameraReadout("Hasselblad", "L1D-20c", 19.9)->readout_time_s, 0.056);
  EXPECT_DOUBLE_EQ(KnownCameraReadout("DJI", "FC3582", 12.0)->readout_time_s, 0.026);
  EXPECT_DOUBLE_EQ(KnownCameraReadout("DJI", "FC3582", 48.0)->readout_time_s, 0.060);
  EXPECT_FALSE(KnownCameraReadout("Parrot", "Sequoia", 16.0).has_value());
  EXPECT_FALSE(KnownCameraReadout("DJI", "FC63100", 20.0).has_value());
  EXPECT_FALSE(KnownCameraReadout("", "", 0.0).has_value());
}

// Found by tests/fuzz/fuzz_exif.cc: an EXIF_PixelXDimension of 1e12 was
// converted to int with undefined behaviour; a corrupt width is now ignored.
TEST(ImageMetadata, ImplausiblePixelWidthTagIsIgnored) {
  const auto path = std::filesystem::path(AEROTRI_SOURCE_DIR) / "tests/fuzz/regressions/exif/pixel_x_dimension_overflow.jpg";
  try {
    const ImageMetadata m = ReadImageMetadata(path);
    EXPECT_FALSE(m.exif_pixel_width.has_value());
  } catch (const IoError&) {
    // Refusing the file is as good: nothing was converted.
  }
}

TEST(GpsSources, Egm96AltitudesBecomeEllipsoidalHeights) {
  // expected: echo "46.5 7.5 0" | cs2cs EPSG:4979 EPSG:4326+5773 -> -50.0934 (N = 50.0934 m)
  EXPECT_NEAR(EllipsoidalHeight(46.5, 7.5, 500.0, AltitudeReference::kEgm96), 550.0934, 1e-3);
  EXPECT_DOUBLE_EQ(EllipsoidalHeight(46.5, 7.5, 500.0, AltitudeReference::kEllipsoid), 500.0);
}

TEST(GpsSources, CsvWithHeaderSigmasAndClearErrors) {
  testing::TempDir dir;
  std::ofstream(dir / "gps.csv") << "name,lat,lon,alt\n# comment\nA.JPG,46.5,7.5,500\nB.JPG;46.6;7.6;510;0.02;0.05\n";
  const auto fixes = ReadGpsFile(dir / "gps.csv", AltitudeReference::kEllipsoid, 3.0, 5.0);
  ASSERT_EQ(fixes.size(), 2u);
  EXPECT_DOUBLE_EQ(fixes.at("A.JPG").sigma_h_m, 3.0);
  EXPECT_DOUBLE_EQ(fixes.at("B.JPG").sigma_v_m, 0.05);
  EXPECT_DOUBLE_EQ(fixes.at("B.JPG").position.h_m, 510.0);
  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {"A.JPG,46.5,7.5\n", 1, "expected 4 or 6 fields"},
           {"name,lat,lon,alt\nA.JPG,95,7.5,500\n", 2, "expected lat in [-90, 90]"},
           {"A.JPG,46.5,x,500\n", 1, "expected a number for lon, got 'x'"},
           {"A.JPG,46.5,7.5,500\nA.JPG,46.5,7.5,500\n", 2, "appears twice"},
           {"A.JPG,46.5,7.5,500,0,1\n", 1, "expected positive sigmas"}}) {
    std::ofstream(dir / "bad.csv") << c.text;
    try {
      ReadGpsFile(dir / "bad.csv", AltitudeReference::kEllipsoid, 3.0, 5.0);
      ADD_FAILURE() << "accepted " << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
  }
}

// OpenDroneMap's geo.txt: a CRS line, then image x y z [angles] [accuracies].
// expected: echo "46.5 7.5 0" | cs2cs -d 4 EPSG:4326 EPSG:32632 -> 384902.8374 5150696.3462
//           echo "46.6 7.6 0" | cs2cs -d 4 EPSG:4326 EPSG:32632 -> 392773.0477 5161667.0443
TEST(GpsSources, OpenDroneMapGeoTxtInAnyCrs) {
  testing::TempDir dir;
  for (const std::string crs : {"EPSG:32632", "WGS84 UTM 32N", "+proj=utm +zone=32 +datum=WGS84 +units=m +no_defs"}) {
    std::ofstream(dir / "geo.txt") << "\xEF\xBB\xBF" << crs << "\r\n# comment\r\n"
                                   << "A.JPG 384902.8374 5150696.3462 500\r\n"
                                   << "B.JPG 392773.0477 5161667.0443 510 0 -90 12.5 0.02 0.05 label\r\n";
    const auto fixes = ReadGpsFile(dir / "geo.txt", AltitudeReference::kEllipsoid, 3.0, 5.0);
    ASSERT_EQ(fixes.size(), 2u) << crs;
    EXPECT_NEAR(fixes.at("A.JPG").position.lat_deg, 46.5, 1e-8) << crs;
    EXPECT_NEAR(fixes.at("A.JPG").position.lon_deg, 7.5, 1e-8) << crs;
    EXPECT_DOUBLE_EQ(fixes.at("A.JPG").position.h_m, 500.0);
    EXPECT_DOUBLE_EQ(fixes.at("A.JPG").sigma_h_m, 3.0);  // no accuracies: the defaults
    EXPECT_NEAR(fixes.at("B.JPG").position.lat_deg, 46.6, 1e-8);
    EXPECT_DOUBLE_EQ(fixes.at("B.JPG").sigma_h_m, 0.02);
    EXPECT_DOUBLE_EQ(fixes.at("B.JPG").sigma_v_m, 0.05);
    EXPECT_EQ(fixes.at("B.JPG").source, "geo.txt");
  }
  // Geographic: x is the longitude (OpenDroneMap's example). A 2D CRS leaves
  // geo_z an altitude in the reference asked for; a vertical datum converts
  // through PROJ (cs2cs EPSG:4979 EPSG:4326+5773 gives N = 50.0934 m here).
  std::ofstream(dir / "geo.txt") << "EPSG:4326\nA.JPG 7.5 46.5 500\n";
  EXPECT_NEAR(ReadGpsFile(dir / "geo.txt", AltitudeReference::kEgm96, 3.0, 5.0).at("A.JPG").position.h_m, 550.0934,
              1e-3);
  std::ofstream(dir / "geo.txt") << "EPSG:32632+5773\nA.JPG 384902.8374 5150696.3462 500\n";
  const GpsFix compound = ReadGpsFile(dir / "geo.txt", AltitudeReference::kEllipsoid, 3.0, 5.0).at("A.JPG");
  EXPECT_NEAR(compound.position.h_m, 550.0934, 1e-3);
  EXPECT_NEAR(compound.position.lat_deg, 46.5, 1e-8);
  // A local engineering frame: the file's own coordinates and unit, no
  // altitude reference applied.
  std::ofstream(dir / "geo.txt") << "LOCAL\nA.JPG 1000.5 2000.25 150\n";
  const GpsFix local = ReadGpsFile(dir / "geo.txt", AltitudeReference::kEgm96, 3.0, 5.0).at("A.JPG");
  ASSERT_TRUE(local.local_xyz.has_value());
  EXPECT_EQ(*local.local_xyz, Eigen::Vector3d(1000.5, 2000.25, 150.0));
  EXPECT_EQ(local.local_unit_m, 1.0);

  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {"EPSG:32632\nA.JPG 384902.8 5150696.3\n", 2, "aerotri needs each camera's height"},
           {"EPSG:32632\nA.JPG 384902.8 5150696.3 500 0 0 0 0.02\n", 2, "expected both horz_accuracy"},
           {"EPSG:32632\nA.JPG 384902.8 north 500\n", 2, "expected a number for geo_y (column 3), got 'north'"},
           {"EPSG:32632\nA.JPG 384902.8 5150696.3 500 0 0 0 0 0.05\n", 2, "expected positive accuracies"},
           {"EPSG:32632\nA.JPG 1 2 3\nA.JPG 1 2 3\n", 3, "appears twice"}}) {
    std::ofstream(dir / "bad.txt") << c.text;
    try {
      ReadGpsFile(dir / "bad.txt", AltitudeReference::kEllipsoid, 3.0, 5.0);
      ADD_FAILURE() << "accepted " << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    }
  }
}

TEST(ExifIntrinsics, FallsBackInOrderAndSaysSo) {
  ExifOptics o;
  o.width = 3600;
  o.height = 2700;
  o.focal_mm = 4.3;
  o.focal_plane_px_per_mm = 16393.4 / 25.4;  // Canon ELPH 300 HS, 4000 px wide originally
  o.exif_pixel_width = 4000;
  EXPECT_NEAR(FocalFromExif(o).focal_px, 4.3 * 16393.4 / 25.4 * 0.9, 1e-9);
  // The pitch of the stored (resized) image: 1 / (645.4 px/mm) at 4000 px wide, x 4000 / 3600.
  EXPECT_NEAR(FocalFromExif(o).pixel_size_mm, 25.4 / 16393.4 / 0.9, 1e-12);
  o.focal_plane_px_per_mm.reset();
  o.focal_35mm = 24;
  EXPECT_NEAR(FocalFromExif(o).focal_px, 24.0 / 36.0 * 3600, 1e-9);
  EXPECT_EQ(FocalFromExif(o).pixel_size_mm, 0.0);  // a 35 mm equivalent states no sensor
  o.focal_35mm.reset();
  o.focal_mm.reset();
  const FocalEstimate guess = FocalFromExif(o);
  EXPECT_NEAR(guess.focal_px, 0.85 * 3600, 1e-9);
  EXPECT_NE(guess.source.find("assumed"), std::string::npos);
}

// Runs f, which must throw E with `text` in its message.
template <typename E, typename F>
void ExpectThrowWith(F f, const std::string& text) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one saying: " << text;
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

// The ingest stage as a module: photos in, a typed record out, the record
// through ingest.json and back unchanged; a schema-1 record's focal prior
// decided as before; a corrupt record refused naming the file.
TEST(IngestStage, TruncatedJpegAndSymlinkLoopAreSkippedWithTheirNames) {
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "photos");
  cv::Mat image(300, 400, CV_8UC3);
  cv::randu(image, 0, 255);
  WriteJpegWithExif(dir / "photos" / "whole.jpg", image, {{"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}});
  WriteJpegWithExif(dir / "photos" / "cut.jpg", image, {{"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}});
  WriteJpegWithExif(dir / "photos" / "padded.jpg", image, {{"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}});
  const auto size = std::filesystem::file_size(dir / "photos" / "cut.jpg");
  std::filesystem::resize_file(dir / "photos" / "cut.jpg", size * 2 / 3);
  std::ofstream(dir / "photos" / "padded.jpg", std::ios::app | std::ios::binary) << std::string(100, '\0');
  // A symbolic link loop among the photos: said and skipped, never fatal.
  std::filesystem::create_symlink("loop.jpg", dir / "photos" / "loop.jpg");
  IngestOptions o;
  o.images_dir = dir / "photos";
  const IngestRecord r = IngestSurveyImages(o, nullptr);
  ASSERT_EQ(r.images.size(), 3u);
  std::map<std::string, IngestedImage> by_name;
  for (const auto& im : r.images) by_name[im.name] = im;
  EXPECT_TRUE(by_name["whole.jpg"].usable);
  EXPECT_TRUE(by_name["padded.jpg"].usable) << by_name["padded.jpg"].problem;
  EXPECT_FALSE(by_name["cut.jpg"].usable);
  EXPECT_NE(by_name["cut.jpg"].problem.find("truncated JPEG"), std::string::npos);
  std::string warnings;
  for (const auto& w : r.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find("cut.jpg: truncated JPEG: it does not end with the end-of-image marker FF D9"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("loop.jpg: Too many levels of symbolic links (a symbolic link loop"), std::string::npos)
      << warnings;
}

// DJI's calibrated focal length and optical centre start the camera group
// where they agree with the EXIF-measured focal length (FC300S: 3.61 mm on
// a 6.17 mm sensor, 234.0 px across 400 px); one tenfold off (another image
// size) is said and not used.
TEST(IngestStage, DjiCalibratedFocalLengthStartsTheGroupUnlessItContradictsExif) {
  testing::TempDir dir;
  cv::Mat image(300, 400, CV_8UC3, cv::Scalar(40, 120, 200));
  auto ingest = [&](const std::string& folder, double stated_f) {
    std::filesystem::create_directories(dir / folder);
    char xmp[400];
    std::snprintf(xmp, sizeof xmp,
                  "<x:xmpmeta xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\" "
                  "drone-dji:CalibratedFocalLength=\"%.3f\" drone-dji:CalibratedOpticalCenterX=\"203.0\" "
                  "drone-dji:CalibratedOpticalCenterY=\"148.0\"/>",
                  stated_f);
    WriteJpegWithExif(dir / folder / "a.jpg", image,
                      {{"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}, {"EXIF_FocalLength", "(3.61)"}}, 90, xmp);
    IngestOptions o;
    o.images_dir = dir / folder;
    o.max_dimension = 200;
    return IngestSurveyImages(o, nullptr);
  };
  const IngestRecord agrees = ingest("agrees", 236.0);
  ASSERT_EQ(agrees.groups.size(), 1u);
  EXPECT_TRUE(agrees.groups[0].calibration_stated);
  EXPECT_DOUBLE_EQ(agrees.groups[0].camera.params[0], 118.0);  // at half the size
  EXPECT_DOUBLE_EQ(agrees.groups[0].camera.params[1], 101.0);  // 203 from the corner: 203 / 2 - 0.5
  EXPECT_DOUBLE_EQ(agrees.groups[0].camera.params[2], 73.5);    // 148 / 2 - 0.5
  const IngestRecord contradicts = ingest("contradicts", 2360.0);
  EXPECT_FALSE(contradicts.groups[0].calibration_stated);
  EXPECT_NEAR(contradicts.groups[0].camera.params[0], 3.61 / 6.17 * 200, 0.01);
  bool said = false;
  for (const std::string& w : contradicts.warnings) said |= w.find("2360.0 px") != std::string::npos;
  EXPECT_TRUE(said);
}

TEST(IngestStage, TypedRecordRoundTripsAndRefusesCorruptFiles) {
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "photos");
  cv::Mat image(300, 400, CV_8UC3, cv::Scalar(40, 120, 200));
  std::map<std::string, std::string> exif = {
      {"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"},
      {"EXIF_GPSLatitude", ExifDms(46.842609)}, {"EXIF_GPSLatitudeRef", "N"},
      {"EXIF_GPSLongitude", ExifDms(91.994561)}, {"EXIF_GPSLongitudeRef", "W"},
      {"EXIF_GPSAltitude", "(198.309)"}, {"EXIF_GPSAltitudeRef", "0x00"},
      {"EXIF_FocalLength", "(3.61)"}};
  WriteJpegWithExif(dir / "photos" / "a.jpg", image, exif);
  WriteJpegWithExif(dir / "photos" / "b.jpg", image, {});  // no EXIF: joins a's group
  IngestOptions o;
  o.images_dir = dir / "photos";
  o.max_dimension = 200;
  o.gps_altitude = AltitudeReference::kEllipsoid;
  const IngestRecord r = IngestSurveyImages(o, nullptr);
  ASSERT_EQ(r.images.size(), 2u);
  ASSERT_EQ(r.groups.size(), 1u);
  EXPECT_EQ(r.images[0].working_width, 200);
  EXPECT_EQ(r.images[0].working_height, 150);
  EXPECT_DOUBLE_EQ(r.images[0].scale, 2.0);
  ASSERT_TRUE(r.images[0].gps.has_value());
  EXPECT_NEAR(r.images[0].gps->position.h_m, 198.309, 1e-3);
  EXPECT_DOUBLE_EQ(r.images[0].gps->sigma_h_m, kDefaultGpsSigmaH);
  EXPECT_FALSE(r.images[1].gps.has_value());
  EXPECT_EQ(r.images[1].group, 0);
  EXPECT_EQ(r.groups[0].images, 2);
  EXPECT_TRUE(r.groups[0].focal_measured);  // 3.61 mm on the known 6.17 mm sensor
  // 3.61 / 6.17 x 200 working px.
  EXPECT_NEAR(r.groups[0].camera.focal_px(), 3.61 / 6.17 * 200, 1e-6);

  const nlohmann::json doc = ToJson(r);
  EXPECT_EQ(doc.at("schema_version"), IngestRecord::kSchemaVersion);
  EXPECT_EQ(ToJson(IngestRecordFromJson(doc, "ingest.json")), doc);

  nlohmann::json legacy = doc;  // schema 1: no version, no focal_measured
  legacy.erase("schema_version");
  legacy["groups"][0].erase("focal_measured");
  legacy["groups"][0]["focal_source"] = "EXIF 35 mm equivalent focal length 20 mm over a 36 mm frame width";
  EXPECT_FALSE(IngestRecordFromJson(legacy, "ingest.json").groups[0].focal_measured);
  legacy["groups"][0]["focal_source"] = "EXIF focal length 3.61 mm, known sensor width 6.17 mm";
  EXPECT_TRUE(IngestRecordFromJson(legacy, "ingest.json").groups[0].focal_measured);

  nlohmann::json bad = doc;
  bad["images"][0]["group"] = 7;
  ExpectThrowWith<ParseError>([&] { IngestRecordFromJson(bad, "WS/ingest.json"); }, "WS/ingest.json: image 'a.jpg' names camera group 7 of 1");
  bad = doc;
  bad["groups"][0].erase("params");
  ExpectThrowWith<ParseError>([&] { IngestRecordFromJson(bad, "WS/ingest.json"); }, "WS/ingest.json: not a complete ingest record");
  bad = doc;
  bad["schema_version"] = 99;
  ExpectThrowWith<ParseError>([&] { IngestRecordFromJson(bad, "WS/ingest.json"); }, "schema_version 99");

  // A GPS CSV: its names must be the photos' file names; one that matches
  // nothing is a warning, a file that matches no photo an error.
  std::ofstream(dir / "gps.csv") << "b.jpg,46.84,-91.99,200\nc.jpg,46.84,-91.99,201\n";
  o.gps_csv = dir / "gps.csv";
  const IngestRecord with_csv = IngestSurveyImages(o, nullptr);
  ASSERT_TRUE(with_csv.images[1].gps.has_value());
  EXPECT_NEAR(with_csv.images[1].gps->position.h_m, 200.0, 1e-9);
  EXPECT_NE(std::find(with_csv.warnings.begin(), with_csv.warnings.end(),
                      (dir / "gps.csv").string() + ": 1 of 2 names match no photo: 'c.jpg'"),
            with_csv.warnings.end());
  std::ofstream(dir / "gps.csv") << "IMG_1.JPG,46.84,-91.99,200\n";
  ExpectThrowWith<InvalidArgument>([&] { IngestSurveyImages(o, nullptr); },
                                   "gps.csv: none of its 1 names ('IMG_1.JPG') is a photo in");

  o.gps_sigma_v_m = 0.0;
  ExpectThrowWith<InvalidArgument>([&] { o.Check(); }, "--gps-sigma-v: expected a positive number");
}

// A photo without GPS among photos with it is named; a set flown without
// GPS is one warning, not one per photo.
TEST(IngestStage, PhotosWithoutGpsAreOneWarningWhenNoneHasIt) {
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "some");
  std::filesystem::create_directories(dir / "none");
  const cv::Mat image(300, 400, CV_8UC3, cv::Scalar(40, 120, 200));
  const std::map<std::string, std::string> gps = {
      {"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}, {"EXIF_FocalLength", "(3.61)"},
      {"EXIF_GPSLatitude", ExifDms(46.842609)}, {"EXIF_GPSLatitudeRef", "N"},
      {"EXIF_GPSLongitude", ExifDms(91.994561)}, {"EXIF_GPSLongitudeRef", "W"},
      {"EXIF_GPSAltitude", "(198.309)"}, {"EXIF_GPSAltitudeRef", "0x00"}};
  const std::map<std::string, std::string> no_gps = {
      {"EXIF_Make", "DJI"}, {"EXIF_Model", "FC300S"}, {"EXIF_FocalLength", "(3.61)"}};
  WriteJpegWithExif(dir / "some" / "a.jpg", image, gps);
  for (const char* name : {"b.jpg", "c.jpg"}) {
    WriteJpegWithExif(dir / "some" / name, image, no_gps);
    WriteJpegWithExif(dir / "none" / name, image, no_gps);
  }
  WriteJpegWithExif(dir / "none" / "d.jpg", image, no_gps);
  IngestOptions o;
  o.images_dir = dir / "some";
  const IngestRecord some = IngestSurveyImages(o, nullptr);
  const auto has = [](const IngestRecord& r, const std::string& w) {
    return std::find(r.warnings.begin(), r.warnings.end(), w) != r.warnings.end();
  };
  EXPECT_TRUE(has(some, "b.jpg: no GPS position (EXIF or CSV)"));
  EXPECT_TRUE(has(some, "c.jpg: no GPS position (EXIF or CSV)"));
  o.images_dir = dir / "none";
  const IngestRecord none = IngestSurveyImages(o, nullptr);
  EXPECT_EQ(none.warnings.size(), 1u);
  EXPECT_TRUE(has(none, "none of the 3 photos has a GPS position (EXIF or CSV): the survey is placed by its control "
                        "alone, or not at all"));
}

}  // namespace
}  // namespace aerotri
