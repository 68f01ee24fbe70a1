// SPDX-License-Identifier: BSD-3-Clause
#include "georef/gps_fix.h"

#include "georef/crs.h"

namespace aerotri {

double EllipsoidalHeight(double lat_deg, double lon_deg, double altitude_m,
                         AltitudeReference reference) {
  if (reference == AltitudeReference::kEllipsoid) return altitude_m;
  return altitude_m + Egm96Undulation(lat_deg, lon_deg);
}

}  // namespace aerotri
