// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/ingest/image_metadata.h"

#include <gdal_priv.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <sstream>

#include "libphoto/base/error.h"
#include "libphoto/ingest/readout_table.h"

namespace aerotri {
namespace {

void RegisterGdalOnce() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetConfigOption("GDAL_PAM_ENABLED", "NO");  // never write .aux.xml beside inputs
  });
}

// EXIF rationals print as "(46) (50) (33.3855)".
std::vector<double> Rationals(const char* value) {
  std::vector<double> out;
  if (!value) return out;
  std::string s(value);
  for (char& c : s) {
    if (c == '(' || c == ')') c = ' ';
  }
  std::istringstream in(s);
  double v;
  while (in >> v) out.push_back(v);
  return out;
}

std::optional<double> First(const char* value) {
  const auto v = Rationals(value);
  if (v.empty() || !std::isfinite(v[0])) return std::nullopt;
  return v[0];
}

std::optional<double> Dms(const char* value, const char* ref, char negative) {
  const auto v = Rationals(value);
  if (v.empty()) return std::nullopt;
  double deg = v[0] + (v.size() > 1 ? v[1] / 60.0 : 0.0) + (v.size() > 2 ? v[2] / 3600.0 : 0.0);
  if (ref && std::toupper(static_cast<unsigned char>(ref[0])) == negative) deg = -deg;
  if (!std::isfinite(deg)) return std::nullopt;
  return deg;
}

// The text of an XMP property in attribute form (ns:Tag="...") or element
// form (<ns:Tag>...<); nullopt when absent.
std::optional<std::string> XmpText(const std::string& xmp, const std::string& tag) {
  for (const auto& [open, close] : {std::pair<std::string, char>{tag + "=\"", '"'}, {"<" + tag + ">", '<'}}) {
    const size_t at = xmp.find(open);
    if (at == std::string::npos) continue;
    const size_t from = at + open.size(), to = xmp.find(close, from);
    if (to == std::string::npos) return std::nullopt;
    return xmp.substr(from, to - from);
  }
  return std::nullopt;
}

// Comma-separated numbers ("2.09,12.59,0.61"); empty unless every one parses.
std::vector<double> XmpNumbers(const std::string& xmp, const std::string& tag) {
  std::vector<double> out;
  const std::optional<std::string> text = XmpText(xmp, tag);
  if (!text) return out;
  std::stringstream in(*text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || !std::isfinite(v)) return {};
    while (*end == ' ') ++end;
    if (*end != '\0') return {};
    out.push_back(v);
  }
  return out;
}

std::optional<double> XmpNumber(const std::string& xmp, const std::string& tag) {
  const std::vector<double> v = XmpNumbers(xmp, tag);
  if (v.size() != 1) return std::nullopt;
  return v[0];
}

void ReadDjiXmp(const std::string& text, ImageMetadata* m) {
  m->relative_altitude_m = XmpNumber(text, "drone-dji:RelativeAltitude");
  m->gimbal_pitch_deg = XmpNumber(text, "drone-dji:GimbalPitchDegree");
  m->gimbal_yaw_deg = XmpNumber(text, "drone-dji:GimbalYawDegree");
  m->gimbal_roll_deg = XmpNumber(text, "drone-dji:GimbalRollDegree");
  m->rtk_std_lat_m = XmpNumber(text, "drone-dji:RtkStdLat");
  m->rtk_std_lon_m = XmpNumber(text, "drone-dji:RtkStdLon");
  m->rtk_std_hgt_m = XmpNumber(text, "drone-dji:RtkStdHgt");
  m->flight_pitch_deg = XmpNumber(text, "drone-dji:FlightPitchDegree");
  m->flight_roll_deg = XmpNumber(text, "drone-dji:FlightRollDegree");
  m->flight_yaw_deg = XmpNumber(text, "drone-dji:FlightYawDegree");
  m->flight_speed_x_mps = XmpNumber(text, "drone-dji:FlightXSpeed");
  m->flight_speed_y_mps = XmpNumber(text, "drone-dji:FlightYSpeed");
  m->flight_speed_z_mps = XmpNumber(text, "drone-dji:FlightZSpeed");
  m->calibrated_focal_px = XmpNumber(text, "drone-dji:CalibratedFocalLength");
  m->calibrated_cx_px = XmpNumber(text, "drone-dji:CalibratedOpticalCenterX");
  m->calibrated_cy_px = XmpNumber(text, "drone-dji:CalibratedOpticalCenterY");
  if (text.find("drone-dji:") != std::string::npos) m->xmp_sources.push_back("DJI (drone-dji)");
}

void ReadPix4dCameraXmp(const std::string& text, ImageMetadata* m) {
  if (text.find("http://pix4d.com/camera/1.0/") == std::string::npos) return;
  m->camera_yaw_deg = XmpNumber(text, "Camera:Yaw");
  m->camera_pitch_deg = XmpNumber(text, "Camera:Pitch");
  m->camera_roll_deg = XmpNumber(text, "Camera:Roll");
  m->gps_xy_accuracy_m = XmpNumber(text, "Camera:GPSXYAccuracy");
  m->gps_z_accuracy_m = XmpNumber(text, "Camera:GPSZAccuracy");
  if (const auto t = XmpNumber(text, "Camera:LineReadoutTime"); t && *t > 0) m->line_readout_time_s = *t * 1e-6;
  m->imu_linear_velocity_mps = XmpNumbers(text, "Camera:IMULinearVelocity");
  if (m->imu_linear_velocity_mps.size() != 3) m->imu_linear_velocity_mps.clear();
  m->perspective_focal_mm = XmpNumber(text, "Camera:PerspectiveFocalLength");
  m->principal_point_mm = XmpNumbers(text, "Camera:PrincipalPoint");
  if (m->principal_point_mm.size() != 2) m->principal_point_mm.clear();
  m->perspective_distortion = XmpNumbers(text, "Camera:PerspectiveDistortion");
  if (m->perspective_distortion.size() != 5) m->perspective_distortion.clear();
  m->xmp_sources.push_back("Pix4D camera tags (Camera namespace)");
}

std::string Text(const char* v) { return v ? std::string(v) : std::string(); }

}  // namespace

std::optional<double> ExifDateTimeSeconds(const std::string& datetime, const std::string& subsec) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, se = 0;
  char tail = 0;
  // Separators as the standard writes them (':' in the date); some writers use '-'.
  if (std::sscanf(datetime.c_str(), "%4d%*1[:-]%2d%*1[:-]%2d %2d:%2d:%2d%c", &y, &mo, &d, &h, &mi, &se, &tail) < 6) {
    return std::nullopt;
  }
  if (y < 1900 || mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || se > 60 || h < 0 || mi < 0 ||
      se < 0) {
    return std::nullopt;
  }
  // Days from 1970-01-01 of the proleptic Gregorian calendar (era arithmetic).
  const int yy = y - (mo <= 2 ? 1 : 0);
  const int era = yy / 400;
  const int yoe = yy - era * 400;
  const int doy = (153 * (mo + (mo > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  const double days = era * 146097.0 + doe - 719468.0;
  double seconds = days * 86400.0 + h * 3600.0 + mi * 60.0 + se;
  // SubSecTimeOriginal: the digits are a decimal fraction ("5" = 0.5 s).
  std::string digits;
  for (char c : subsec) {
    if (!std::isdigit(static_cast<unsigned char>(c))) break;
    digits += c;
  }
  if (!digits.empty() && digits.size() <= 9) seconds += std::stod("0." + digits);
  return seconds;
}

bool IsImageFileName(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff";
}

ImageMetadata ReadImageMetadata(const std::filesystem::path& path) {
  RegisterGdalOnce();
  CPLErrorReset();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  std::unique_ptr<GDALDataset> ds(
      static_cast<GDALDataset*>(GDALOpen(path.string().c_str(), GA_ReadOnly)));
  CPLPopErrorHandler();
  if (!ds) {
    const std::string why = CPLGetLastErrorMsg();
    throw IoError(path.string(), "cannot read as an image" + (why.empty() ? "" : " (" + why + ")"));
  }
  ImageMetadata m;
  m.path = path.string();
  m.width = ds->GetRasterXSize();
  m.height = ds->GetRasterYSize();
  if (m.width <= 0 || m.height <= 0 || ds->GetRasterCount() < 1) {
    throw IoError(path.string(), "not an image with pixels");
  }
  auto item = [&](const char* key) { return ds->GetMetadataItem(key); };
  m.make = Text(item("EXIF_Make"));
  m.model = Text(item("EXIF_Model"));
  m.datetime_original = Text(item("EXIF_DateTimeOriginal"));
  m.capture_time_s = ExifDateTimeSeconds(m.datetime_original, Text(item("EXIF_SubSecTimeOriginal")));
  m.lat_deg = Dms(item("EXIF_GPSLatitude"), item("EXIF_GPSLatitudeRef"), 'S');
  m.lon_deg = Dms(item("EXIF_GPSLongitude"), item("EXIF_GPSLongitudeRef"), 'W');
  if (m.lat_deg && std::abs(*m.lat_deg) > 90.0) m.lat_deg.reset();
  if (m.lon_deg && std::abs(*m.lon_deg) > 180.0) m.lon_deg.reset();
  m.gps_altitude_m = First(item("EXIF_GPSAltitude"));
  if (m.gps_altitude_m) {
    const std::string ref = Text(item("EXIF_GPSAltitudeRef"));
    if (ref == "0x01" || ref == "1") *m.gps_altitude_m = -*m.gps_altitude_m;  // below sea level
  }
  m.gps_dop = First(item("EXIF_GPSDOP"));
  m.focal_mm = First(item("EXIF_FocalLength"));
  if (m.focal_mm && *m.focal_mm <= 0.0) m.focal_mm.reset();
  m.focal_35mm = First(item("EXIF_FocalLengthIn35mmFilm"));
  if (m.focal_35mm && *m.focal_35mm <= 0.0) m.focal_35mm.reset();
  if (const auto res = First(item("EXIF_FocalPlaneXResolution")); res && *res > 0.0) {
    const std::string unit = Text(item("EXIF_FocalPlaneResolutionUnit"));
    const double per_mm = unit == "3" ? *res / 10.0 : unit == "4" ? *res / 1.0
                          : unit == "5" ? *res / 1e-3 : *res / 25.4;  // 2 (inch) is the default
    m.focal_plane_px_per_mm = per_mm;
    // A width beyond a million pixels is a corrupt tag, not a sensor (and
    // would not convert to int).
    if (const auto w = First(item("EXIF_PixelXDimension")); w && *w > 0 && *w < 1e6) {
      m.exif_pixel_width = static_cast<int>(*w);
    }
  }
  if (char** xmp = ds->GetMetadata("xml:XMP"); xmp && xmp[0]) {
    const std::string text(xmp[0]);
    ReadDjiXmp(text, &m);
    ReadPix4dCameraXmp(text, &m);
  }
  return m;
}

std::optional<StatedRollingShutter> RollingShutterStatedBy(const ImageMetadata& m) {
  StatedRollingShutter s;
  if (m.imu_linear_velocity_mps.size() == 3) {
    s.east_mps = m.imu_linear_velocity_mps[0];
    s.north_mps = m.imu_linear_velocity_mps[1];
    s.source = "velocity: the photos' Pix4D camera tags, Camera:IMULinearVelocity (east and north; vertical speed not "
               "modelled)";
  } else if (m.flight_speed_x_mps && m.flight_speed_y_mps) {
    s.east_mps = *m.flight_speed_y_mps;
    s.north_mps = *m.flight_speed_x_mps;
    s.source = "velocity: the photos' DJI tags, drone-dji:FlightXSpeed (north) and FlightYSpeed (east), as DJI's "
               "Mobile SDK defines the aircraft's velocity (vertical speed not modelled)";
  } else {
    return std::nullopt;
  }
  if (!std::isfinite(s.east_mps) || !std::isfinite(s.north_mps)) return std::nullopt;
  if (m.line_readout_time_s && *m.line_readout_time_s > 0.0) {
    s.readout_time_s = *m.line_readout_time_s;
    s.source += "; readout: Camera:LineReadoutTime";
  } else if (const auto known = KnownCameraReadout(m.make, m.model, 1e-6 * m.width * m.height)) {
    s.readout_time_s = known->readout_time_s;
    char text[64];
    std::snprintf(text, sizeof text, "%.0f ms", 1e3 * known->readout_time_s);
    s.source += "; readout: " + std::string(text) + " for the " + known->camera + " from " + known->source;
  } else {
    s.source += "; readout: not stated, not in the known-camera table";
  }
  return s;
}

std::optional<StatedCalibration> CalibrationStatedBy(const ImageMetadata& m, double pixel_size_mm) {
  if (m.perspective_focal_mm && *m.perspective_focal_mm > 0.0 && m.principal_point_mm.size() == 2 &&
      pixel_size_mm > 0.0) {
    StatedCalibration c;
    c.focal_px = *m.perspective_focal_mm / pixel_size_mm;
    c.cx_px = m.principal_point_mm[0] / pixel_size_mm - 0.5;
    c.cy_px = m.principal_point_mm[1] / pixel_size_mm - 0.5;
    c.distortion = m.perspective_distortion;
    c.source = "the photos' Pix4D camera tags (Camera:PerspectiveFocalLength, Camera:PrincipalPoint" +
               std::string(c.distortion.empty() ? "" : ", Camera:PerspectiveDistortion") + ")";
    return c;
  }
  if (m.calibrated_focal_px && *m.calibrated_focal_px > 0.0 && m.calibrated_cx_px && m.calibrated_cy_px) {
    StatedCalibration c;
    c.focal_px = *m.calibrated_focal_px;
    c.cx_px = *m.calibrated_cx_px - 0.5;
    c.cy_px = *m.calibrated_cy_px - 0.5;
    c.source = "the photos' DJI tags (drone-dji:CalibratedFocalLength, CalibratedOpticalCenterX / Y)";
    return c;
  }
  return std::nullopt;
}

std::optional<StatedGpsSigmas> GpsSigmasStatedBy(const ImageMetadata& m) {
  constexpr double kFloor = 0.005;
  if (m.rtk_std_lat_m && m.rtk_std_lon_m && m.rtk_std_hgt_m && *m.rtk_std_lat_m > 0 && *m.rtk_std_lon_m > 0 &&
      *m.rtk_std_hgt_m > 0) {
    return StatedGpsSigmas{std::max(kFloor, std::hypot(*m.rtk_std_lat_m, *m.rtk_std_lon_m) / std::sqrt(2.0)),
                           std::max(kFloor, *m.rtk_std_hgt_m), "exif+rtk"};
  }
  if (m.gps_xy_accuracy_m && m.gps_z_accuracy_m && *m.gps_xy_accuracy_m > 0 && *m.gps_z_accuracy_m > 0) {
    return StatedGpsSigmas{std::max(kFloor, *m.gps_xy_accuracy_m), std::max(kFloor, *m.gps_z_accuracy_m),
                           "exif+accuracy"};
  }
  return std::nullopt;
}

}  // namespace aerotri
