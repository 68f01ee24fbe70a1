// SPDX-License-Identifier: BSD-3-Clause
#include "georef/local_frame.h"

#include <gtest/gtest.h>

#include "libphoto/base/error.h"

namespace aerotri {
namespace {

// CartConvert prints 6 decimals: 1 µm.
constexpr double kToolToleranceM = 2e-6;

TEST(LocalFrame, MatchesCartConvertEnu) {
  // expected: echo "46.501 7.502 520" | CartConvert -l 46.5 7.5 500 -p 6
  const LocalFrame frame({46.5, 7.5, 500.0});
  const Eigen::Vector3d enu = frame.EnuFromGeodetic({46.501, 7.502, 520.0});
  EXPECT_NEAR(enu.x(), 153.534866, kToolToleranceM);
  EXPECT_NEAR(enu.y(), 111.172113, kToolToleranceM);
  EXPECT_NEAR(enu.z(), 19.997185, kToolToleranceM);
  const Geodetic back = frame.GeodeticFromEnu(enu);
  EXPECT_NEAR(back.lat_deg, 46.501, 1e-11);
  EXPECT_NEAR(back.lon_deg, 7.502, 1e-11);
  EXPECT_NEAR(back.h_m, 520.0, 1e-6);
}

TEST(LocalFrame, MatchesCartConvertEcef) {
  // expected: echo "46.5 7.5 500" | CartConvert -p 6
  const Eigen::Vector3d ecef = LocalFrame::EcefFromGeodetic({46.5, 7.5, 500.0});
  EXPECT_NEAR(ecef.x(), 4360886.869925, kToolToleranceM);
  EXPECT_NEAR(ecef.y(), 574121.648122, kToolToleranceM);
  EXPECT_NEAR(ecef.z(), 4604043.085831, kToolToleranceM);
  const LocalFrame frame({46.5, 7.5, 500.0});
  EXPECT_LT(frame.EnuFromEcef(ecef).norm(), 1e-6);
  EXPECT_LT((frame.EcefFromEnu(Eigen::Vector3d::Zero()) - ecef).norm(), 1e-6);
}

TEST(LocalFrame, RefusesAnImpossibleOrigin) {
  EXPECT_THROW(LocalFrame({91.0, 0.0, 0.0}), InvalidArgument);
  EXPECT_THROW(LocalFrame({0.0, std::nan(""), 0.0}), InvalidArgument);
}

}  // namespace
}  // namespace aerotri
