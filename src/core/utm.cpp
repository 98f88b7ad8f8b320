#include "core/utm.h"

#include <array>
#include <cmath>
#include <string>

#include "core/error.h"

namespace ddhgs::core {
namespace {

constexpr double kUtmPi = 3.14159265358979323846;
constexpr double kUtmDeg = kUtmPi / 180;
constexpr double kWgs84A = 6378137.0;          // WGS84 semi-major axis, m
constexpr double kWgs84F = 1 / 298.257223563;  // WGS84 flattening
constexpr double kUtmK0 = 0.9996;              // UTM central scale factor
constexpr double kFalseEasting = 500000.0;     // m
constexpr double kFalseNorthing = 10000000.0;  // m, southern zones

// The series' constants, computed once from the ellipsoid.
struct KruegerSeries {
  double e = 0;       // eccentricity
  double radius = 0;  // rectifying radius A, m
  std::array<double, 6> alpha{}, beta{};
  KruegerSeries() {
    const double n = kWgs84F / (2 - kWgs84F), n2 = n * n, n3 = n2 * n, n4 = n3 * n, n5 = n4 * n,
                 n6 = n5 * n;
    e = std::sqrt(kWgs84F * (2 - kWgs84F));
    radius = kWgs84A / (1 + n) * (1 + n2 / 4 + n4 / 64 + n6 / 256);
    alpha = {n / 2 - 2 * n2 / 3 + 5 * n3 / 16 + 41 * n4 / 180 - 127 * n5 / 288 + 7891 * n6 / 37800,
             13 * n2 / 48 - 3 * n3 / 5 + 557 * n4 / 1440 + 281 * n5 / 630 - 1983433 * n6 / 1935360,
             61 * n3 / 240 - 103 * n4 / 140 + 15061 * n5 / 26880 + 167603 * n6 / 181440,
             49561 * n4 / 161280 - 179 * n5 / 168 + 6601661 * n6 / 7257600,
             34729 * n5 / 80640 - 3418889 * n6 / 1995840,
             212378941 * n6 / 319334400};
    beta = {n / 2 - 2 * n2 / 3 + 37 * n3 / 96 - n4 / 360 - 81 * n5 / 512 + 96199 * n6 / 604800,
            n2 / 48 + n3 / 15 - 437 * n4 / 1440 + 46 * n5 / 105 - 1118711 * n6 / 3870720,
            17 * n3 / 480 - 37 * n4 / 840 - 209 * n5 / 4480 + 5569 * n6 / 90720,
            4397 * n4 / 161280 - 11 * n5 / 504 - 830251 * n6 / 7257600,
            4583 * n5 / 161280 - 108847 * n6 / 3991680,
            20648693 * n6 / 638668800};
  }
};

const KruegerSeries& krueger_series() {
  static const KruegerSeries s;
  return s;
}

double central_meridian_deg(const UtmZone& zone) {
  return 6.0 * zone.number - 183.0;
}

void check_zone(const UtmZone& zone) {
  require(zone.number >= 1 && zone.number <= 60,
          "UTM zone " + std::to_string(zone.number) + " is not a zone (1-60)");
}

}  // namespace

UtmZone utm_zone(double latitude_deg, double longitude_deg) {
  require(
      latitude_deg >= -80 && latitude_deg <= 84 && longitude_deg >= -180 && longitude_deg <= 180,
      "latitude " + std::to_string(latitude_deg) + ", longitude " + std::to_string(longitude_deg) +
          " deg: outside UTM's range (latitude -80 to 84, longitude -180 to 180)");
  UtmZone zone;
  zone.north = latitude_deg >= 0;
  zone.number = std::min(60, int(std::floor((longitude_deg + 180) / 6)) + 1);
  if (latitude_deg >= 56 && latitude_deg < 64 && longitude_deg >= 3 && longitude_deg < 12)
    zone.number = 32;        // south-west Norway
  if (latitude_deg >= 72) {  // Svalbard: zones 31, 33, 35 and 37 only
    if (longitude_deg >= 0 && longitude_deg < 9)
      zone.number = 31;
    else if (longitude_deg >= 9 && longitude_deg < 21)
      zone.number = 33;
    else if (longitude_deg >= 21 && longitude_deg < 33)
      zone.number = 35;
    else if (longitude_deg >= 33 && longitude_deg < 42)
      zone.number = 37;
  }
  return zone;
}

UtmPoint to_utm(double latitude_deg, double longitude_deg, const UtmZone& zone) {
  check_zone(zone);
  const KruegerSeries& s = krueger_series();
  const double phi = latitude_deg * kUtmDeg;
  const double lambda = (longitude_deg - central_meridian_deg(zone)) * kUtmDeg;
  // The conformal latitude's tangent.
  const double sin_phi = std::sin(phi);
  const double t = std::sinh(std::atanh(sin_phi) - s.e * std::atanh(s.e * sin_phi));
  const double xi_p = std::atan2(t, std::cos(lambda));
  const double eta_p = std::atanh(std::sin(lambda) / std::sqrt(1 + t * t));
  double xi = xi_p, eta = eta_p;
  for (int j = 1; j <= 6; ++j) {
    xi += s.alpha[size_t(j - 1)] * std::sin(2 * j * xi_p) * std::cosh(2 * j * eta_p);
    eta += s.alpha[size_t(j - 1)] * std::cos(2 * j * xi_p) * std::sinh(2 * j * eta_p);
  }
  return {kFalseEasting + kUtmK0 * s.radius * eta,
          (zone.north ? 0.0 : kFalseNorthing) + kUtmK0 * s.radius * xi};
}

LatLon from_utm(const UtmPoint& point, const UtmZone& zone) {
  check_zone(zone);
  const KruegerSeries& s = krueger_series();
  const double xi = (point.northing_m - (zone.north ? 0.0 : kFalseNorthing)) / (kUtmK0 * s.radius);
  const double eta = (point.easting_m - kFalseEasting) / (kUtmK0 * s.radius);
  double xi_p = xi, eta_p = eta;
  for (int j = 1; j <= 6; ++j) {
    xi_p -= s.beta[size_t(j - 1)] * std::sin(2 * j * xi) * std::cosh(2 * j * eta);
    eta_p -= s.beta[size_t(j - 1)] * std::cos(2 * j * xi) * std::sinh(2 * j * eta);
  }
  const double tau_p = std::sin(xi_p) / std::sqrt(std::sinh(eta_p) * std::sinh(eta_p) +
                                                  std::cos(xi_p) * std::cos(xi_p));
  const double lambda = std::atan2(std::sinh(eta_p), std::cos(xi_p));
  // The geographic latitude's tangent from the conformal one, by Newton's
  // method (Karney 2011, eqs. 19-21); a few steps reach double precision.
  const double e2 = s.e * s.e;
  double tau = tau_p;
  for (int i = 0; i < 8; ++i) {
    const double root = std::sqrt(1 + tau * tau);
    const double sigma = std::sinh(s.e * std::atanh(s.e * tau / root));
    const double tau_i = tau * std::sqrt(1 + sigma * sigma) - sigma * root;
    const double step = (tau_p - tau_i) / std::sqrt(1 + tau_i * tau_i) *
                        (1 + (1 - e2) * tau * tau) / ((1 - e2) * root);
    tau += step;
    if (std::abs(step) < 1e-15) break;
  }
  return {std::atan(tau) / kUtmDeg, central_meridian_deg(zone) + lambda / kUtmDeg};
}

}  // namespace ddhgs::core
