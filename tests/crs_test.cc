// SPDX-License-Identifier: BSD-3-Clause
#include "georef/crs.h"

#include <gtest/gtest.h>

#include "libphoto/base/error.h"

namespace aerotri {
namespace {

// cs2cs -f %.4f prints 0.1 mm.
constexpr double kToolToleranceM = 1e-4;

TEST(Crs, ProjectedMatchesCs2cs) {
  // expected: echo "46.5 7.5 500" | cs2cs -f %.4f EPSG:4979 EPSG:32632
  const Crs utm = Crs::FromString("EPSG:32632");
  const Eigen::Vector3d xyz = utm.FromGeodetic({46.5, 7.5, 500.0});
  EXPECT_NEAR(xyz.x(), 384902.8374, kToolToleranceM);
  EXPECT_NEAR(xyz.y(), 5150696.3462, kToolToleranceM);
  EXPECT_NEAR(xyz.z(), 500.0, kToolToleranceM);  // 2D CRS: ellipsoidal height kept
  EXPECT_FALSE(utm.IsGeographic());
  EXPECT_FALSE(utm.HasVerticalDatum());
  const Geodetic back = utm.ToGeodetic(xyz);
  EXPECT_NEAR(back.lat_deg, 46.5, 1e-10);
  EXPECT_NEAR(back.lon_deg, 7.5, 1e-10);
}

TEST(Crs, CompoundCrsGivesGeoidHeights) {
  // expected: echo "46.5 7.5 500" | cs2cs -f %.4f EPSG:4979 EPSG:32632+5773
  const Crs compound = Crs::FromString("EPSG:32632+5773");
  EXPECT_TRUE(compound.HasVerticalDatum());
  const Eigen::Vector3d xyz = compound.FromGeodetic({46.5, 7.5, 500.0});
  EXPECT_NEAR(xyz.x(), 384902.8374, kToolToleranceM);
  EXPECT_NEAR(xyz.y(), 5150696.3462, kToolToleranceM);
  EXPECT_NEAR(xyz.z(), 449.9066, kToolToleranceM);
  // expected: echo "44.9 -93.2 200" | cs2cs -f %.4f EPSG:4979 EPSG:32615+5773
  const Eigen::Vector3d mn = Crs::FromString("EPSG:32615+5773").FromGeodetic({44.9, -93.2, 200.0});
  EXPECT_NEAR(mn.x(), 484209.5454, kToolToleranceM);
  EXPECT_NEAR(mn.y(), 4971861.2190, kToolToleranceM);
  EXPECT_NEAR(mn.z(), 228.0508, kToolToleranceM);
  const Geodetic back = compound.ToGeodetic(xyz);
  EXPECT_NEAR(back.h_m, 500.0, 1e-3);
}

TEST(Crs, ProjStringAndEpsgAgree) {
  const Eigen::Vector3d a = Crs::FromString("EPSG:32632").FromGeodetic({46.5, 7.5, 500.0});
  const Eigen::Vector3d b =
      Crs::FromString("+proj=utm +zone=32 +datum=WGS84").FromGeodetic({46.5, 7.5, 500.0});
  EXPECT_LT((a - b).norm(), 1e-6);
  const Crs wkt = Crs::FromString(Crs::FromString("EPSG:32632").Wkt());
  EXPECT_LT((wkt.FromGeodetic({46.5, 7.5, 500.0}) - a).norm(), 1e-6);
}

TEST(Crs, GeographicUsesLongitudeLatitudeOrder) {
  const Crs wgs84 = Crs::FromString("EPSG:4326");
  EXPECT_TRUE(wgs84.IsGeographic());
  const Eigen::Vector3d xyz = wgs84.FromGeodetic({46.5, 7.5, 500.0});
  EXPECT_NEAR(xyz.x(), 7.5, 1e-12);
  EXPECT_NEAR(xyz.y(), 46.5, 1e-12);
}

TEST(Crs, UtmZoneFromPosition) {
  EXPECT_EQ(Crs::UtmFor({46.5, 7.5, 0}).definition(), "EPSG:32632");
  EXPECT_EQ(Crs::UtmFor({44.9, -93.2, 0}).definition(), "EPSG:32615");
  // expected: echo "-33.9 151.2 30" | cs2cs -f %.4f EPSG:4979 EPSG:32756
  const Crs south = Crs::UtmFor({-33.9, 151.2, 30.0});
  EXPECT_EQ(south.definition(), "EPSG:32756");
  const Eigen::Vector3d xyz = south.FromGeodetic({-33.9, 151.2, 30.0});
  EXPECT_NEAR(xyz.x(), 333568.9410, kToolToleranceM);
  EXPECT_NEAR(xyz.y(), 6247473.3368, kToolToleranceM);
  EXPECT_EQ(Crs::UtmFor({60.5, 5.0, 0}).definition(), "EPSG:32632");  // Norway exception
}

TEST(Crs, BadDefinitionsAreRefusedClearly) {
  try {
    Crs::FromString("EPSG:999999");
    FAIL() << "accepted an unknown EPSG code";
  } catch (const CrsError& e) {
    EXPECT_NE(std::string(e.what()).find("EPSG:999999"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Crs::FromString("not a crs"), CrsError);
  EXPECT_THROW(Crs::FromString("EPSG:5773"), CrsError);  // vertical only
}

}  // namespace
}  // namespace aerotri

namespace aerotri {
namespace {

// Local engineering frames: "LOCAL" and engineering CRS WKT (WKT2 ENGCRS, WKT1
// LOCAL_CS) are Cartesian frames in their own unit, converted exactly through
// the stand-in tangent plane (no curvature, no projection).
TEST(Crs, LocalEngineeringFramesAreExactCartesian) {
  const Crs local = Crs::FromString("local");
  EXPECT_TRUE(local.IsLocal());
  EXPECT_FALSE(local.IsGeographic());
  EXPECT_DOUBLE_EQ(local.LocalUnitMetres(), 1.0);
  const Crs at = local.LocalAt({1000.0, 2000.0, 100.0});
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(1000, 2000, 100), Eigen::Vector3d(1730.25, 1520.5, 161.75)}) {
    const Eigen::Vector3d back = at.FromGeodetic(at.ToGeodetic(x));
    EXPECT_LT((back - x).norm(), 1e-8);
    // Distances are the file's: on the stand-in's tangent plane.
    const LocalFrame frame(Crs::LocalGeodeticOrigin());
    EXPECT_LT((frame.EnuFromGeodetic(at.ToGeodetic(x)) - (x - Eigen::Vector3d(1000, 2000, 100))).norm(), 1e-8);
  }
  // Its WKT is an engineering CRS that PROJ reads back as one.
  EXPECT_TRUE(Crs::FromString(local.Wkt()).IsLocal());
  EXPECT_TRUE(Crs::FromString(local.WktV1()).IsLocal());
  const Crs feet = Crs::FromString(
      "ENGCRS[\"site grid\",EDATUM[\"site\"],CS[Cartesian,3],"
      "AXIS[\"x\",east,ORDER[1],LENGTHUNIT[\"US survey foot\",0.304800609601219]],"
      "AXIS[\"y\",north,ORDER[2],LENGTHUNIT[\"US survey foot\",0.304800609601219]],"
      "AXIS[\"z\",up,ORDER[3],LENGTHUNIT[\"US survey foot\",0.304800609601219]]]");
  EXPECT_TRUE(feet.IsLocal());
  EXPECT_NEAR(feet.LocalUnitMetres(), 0.304800609601219, 1e-15);
  const Crs feet_at = feet.LocalAt(Eigen::Vector3d::Zero());
  const LocalFrame frame(Crs::LocalGeodeticOrigin());
  EXPECT_NEAR(frame.EnuFromGeodetic(feet_at.ToGeodetic({100.0, 0.0, 0.0})).x(), 30.4800609601219, 1e-8);
  EXPECT_TRUE(Crs::FromString("EPSG:4978").IsGeocentric());
}

}  // namespace
}  // namespace aerotri
