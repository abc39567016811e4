// WGS84 geographic coordinates to UTM (Universal Transverse Mercator), by the Krüger
// series in the form of Karney, "Transverse Mercator with an accuracy of a few
// nanometers" (J. Geodesy 85, 2011), eq. 35-36, truncated at n^4: better than a
// millimetre within a zone. Zone numbers follow the standard grid including the
// Norway (32V) and Svalbard (31X..37X) exceptions.
//
// Real-time contract: RT-safe (pure arithmetic).
#pragma once

#include <cstdint>

namespace rack::devices {

struct UtmPoint {
  double easting = 0.0;   // m (500 km false easting)
  double northing = 0.0;  // m (10 000 km false northing in the south)
  int zone = 0;           // 1..60
  bool north = true;
};

// The standard zone of a point (1..60). lat/lon in degrees.
[[nodiscard]] int utm_zone(double lat_deg, double lon_deg) noexcept;
// Projects into the standard zone (force_zone 0) or into `force_zone` (1..60), which
// keeps a local frame continuous when a robot crosses a zone border. `north` is taken
// from the latitude. lat in [-80, 84] for UTM proper; the formulas stay finite beyond.
[[nodiscard]] UtmPoint wgs84_to_utm(double lat_deg, double lon_deg, int force_zone = 0) noexcept;

}  // namespace rack::devices
