// SPDX-License-Identifier: BSD-3-Clause
#include "georef/crs.h"

#include <proj.h>

#include <GeographicLib/UTMUPS.hpp>

#include <algorithm>
#include <sstream>
#include <cctype>
#include <cmath>
#include <mutex>

#include "libphoto/base/error.h"

namespace aerotri {

// PROJ objects are not thread-safe: each Crs owns a context and serialises
// its transformations.
struct Crs::Impl {
  std::string definition;
  PJ_CONTEXT* ctx = nullptr;
  PJ* crs = nullptr;
  PJ* forward = nullptr;  // EPSG:4979 (lon, lat, h) -> crs (normalised)
  bool geographic = false;
  bool geocentric = false;
  bool vertical = false;
  bool local = false;
  double unit_m = 1.0;
  Eigen::Vector3d local_origin = Eigen::Vector3d::Zero();
  std::mutex mutex;

  ~Impl() {
    if (forward) proj_destroy(forward);
    if (crs) proj_destroy(crs);
    if (ctx) proj_context_destroy(ctx);
  }
};

namespace {

std::string ProjError(PJ_CONTEXT* ctx) {
  const int err = proj_context_errno(ctx);
  return err ? proj_context_errno_string(ctx, err) : "unknown PROJ error";
}

// For a CRS with a vertical datum, the first transformation from WGS84 that
// needs no missing grid and is not a "ballpark" (which would pass ellipsoidal
// heights through as if they were orthometric).
PJ* VerticalOperation(PJ_CONTEXT* ctx, PJ* target, const std::string& definition) {
  PJ* source = proj_create(ctx, "EPSG:4979");
  PJ_OPERATION_FACTORY_CONTEXT* factory = proj_create_operation_factory_context(ctx, nullptr);
  proj_operation_factory_context_set_grid_availability_use(
      ctx, factory, PROJ_GRID_AVAILABILITY_DISCARD_OPERATION_IF_MISSING_GRID);
  proj_operation_factory_context_set_spatial_criterion(
      ctx, factory, PROJ_SPATIAL_CRITERION_PARTIAL_INTERSECTION);
  PJ_OBJ_LIST* ops = proj_create_operations(ctx, source, target, factory);
  PJ* chosen = nullptr;
  const int count = ops ? proj_list_get_count(ops) : 0;
  for (int i = 0; i < count && !chosen; ++i) {
    PJ* op = proj_list_get(ctx, ops, i);
    if (op && !proj_coordoperation_has_ballpark_transformation(ctx, op) &&
        proj_coordoperation_is_instantiable(ctx, op)) {
      chosen = op;
    } else if (op) {
      proj_destroy(op);
    }
  }
  if (ops) proj_list_destroy(ops);
  proj_operation_factory_context_destroy(factory);
  proj_destroy(source);
  if (!chosen) {
    throw CrsError("CRS '" + definition + "': no exact height transformation from WGS84 "
                   "ellipsoidal heights is available (is the geoid grid installed? Debian's "
                   "proj-data ships egm96_15.gtx for EGM96, EPSG:5773)");
  }
  return chosen;
}

}  // namespace

Crs::Crs(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}
Crs::~Crs() = default;

Crs Crs::FromString(const std::string& definition) {
  auto impl = std::make_shared<Impl>();
  impl->definition = definition;
  impl->ctx = proj_context_create();
  proj_context_set_enable_network(impl->ctx, 0);
  proj_log_level(impl->ctx, PJ_LOG_NONE);
  std::string upper = definition;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (upper == "LOCAL") {
    impl->local = true;
    return Crs(impl);
  }
  std::string text = definition;
  // OpenDroneMap's "WGS84 UTM 16N" (gcp_list.txt, geo.txt): EPSG:326zz / 327zz.
  {
    std::istringstream words(upper);
    std::string datum, utm, zone_text, rest;
    if (words >> datum >> utm >> zone_text && !(words >> rest) && datum == "WGS84" && utm == "UTM" &&
        zone_text.size() >= 2 && (zone_text.back() == 'N' || zone_text.back() == 'S')) {
      const std::string digits = zone_text.substr(0, zone_text.size() - 1);
      const bool numeric = digits.size() <= 2 && std::all_of(digits.begin(), digits.end(), ::isdigit);
      const int zone = numeric ? std::stoi(digits) : 0;
      if (zone < 1 || zone > 60) {
        throw CrsError("CRS '" + definition + "': expected a UTM zone from 1 to 60 followed by N or S");
      }
      text = "EPSG:" + std::to_string((zone_text.back() == 'N' ? 32600 : 32700) + zone);
    }
  }
  if (text.rfind("+proj", 0) == 0 && text.find("+type=crs") == std::string::npos) {
    text += " +type=crs";
  }
  impl->crs = proj_create(impl->ctx, text.c_str());
  if (!impl->crs) {
    throw CrsError("CRS '" + definition + "': PROJ cannot create it (" + ProjError(impl->ctx) +
                   "); expected e.g. EPSG:32632, EPSG:32632+5773, a WKT or a PROJ string");
  }
  const PJ_TYPE type = proj_get_type(impl->crs);
  switch (type) {
    case PJ_TYPE_GEOGRAPHIC_2D_CRS:
    case PJ_TYPE_GEOGRAPHIC_3D_CRS:
      impl->geographic = true;
      break;
    case PJ_TYPE_PROJECTED_CRS:
      break;
    case PJ_TYPE_GEOCENTRIC_CRS:
      impl->geocentric = true;
      break;
    case PJ_TYPE_COMPOUND_CRS:
      impl->vertical = true;
      {
        PJ* horizontal = proj_crs_get_sub_crs(impl->ctx, impl->crs, 0);
        if (horizontal) {
          const PJ_TYPE h = proj_get_type(horizontal);
          impl->geographic = h == PJ_TYPE_GEOGRAPHIC_2D_CRS || h == PJ_TYPE_GEOGRAPHIC_3D_CRS;
          proj_destroy(horizontal);
        }
      }
      break;
    case PJ_TYPE_BOUND_CRS:
      break;
    case PJ_TYPE_ENGINEERING_CRS: {
      // Its length unit, from the first axis.
      impl->local = true;
      PJ* cs = proj_crs_get_coordinate_system(impl->ctx, impl->crs);
      double factor = 1.0;
      if (cs && proj_cs_get_axis_count(impl->ctx, cs) >= 1) {
        proj_cs_get_axis_info(impl->ctx, cs, 0, nullptr, nullptr, nullptr, &factor, nullptr, nullptr, nullptr);
      }
      if (cs) proj_destroy(cs);
      impl->unit_m = factor > 0.0 ? factor : 1.0;
      return Crs(impl);
    }
    default:
      throw CrsError("'" + definition + "' is not a coordinate reference system PROJ can "
                     "transform to (it is a " + std::string(proj_get_type(impl->crs) ==
                     PJ_TYPE_VERTICAL_CRS ? "vertical-only CRS" : "non-CRS object") +
                     "); expected e.g. EPSG:32632 or EPSG:32632+5773");
  }

  PJ* raw = impl->vertical ? VerticalOperation(impl->ctx, impl->crs, definition)
                           : proj_create_crs_to_crs(impl->ctx, "EPSG:4979", text.c_str(), nullptr);
  if (!raw) {
    throw CrsError("CRS '" + definition + "': no transformation from WGS84 (" +
                   ProjError(impl->ctx) + ")");
  }
  impl->forward = proj_normalize_for_visualization(impl->ctx, raw);
  proj_destroy(raw);
  if (!impl->forward) {
    throw CrsError("CRS '" + definition + "': cannot normalise axis order (" +
                   ProjError(impl->ctx) + ")");
  }
  return Crs(impl);
}

Crs Crs::UtmFor(const Geodetic& g) {
  const int zone = GeographicLib::UTMUPS::StandardZone(g.lat_deg, g.lon_deg);
  if (zone <= 0) {
    throw CrsError("no UTM zone at latitude " + std::to_string(g.lat_deg) +
                   " (polar: name a CRS with --crs)");
  }
  return FromString("EPSG:" + std::to_string((g.lat_deg >= 0 ? 32600 : 32700) + zone));
}

const std::string& Crs::definition() const { return impl_->definition; }

std::string Crs::Name() const {
  if (impl_->local && !impl_->crs) return "local engineering frame (x east, y north, z up; metres)";
  const char* name = proj_get_name(impl_->crs);
  return name ? name : impl_->definition;
}

namespace {
// WKT of "LOCAL": a 3D Cartesian engineering CRS in metres.
const char* kLocalWkt2 =
    "ENGCRS[\"Local engineering frame\",EDATUM[\"Unknown engineering datum\"],CS[Cartesian,3],"
    "AXIS[\"x\",east,ORDER[1],LENGTHUNIT[\"metre\",1]],AXIS[\"y\",north,ORDER[2],LENGTHUNIT[\"metre\",1]],"
    "AXIS[\"z\",up,ORDER[3],LENGTHUNIT[\"metre\",1]]]";
const char* kLocalWkt1 =
    "LOCAL_CS[\"Local engineering frame\",LOCAL_DATUM[\"Unknown engineering datum\",32767],UNIT[\"metre\",1],"
    "AXIS[\"x\",EAST],AXIS[\"y\",NORTH]]";  // WKT1 allows two axes: z is the height, in metres too
}  // namespace

std::string Crs::Wkt() const {
  if (impl_->local && !impl_->crs) return kLocalWkt2;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* wkt = proj_as_wkt(impl_->ctx, impl_->crs, PJ_WKT2_2019, nullptr);
  return wkt ? wkt : "";
}

std::string Crs::WktV1() const {
  if (impl_->local && !impl_->crs) return kLocalWkt1;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* wkt = proj_as_wkt(impl_->ctx, impl_->crs, PJ_WKT1_GDAL, nullptr);
  return wkt ? wkt : "";
}

bool Crs::IsGeographic() const { return impl_->geographic; }
bool Crs::IsGeocentric() const { return impl_->geocentric; }
bool Crs::IsLocal() const { return impl_->local; }
double Crs::LocalUnitMetres() const { return impl_->unit_m; }

Crs Crs::LocalAt(const Eigen::Vector3d& origin) const {
  if (!impl_->local) throw CrsError("CRS '" + impl_->definition + "' is not a local frame");
  Crs moved = FromString(impl_->definition);
  moved.impl_->local_origin = origin;
  return moved;
}
bool Crs::HasVerticalDatum() const { return impl_->vertical; }

Eigen::Vector3d Crs::FromGeodetic(const Geodetic& g) const {
  if (impl_->local) {
    static const LocalFrame stand_in(LocalGeodeticOrigin());
    return stand_in.EnuFromGeodetic(g) / impl_->unit_m + impl_->local_origin;
  }
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PJ_COORD in = proj_coord(g.lon_deg, g.lat_deg, g.h_m, 0.0);
  proj_errno_reset(impl_->forward);
  const PJ_COORD out = proj_trans(impl_->forward, PJ_FWD, in);
  if (!std::isfinite(out.xyz.x) || !std::isfinite(out.xyz.y) || !std::isfinite(out.xyz.z) ||
      out.xyz.x == HUGE_VAL) {
    throw CrsError("cannot transform lat " + std::to_string(g.lat_deg) + " lon " +
                   std::to_string(g.lon_deg) + " to '" + impl_->definition + "' (" +
                   ProjError(impl_->ctx) +
                   "); for geoid heights install Debian's proj-data (egm96_15.gtx)");
  }
  return {out.xyz.x, out.xyz.y, out.xyz.z};
}

Geodetic Crs::ToGeodetic(const Eigen::Vector3d& xyz) const {
  if (impl_->local) {
    static const LocalFrame stand_in(LocalGeodeticOrigin());
    return stand_in.GeodeticFromEnu((xyz - impl_->local_origin) * impl_->unit_m);
  }
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PJ_COORD in = proj_coord(xyz.x(), xyz.y(), xyz.z(), 0.0);
  proj_errno_reset(impl_->forward);
  const PJ_COORD out = proj_trans(impl_->forward, PJ_INV, in);
  if (!std::isfinite(out.xyz.x) || !std::isfinite(out.xyz.y) || !std::isfinite(out.xyz.z) ||
      out.xyz.x == HUGE_VAL) {
    throw CrsError("cannot transform (" + std::to_string(xyz.x()) + ", " +
                   std::to_string(xyz.y()) + ", " + std::to_string(xyz.z()) + ") from '" +
                   impl_->definition + "' to WGS84 (" + ProjError(impl_->ctx) + ")");
  }
  return {out.xyz.y, out.xyz.x, out.xyz.z};
}

double Egm96Undulation(double lat_deg, double lon_deg) {
  static const Crs egm96 = Crs::FromString("EPSG:4326+5773");
  // Orthometric height of a point on the ellipsoid is -N.
  return -egm96.FromGeodetic({lat_deg, lon_deg, 0.0}).z();
}

}  // namespace aerotri
