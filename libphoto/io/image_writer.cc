// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/image_writer.h"

#include <gdal_priv.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {

std::string ExifDms(double degrees) {
  double a = std::abs(degrees);
  int d = static_cast<int>(std::floor(a));
  int m = static_cast<int>(std::floor((a - d) * 60.0));
  double s = (a - d - m / 60.0) * 3600.0;
  char buf[64];
  std::snprintf(buf, sizeof(buf), "(%d) (%d) (%.4f)", d, m, s);
  return buf;
}

std::string DjiGimbalXmp(double pitch_deg, double yaw_deg, double roll_deg) {
  char text[512];
  std::snprintf(text, sizeof text,
                "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF "
                "xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\"><rdf:Description rdf:about=\"\" "
                "xmlns:drone-dji=\"http://www.dji.com/drone-dji/1.0/\" drone-dji:GimbalRollDegree=\"%+.2f\" "
                "drone-dji:GimbalYawDegree=\"%+.2f\" drone-dji:GimbalPitchDegree=\"%+.2f\"/></rdf:RDF></x:xmpmeta>",
                roll_deg, yaw_deg, pitch_deg);
  return text;
}

std::string RollingShutterXmp(double readout_time_s, const Eigen::Vector3d& velocity_enu_mps) {
  char text[512];
  std::snprintf(text, sizeof text,
                "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF "
                "xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\"><rdf:Description rdf:about=\"\" "
                "xmlns:Camera=\"http://pix4d.com/camera/1.0/\" Camera:LineReadoutTime=\"%ld\" "
                "Camera:IMULinearVelocity=\"%.2f,%.2f,%.2f\"/></rdf:RDF></x:xmpmeta>",
                std::lround(readout_time_s * 1e6), velocity_enu_mps.x(), velocity_enu_mps.y(), velocity_enu_mps.z());
  return text;
}

namespace {

// Inserts the XMP packet as an APP1 segment after the file's leading APPn
// segments (JFIF APP0, EXIF APP1), where readers look for it.
void InsertXmpSegment(const std::filesystem::path& file, const std::string& xmp) {
  static const char kNamespace[] = "http://ns.adobe.com/xap/1.0/";  // and its terminating NUL
  const size_t length = 2 + sizeof kNamespace + xmp.size();
  if (length > 65535) throw InvalidArgument("XMP packet of " + std::to_string(xmp.size()) + " bytes: at most 65,000 fit");
  std::string bytes;
  {
    std::ifstream in(file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto byte = [&](size_t k) { return static_cast<unsigned char>(bytes[k]); };
  if (bytes.size() < 4 || byte(0) != 0xFF || byte(1) != 0xD8) throw IoError(file.string(), "not a JPEG (no SOI)");
  size_t at = 2;
  while (at + 4 <= bytes.size() && byte(at) == 0xFF && byte(at + 1) >= 0xE0 && byte(at + 1) <= 0xEF) {
    at += 2 + (static_cast<size_t>(byte(at + 2)) << 8 | byte(at + 3));
  }
  if (at > bytes.size()) throw IoError(file.string(), "truncated APP segment");
  std::string segment = {'\xFF', '\xE1', static_cast<char>(length >> 8), static_cast<char>(length & 0xFF)};
  segment.append(kNamespace, sizeof kNamespace);
  segment += xmp;
  bytes.insert(at, segment);
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw IoError(file.string(), "cannot write the XMP segment");
}

}  // namespace

void WriteJpegWithExif(const std::filesystem::path& path, const cv::Mat& image,
                       const std::map<std::string, std::string>& exif, int quality, const std::string& xmp) {
  GDALAllRegister();
  if (xmp.size() > 65000) {
    throw InvalidArgument("XMP packet of " + std::to_string(xmp.size()) + " bytes for " + path.string() +
                          ": at most 65,000 fit in a JPEG segment");
  }
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1)) {
    throw InvalidArgument("JPEG output needs an 8-bit grey or BGR image");
  }
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* jpeg = GetGDALDriverManager()->GetDriverByName("JPEG");
  if (!mem || !jpeg) throw IoError(path.string(), "GDAL lacks the MEM or JPEG driver");
  const int bands = image.channels();
  std::unique_ptr<GDALDataset> ds(
      mem->Create("", image.cols, image.rows, bands, GDT_Byte, nullptr));
  for (int b = 0; b < bands; ++b) {
    // OpenCV is BGR: GDAL band 1 is red.
    const int channel = bands == 3 ? 2 - b : 0;
    std::vector<std::uint8_t> plane(static_cast<size_t>(image.cols) * image.rows);
    for (int y = 0; y < image.rows; ++y) {
      const std::uint8_t* row = image.ptr<std::uint8_t>(y);
      for (int x = 0; x < image.cols; ++x) plane[static_cast<size_t>(y) * image.cols + x] = row[x * bands + channel];
    }
    if (ds->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, image.cols, image.rows, plane.data(),
                                           image.cols, image.rows, GDT_Byte, 0, 0) != CE_None) {
      throw IoError(path.string(), "cannot fill the in-memory image");
    }
  }
  for (const auto& [key, value] : exif) ds->SetMetadataItem(key.c_str(), value.c_str());
  const std::filesystem::path tmp = TemporaryPathFor(path);
  const std::string q = "QUALITY=" + std::to_string(quality);
  const char* options[] = {q.c_str(), "WRITE_EXIF_METADATA=YES", nullptr};
  CPLPushErrorHandler(CPLQuietErrorHandler);
  std::unique_ptr<GDALDataset> out(
      jpeg->CreateCopy(tmp.string().c_str(), ds.get(), FALSE, const_cast<char**>(options), nullptr, nullptr));
  CPLPopErrorHandler();
  if (!out) {
    std::filesystem::remove(tmp);
    throw IoError(path.string(), std::string("JPEG write failed: ") + CPLGetLastErrorMsg());
  }
  out.reset();
  std::error_code ec;
  std::filesystem::remove(tmp.string() + ".aux.xml", ec);
  if (!xmp.empty()) {
    try {
      InsertXmpSegment(tmp, xmp);
    } catch (...) {
      std::filesystem::remove(tmp, ec);
      throw;
    }
  }
  CommitTemporaryFile(tmp, path);
}

}  // namespace aerotri
