// SPDX-License-Identifier: BSD-3-Clause
// matches.bin against the features it indexes: a stale or bit-flipped file is
// refused with a message naming it, never read out of bounds.
#include "libphoto/matching/matching.h"

#include <gtest/gtest.h>

#include "libphoto/base/error.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

std::vector<ImageFeatures> TwoImages(int a, int b) {
  std::vector<ImageFeatures> f(2);
  f[0].keypoints.resize(a);
  f[1].keypoints.resize(b);
  return f;
}

std::string MessageOf(const std::vector<PairMatches>& m, const std::vector<ImageFeatures>& f) {
  try {
    ValidateMatches(m, f, "ws/matches.bin");
  } catch (const ParseError& e) {
    return e.what();
  }
  return "";
}

TEST(Matches, RoundTripAndValidate) {
  testing::TempDir dir;
  PairMatches m;
  m.i = 0;
  m.j = 1;
  m.putative = 9;
  m.inliers = {{0, 2}, {4, 0}};
  WriteMatches({m}, dir / "matches.bin");
  const std::vector<PairMatches> back = ReadMatches(dir / "matches.bin");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].inliers, m.inliers);
  EXPECT_NO_THROW(ValidateMatches(back, TwoImages(5, 3), dir / "matches.bin"));
}

TEST(Matches, StaleFeatureIndicesAreRefusedWithTheFileAndTheFix) {
  PairMatches m;
  m.i = 0;
  m.j = 1;
  m.inliers = {{0, 2}, {4, 0}};
  // Features re-extracted with fewer keypoints: feature 4 of image 0 is gone.
  const std::string message = MessageOf({m}, TwoImages(3, 3));
  EXPECT_NE(message.find("ws/matches.bin"), std::string::npos) << message;
  EXPECT_NE(message.find("refers to features 4 and 0 but the images have 3 and 3"), std::string::npos) << message;
  EXPECT_NE(message.find("aerotri match --force"), std::string::npos) << message;
  m.inliers = {{0, -7}};
  EXPECT_FALSE(MessageOf({m}, TwoImages(3, 3)).empty());
}

TEST(Matches, ImageIndicesOutsideTheSurveyAreRefused) {
  PairMatches m;
  m.i = 0;
  m.j = 7;
  EXPECT_NE(MessageOf({m}, TwoImages(3, 3)).find("joins images 0 and 7"), std::string::npos);
  m.j = 0;
  EXPECT_FALSE(MessageOf({m}, TwoImages(3, 3)).empty());
}

}  // namespace
}  // namespace aerotri
