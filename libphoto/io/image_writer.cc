// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/io/image_writer.h"

#include <gdal_priv.h>

#include <cmath>
#include <cstdio>
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

void WriteJpegWithExif(const std::filesystem::path& path, const cv::Mat& image,
                       const std::map<std::string, std::string>& exif, int quality) {
  GDALAllRegister();
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
  CommitTemporaryFile(tmp, path);
}

}  // namespace aerotri
