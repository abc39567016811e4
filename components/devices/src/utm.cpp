#include "rack/devices/utm.h"

#include <cmath>
#include <numbers>

namespace rack::devices {

namespace {
constexpr double kA = 6378137.0;            // WGS84 semi-major axis, m
constexpr double kF = 1.0 / 298.257223563;  // WGS84 flattening
constexpr double kK0 = 0.9996;              // UTM central scale factor
constexpr double kFalseEasting = 500000.0;
constexpr double kFalseNorthingSouth = 10000000.0;
constexpr double kDeg = std::numbers::pi / 180.0;
}  // namespace

int utm_zone(double lat_deg, double lon_deg) noexcept {
  double lon = std::fmod(lon_deg + 180.0, 360.0);
  if (lon < 0) lon += 360.0;
  int zone = static_cast<int>(lon / 6.0) + 1;
  if (zone > 60) zone = 60;
  lon -= 180.0;
  if (lat_deg >= 56.0 && lat_deg < 64.0 && lon >= 3.0 && lon < 12.0) zone = 32;  // Norway
  if (lat_deg >= 72.0 && lat_deg < 84.0 && lon >= 0.0 && lon < 42.0) {           // Svalbard
    if (lon < 9.0) zone = 31;
    else if (lon < 21.0) zone = 33;
    else if (lon < 33.0) zone = 35;
    else zone = 37;
  }
  return zone;
}

UtmPoint wgs84_to_utm(double lat_deg, double lon_deg, int force_zone) noexcept {
  UtmPoint p;
  p.zone = force_zone >= 1 && force_zone <= 60 ? force_zone : utm_zone(lat_deg, lon_deg);
  p.north = lat_deg >= 0.0;
  const double lon0 = (p.zone * 6 - 183) * kDeg;
  double dl = lon_deg * kDeg - lon0;
  dl = std::remainder(dl, 2.0 * std::numbers::pi);  // (-pi, pi]
  const double phi = lat_deg * kDeg;

  const double n = kF / (2.0 - kF);
  const double n2 = n * n, n3 = n2 * n, n4 = n3 * n;
  const double a_rect = kA / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0);  // rectifying radius
  const double alpha[4] = {n / 2.0 - 2.0 * n2 / 3.0 + 5.0 * n3 / 16.0 + 41.0 * n4 / 180.0,
                           13.0 * n2 / 48.0 - 3.0 * n3 / 5.0 + 557.0 * n4 / 1440.0,
                           61.0 * n3 / 240.0 - 103.0 * n4 / 140.0, 49561.0 * n4 / 161280.0};
  // Conformal latitude via t = tan(chi).
  const double e = 2.0 * std::sqrt(n) / (1.0 + n);  // first eccentricity
  const double sphi = std::sin(phi);
  const double t = std::sinh(std::atanh(sphi) - e * std::atanh(e * sphi));
  const double xi1 = std::atan2(t, std::cos(dl));
  const double eta1 = std::atanh(std::sin(dl) / std::sqrt(1.0 + t * t));

  double xi = xi1, eta = eta1;
  for (int j = 1; j <= 4; ++j) {
    const double a = alpha[j - 1];
    xi += a * std::sin(2.0 * j * xi1) * std::cosh(2.0 * j * eta1);
    eta += a * std::cos(2.0 * j * xi1) * std::sinh(2.0 * j * eta1);
  }
  p.easting = kFalseEasting + kK0 * a_rect * eta;
  p.northing = kK0 * a_rect * xi + (p.north ? 0.0 : kFalseNorthingSouth);
  return p;
}

}  // namespace rack::devices
