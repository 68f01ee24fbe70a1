// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/raster.h"

#include <gdal_priv.h>

#include <memory>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {

void WriteRaster(const Raster& raster, const std::filesystem::path& path,
                 const RasterWriteOptions& options) {
  GDALAllRegister();
  if (raster.width <= 0 || raster.height <= 0 ||
      raster.values.size() != static_cast<size_t>(raster.width) * raster.height) {
    throw InvalidArgument("raster " + path.string() + ": size and values disagree");
  }
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> ds(mem->Create("", raster.width, raster.height, 1, GDT_Float32, nullptr));
  double gt[6];
  std::copy(raster.geotransform.begin(), raster.geotransform.end(), gt);
  ds->SetGeoTransform(gt);
  if (!raster.wkt.empty()) ds->SetProjection(raster.wkt.c_str());
  for (const auto& [key, value] : options.metadata) ds->SetMetadataItem(key.c_str(), value.c_str());
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(raster.nodata);
  if (band->RasterIO(GF_Write, 0, 0, raster.width, raster.height,
                     const_cast<float*>(raster.values.data()), raster.width, raster.height,
                     GDT_Float32, 0, 0) != CE_None) {
    throw IoError(path.string(), "cannot fill the in-memory raster");
  }
  band->ComputeStatistics(FALSE, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr);

  const std::filesystem::path tmp = TemporaryPathFor(path);
  std::vector<std::string> opts;
  const std::string compress = "COMPRESS=" + options.compress;
  GDALDriver* driver = nullptr;
  if (options.cog) {
    driver = GetGDALDriverManager()->GetDriverByName("COG");
    opts = {compress, "PREDICTOR=YES", "BLOCKSIZE=256", "OVERVIEWS=AUTO"};
  } else {
    driver = GetGDALDriverManager()->GetDriverByName("GTiff");
    opts = {compress, "PREDICTOR=3", "TILED=YES"};
    if (options.overviews) opts.push_back("COPY_SRC_OVERVIEWS=YES");
    if (options.overviews) {
      int factors[8];
      int n = 0;
      for (int f = 2; n < 8 && (raster.width / f >= 64 || raster.height / f >= 64); f *= 2) factors[n++] = f;
      if (n > 0) ds->BuildOverviews("AVERAGE", n, factors, 0, nullptr, nullptr, nullptr);
    }
  }
  if (!driver) throw IoError(path.string(), "GDAL lacks the GeoTIFF / COG driver");
  std::vector<const char*> copts;
  for (const auto& o : opts) copts.push_back(o.c_str());
  copts.push_back(nullptr);
  CPLPushErrorHandler(CPLQuietErrorHandler);
  std::unique_ptr<GDALDataset> out(driver->CreateCopy(tmp.string().c_str(), ds.get(), FALSE,
                                                      const_cast<char**>(copts.data()), nullptr, nullptr));
  CPLPopErrorHandler();
  if (!out) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw IoError(path.string(), std::string("GeoTIFF write failed: ") + CPLGetLastErrorMsg());
  }
  out.reset();
  CommitTemporaryFile(tmp, path);
}

Raster ReadRaster(const std::filesystem::path& path) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(static_cast<GDALDataset*>(GDALOpen(path.string().c_str(), GA_ReadOnly)));
  if (!ds) throw IoError(path.string(), "cannot open as a raster");
  Raster r;
  r.width = ds->GetRasterXSize();
  r.height = ds->GetRasterYSize();
  double gt[6];
  if (ds->GetGeoTransform(gt) == CE_None) std::copy(gt, gt + 6, r.geotransform.begin());
  if (const char* wkt = ds->GetProjectionRef()) r.wkt = wkt;
  GDALRasterBand* band = ds->GetRasterBand(1);
  int has = 0;
  const double nd = band->GetNoDataValue(&has);
  if (has) r.nodata = nd;
  r.values.resize(static_cast<size_t>(r.width) * r.height);
  if (band->RasterIO(GF_Read, 0, 0, r.width, r.height, r.values.data(), r.width, r.height,
                     GDT_Float32, 0, 0) != CE_None) {
    throw IoError(path.string(), "cannot read the raster's pixels");
  }
  return r;
}

}  // namespace aerotri
