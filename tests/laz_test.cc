// SPDX-License-Identifier: BSD-3-Clause
// LAZ as aerotri writes and reads it (libphoto/export/laz.h). The independent
// decoder's check is tests/las/check_laz.mjs (laz-perf); here: the round trip
// through aerotri's own decoder for every field, chunk sizes from one point
// up, whole files against LAS, and files cut short.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <algorithm>
#include <random>
#include <tuple>

#include "libphoto/base/error.h"
#include "libphoto/export/copc.h"
#include "libphoto/export/laz.h"
#include "libphoto/export/point_cloud.h"
#include "tests/las/laz_records.h"
#include "tests/test_util.h"

namespace aerotri {
namespace {

std::vector<std::uint8_t> RoundTrip(int format, const std::vector<std::uint8_t>& records, std::uint32_t n) {
  const std::size_t size = format == 7 ? 36 : 30;
  std::vector<std::uint8_t> packed;  // format 6: the first 30 bytes of each record
  for (std::uint32_t i = 0; i < n; ++i) packed.insert(packed.end(), &records[i * 36], &records[i * 36] + size);
  const std::vector<std::uint8_t> chunk = laz::CompressChunk(format, packed.data(), n);
  laz::ChunkDecoder decoder(format, chunk.data(), chunk.size(), "chunk");
  EXPECT_EQ(decoder.points(), n);
  std::vector<std::uint8_t> back(packed.size());
  for (std::uint32_t i = 0; i < n; ++i) decoder.Next(back.data() + i * size);
  EXPECT_EQ(back, packed);
  return chunk;
}

TEST(Laz, EveryFieldOfEveryRecordComesBackAsItWas) {
  const std::vector<std::uint8_t> records = test::LidarLikeRecords(60000, 11);
  for (std::uint32_t n : {1u, 2u, 3u, 100u, 50000u}) {
    SCOPED_TRACE(n);
    RoundTrip(7, records, n);
    RoundTrip(6, records, n);
  }
}

TEST(Laz, ACloudOfConstantFieldsCompressesToAFewBytesAPoint) {
  // aerotri's own records: returns 1 of 1, no intensity or time, classes and colour.
  std::vector<std::uint8_t> records(36 * 20000, 0);
  std::mt19937 rng(3);
  for (std::uint32_t i = 0; i < 20000; ++i) {
    std::uint8_t* b = &records[i * 36];
    const std::int32_t xyz[3] = {static_cast<std::int32_t>(i % 200) * 50, static_cast<std::int32_t>(i / 200) * 50,
                                 static_cast<std::int32_t>(rng() % 30)};
    std::memcpy(b, xyz, 12);
    b[14] = 0x11;
    b[16] = i % 50 == 0 ? 2 : 1;
    const std::uint16_t rgb[3] = {static_cast<std::uint16_t>(257 * (100 + i % 7)), 257 * 90, 257 * 80};
    std::memcpy(b + 30, rgb, 6);
  }
  const std::vector<std::uint8_t> chunk = RoundTrip(7, records, 20000);
  // Layers that never change are left out: the chunk holds XY, Z, classes and red.
  EXPECT_LT(chunk.size(), 20000u * 6);
  EXPECT_GT(chunk.size(), 20000u / 2);
}

TEST(Laz, ChunkTableRoundTripsFixedAndVariableSizes) {
  std::vector<laz::Chunk> chunks = {{50000, 812345}, {50000, 790001}, {1234, 2000}};
  for (bool variable : {false, true}) {
    const std::vector<std::uint8_t> table = laz::EncodeChunkTable(chunks, variable);
    const std::vector<laz::Chunk> back = laz::DecodeChunkTable(
        table.data(), table.size(), variable ? laz::kVariableChunkSize : 50000, 101234, "table");
    ASSERT_EQ(back.size(), chunks.size());
    for (std::size_t i = 0; i < chunks.size(); ++i) {
      EXPECT_EQ(back[i].points, chunks[i].points);
      EXPECT_EQ(back[i].bytes, chunks[i].bytes);
    }
  }
}

CrsCloud SomeCloud(std::size_t n) {
  CrsCloud cloud;
  cloud.crs_wkt = "LOCAL_CS[\"test\"]";
  std::mt19937 rng(5);
  for (std::size_t i = 0; i < n; ++i) {
    cloud.xyz.emplace_back(500000.0 + 0.05 * static_cast<double>(i % 1000), 4000000.0 + 0.05 * static_cast<double>(i / 1000),
                           100.0 + 0.001 * static_cast<double>(rng() % 5000));
    cloud.rgb.push_back({static_cast<std::uint8_t>(rng() % 256), static_cast<std::uint8_t>(i % 256), 7});
    cloud.classes.push_back(static_cast<std::uint8_t>(i % 3 == 0 ? 2 : 1));
  }
  return cloud;
}

TEST(Laz, FileReadsBackAsTheLasOfTheSameCloud) {
  const testing::TempDir dir;
  const CrsCloud cloud = SomeCloud(120001);  // three chunks, the last of one point... and a half
  WriteLas(cloud, dir / "c.las");
  WriteLas(cloud, dir / "c.laz");
  const CrsCloud las = ReadLas(dir / "c.las"), laz = ReadLas(dir / "c.laz");
  ASSERT_EQ(laz.xyz.size(), cloud.xyz.size());
  EXPECT_EQ(laz.crs_wkt, las.crs_wkt);
  for (std::size_t i = 0; i < las.xyz.size(); ++i) {
    ASSERT_EQ(laz.xyz[i], las.xyz[i]) << i;
    ASSERT_EQ(laz.rgb[i], las.rgb[i]) << i;
    ASSERT_EQ(laz.classes[i], las.classes[i]) << i;
  }
  // In batches that straddle chunks too.
  std::size_t seen = 0;
  ReadLasInBatches(dir / "c.laz", [&](CrsCloud&& batch) {
    for (std::size_t i = 0; i < batch.xyz.size(); ++i) ASSERT_EQ(batch.xyz[i], las.xyz[seen + i]);
    seen += batch.xyz.size();
  }, 33333);
  EXPECT_EQ(seen, las.xyz.size());
  EXPECT_LT(std::filesystem::file_size(dir / "c.laz"), std::filesystem::file_size(dir / "c.las") / 3);
}

TEST(Laz, AFileCutShortIsAnErrorWhereverItIsCut) {
  const testing::TempDir dir;
  WriteLas(SomeCloud(60000), dir / "c.laz");
  std::ifstream in(dir / "c.laz", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (double at : {0.05, 0.3, 0.6, 0.9, 0.999}) {
    SCOPED_TRACE(at);
    const auto keep = static_cast<std::size_t>(at * static_cast<double>(bytes.size()));
    std::ofstream(dir / "cut.laz", std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(keep));
    EXPECT_THROW(ReadLas(dir / "cut.laz"), ParseError);
  }
}

TEST(Laz, ARecordOfAnotherScannerChannelIsRefused) {
  std::vector<std::uint8_t> records = test::LidarLikeRecords(10, 2);
  records[36 * 4 + 15] |= 0x10;  // channel 1
  laz::ChunkEncoder encoder(7);
  for (int i = 0; i < 10; ++i) {
    if (i == 4) {
      EXPECT_THROW(encoder.Add(&records[36 * i]), InvalidArgument);
    } else {
      encoder.Add(&records[36 * i]);
    }
  }
}

// COPC through aerotri's own reader (the chunk table of varying chunks,
// the EVLR after it), with the records spilled to the scratch file on the
// way: the same points as the cloud, each once, in octree order.
TEST(Copc, ReadsBackAsTheSamePointsEachOnceWithTheRecordsSpilledOnTheWay) {
  const testing::TempDir dir;
  const CrsCloud cloud = SomeCloud(250000);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& p : cloud.xyz) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  CopcWriter writer(dir / "c.copc.laz", cloud.xyz.size(), lo, hi, cloud.crs_wkt, 1 << 20);
  EXPECT_EQ(writer.leaf_level(), 2);  // 250,000 points: leaves of about 16,000 over a surface
  for (std::size_t i = 0; i < cloud.xyz.size(); ++i) writer.Add(cloud.xyz[i], cloud.rgb[i], cloud.classes[i]);
  EXPECT_FALSE(std::filesystem::exists(dir / "c.copc.laz"));  // not before Commit
  writer.Commit();
  // A COPC name is CopcWriter's: LasWriter would write plain LAZ under it.
  EXPECT_THROW(LasWriter(dir / "x.copc.laz", 1, lo, hi, ""), InvalidArgument);
  WriteLas(cloud, dir / "c.las");
  const CrsCloud las = ReadLas(dir / "c.las"), copc = ReadLas(dir / "c.copc.laz");
  EXPECT_EQ(copc.crs_wkt, las.crs_wkt);
  auto sorted = [](const CrsCloud& c) {
    std::vector<std::tuple<double, double, double, int, int>> v;
    for (std::size_t i = 0; i < c.xyz.size(); ++i) v.emplace_back(c.xyz[i].x(), c.xyz[i].y(), c.xyz[i].z(), c.rgb[i][0], c.classes[i]);
    std::sort(v.begin(), v.end());
    return v;
  };
  EXPECT_EQ(sorted(copc), sorted(las));
  EXPECT_NE(copc.xyz, las.xyz);  // reordered into the octree
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(e.path().string().find(".points"), std::string::npos) << "scratch left: " << e.path();
  }
}

}  // namespace
}  // namespace aerotri
