// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/export/contours.h"

#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "libphoto/base/atomic_file.h"
#include "libphoto/base/error.h"

namespace aerotri {
namespace {

// 1, 2, 2.5 or 5 times a power of ten, the nearest at or above x.
double RoundStep(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (m * p >= x * 0.999) return m * p;
  }
  return 10.0 * p;
}

}  // namespace

double AutomaticContourInterval(const Raster& r) {
  std::vector<float> z;
  z.reserve(r.values.size());
  for (float v : r.values) {
    if (v != static_cast<float>(r.nodata)) z.push_back(v);
  }
  if (z.empty()) return 1.0;
  const size_t lo = z.size() / 50, hi = z.size() - 1 - z.size() / 50;
  std::nth_element(z.begin(), z.begin() + lo, z.end());
  const float zlo = z[lo];
  std::nth_element(z.begin(), z.begin() + hi, z.end());
  const double relief = std::max(0.0f, z[hi] - zlo);
  return std::max(0.1, RoundStep(std::max(1e-3, relief / 20.0)));
}

void WriteContours(const Raster& surface, const std::filesystem::path& path, const ContourOptions& o,
                   ContourSummary* summary) {
  if (surface.width < 2 || surface.height < 2) throw InvalidArgument("contours: the surface is empty");
  ContourSummary s;
  s.interval_m = o.interval_m > 0 ? o.interval_m : AutomaticContourInterval(surface);
  const double cell = std::abs(surface.geotransform[1]);
  s.smoothing_sigma_m = o.smoothing_sigma_m >= 0 ? o.smoothing_sigma_m : std::max(3.0 * cell, 2.0 * s.interval_m);
  const double min_length = o.min_length_m >= 0 ? o.min_length_m : 4.0 * s.smoothing_sigma_m;

  // Nodata-aware Gaussian: blur(values * mask) / blur(mask).
  const float nd = static_cast<float>(surface.nodata);
  cv::Mat z(surface.height, surface.width, CV_32F), mask(surface.height, surface.width, CV_32F);
  for (int y = 0; y < surface.height; ++y) {
    for (int x = 0; x < surface.width; ++x) {
      const float v = surface.at(x, y);
      const bool ok = v != nd;
      z.at<float>(y, x) = ok ? v : 0.0f;
      mask.at<float>(y, x) = ok ? 1.0f : 0.0f;
    }
  }
  cv::Mat smooth = z;
  if (s.smoothing_sigma_m > 0) {
    const double sigma_px = s.smoothing_sigma_m / cell;
    cv::Mat zb, mb;
    cv::GaussianBlur(z, zb, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_CONSTANT);
    cv::GaussianBlur(mask, mb, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_CONSTANT);
    smooth = zb / cv::max(mb, 1e-6);
  }
  smooth.setTo(nd, mask == 0.0f);

  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> raster(mem->Create("", surface.width, surface.height, 1, GDT_Float32, nullptr));
  double gt[6];
  std::copy(surface.geotransform.begin(), surface.geotransform.end(), gt);
  raster->SetGeoTransform(gt);
  GDALRasterBand* band = raster->GetRasterBand(1);
  band->SetNoDataValue(surface.nodata);
  if (band->RasterIO(GF_Write, 0, 0, surface.width, surface.height, smooth.ptr<float>(), surface.width,
                     surface.height, GDT_Float32, 0, 0) != CE_None) {
    throw IoError(path.string(), "cannot fill the in-memory raster");
  }
  OGRSpatialReference srs;
  if (!surface.wkt.empty()) {
    srs.importFromWkt(surface.wkt.c_str());
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  }
  GDALDriver* memv = GetGDALDriverManager()->GetDriverByName("Memory");
  std::unique_ptr<GDALDataset> lines(memv->Create("", 0, 0, 0, GDT_Unknown, nullptr));
  OGRLayer* raw = lines->CreateLayer("raw", surface.wkt.empty() ? nullptr : &srs, wkbLineString, nullptr);
  OGRFieldDefn elev_raw("elevation", OFTReal);
  raw->CreateField(&elev_raw);
  const std::string interval = "LEVEL_INTERVAL=" + std::to_string(s.interval_m);
  const std::string nodata = "NODATA=" + std::to_string(surface.nodata);
  const char* copts[] = {interval.c_str(), "ELEV_FIELD=elevation", nodata.c_str(), nullptr};
  if (GDALContourGenerateEx(band, raw, const_cast<char**>(copts), nullptr, nullptr) != CE_None) {
    throw IoError(path.string(), std::string("GDALContourGenerateEx failed: ") + CPLGetLastErrorMsg());
  }

  // GeoPackage wants its extension: the temporary name keeps it.
  const std::filesystem::path tmp = TemporaryPathFor(path).string() + ".gpkg";
  std::filesystem::remove(tmp);
  GDALDriver* gpkg = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!gpkg) throw IoError(path.string(), "GDAL has no GeoPackage driver");
  {
    std::unique_ptr<GDALDataset> out(gpkg->Create(tmp.string().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    if (!out) throw IoError(tmp.string(), std::string("cannot create: ") + CPLGetLastErrorMsg());
    OGRLayer* layer = out->CreateLayer("contours", surface.wkt.empty() ? nullptr : &srs, wkbLineString, nullptr);
    if (!layer) throw IoError(tmp.string(), std::string("cannot create the layer: ") + CPLGetLastErrorMsg());
    OGRFieldDefn elev("elevation", OFTReal);
    OGRFieldDefn index("index", OFTInteger);
    layer->CreateField(&elev);
    layer->CreateField(&index);
    if (layer->StartTransaction() != OGRERR_NONE) throw IoError(tmp.string(), "cannot start a transaction");
    raw->ResetReading();
    for (std::unique_ptr<OGRFeature> f(raw->GetNextFeature()); f; f.reset(raw->GetNextFeature())) {
      const OGRGeometry* g = f->GetGeometryRef();
      const double length = g ? g->toLineString()->get_Length() : 0.0;
      if (length < min_length) {
        ++s.dropped_short;
        continue;
      }
      const double h = f->GetFieldAsDouble("elevation");
      const long long step = std::llround(h / s.interval_m);
      OGRFeature out_f(layer->GetLayerDefn());
      out_f.SetGeometry(g);
      out_f.SetField("elevation", h);
      out_f.SetField("index", o.index_every > 0 && step % o.index_every == 0 ? 1 : 0);
      if (layer->CreateFeature(&out_f) != OGRERR_NONE) {
        throw IoError(tmp.string(), std::string("cannot write a contour: ") + CPLGetLastErrorMsg());
      }
      ++s.lines;
    }
    if (layer->CommitTransaction() != OGRERR_NONE) {
      throw IoError(tmp.string(), std::string("cannot commit the contours: ") + CPLGetLastErrorMsg());
    }
  }
  std::filesystem::rename(tmp, path);
  if (summary) *summary = s;
}

void WritePointsGpkg(const std::filesystem::path& path, const std::string& layer_name, const std::string& wkt,
                     const std::string& description, const std::vector<std::string>& text_fields,
                     const std::vector<std::string>& number_fields, const std::vector<GpkgPoint>& points) {
  GDALAllRegister();
  GDALDriver* gpkg = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!gpkg) throw IoError(path.string(), "GDAL has no GeoPackage driver");
  OGRSpatialReference srs;
  const bool has_srs = !wkt.empty() && srs.importFromWkt(wkt.c_str()) == OGRERR_NONE;
  if (has_srs) srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  const std::filesystem::path tmp = TemporaryPathFor(path).string() + ".gpkg";
  std::filesystem::remove(tmp);
  {
    std::unique_ptr<GDALDataset> out(gpkg->Create(tmp.string().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    if (!out) throw IoError(tmp.string(), std::string("cannot create: ") + CPLGetLastErrorMsg());
    const std::string desc = "DESCRIPTION=" + description;
    const char* lco[] = {desc.c_str(), nullptr};
    OGRLayer* layer = out->CreateLayer(layer_name.c_str(), has_srs ? &srs : nullptr, wkbPoint25D, const_cast<char**>(lco));
    if (!layer) throw IoError(tmp.string(), std::string("cannot create the layer: ") + CPLGetLastErrorMsg());
    for (const std::string& f : text_fields) {
      OGRFieldDefn d(f.c_str(), OFTString);
      if (layer->CreateField(&d) != OGRERR_NONE) throw IoError(tmp.string(), "cannot create field " + f);
    }
    for (const std::string& f : number_fields) {
      OGRFieldDefn d(f.c_str(), OFTReal);
      if (layer->CreateField(&d) != OGRERR_NONE) throw IoError(tmp.string(), "cannot create field " + f);
    }
    if (layer->StartTransaction() != OGRERR_NONE) throw IoError(tmp.string(), "cannot start a transaction");
    for (const GpkgPoint& p : points) {
      OGRFeature f(layer->GetLayerDefn());
      OGRPoint point(p.xyz.x(), p.xyz.y(), p.xyz.z());
      f.SetGeometry(&point);
      for (size_t k = 0; k < text_fields.size() && k < p.text.size(); ++k) f.SetField(static_cast<int>(k), p.text[k].c_str());
      for (size_t k = 0; k < number_fields.size() && k < p.numbers.size(); ++k) {
        const int field = static_cast<int>(text_fields.size() + k);
        if (std::isfinite(p.numbers[k])) {
          f.SetField(field, p.numbers[k]);
        } else {
          f.SetFieldNull(field);
        }
      }
      if (layer->CreateFeature(&f) != OGRERR_NONE) {
        throw IoError(tmp.string(), std::string("cannot write a point: ") + CPLGetLastErrorMsg());
      }
    }
    if (layer->CommitTransaction() != OGRERR_NONE) {
      throw IoError(tmp.string(), std::string("cannot commit the points: ") + CPLGetLastErrorMsg());
    }
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace aerotri
