#include "io/rig/sun.h"

#include <algorithm>
#include <cmath>

namespace ddhgs::io {

namespace {

constexpr double kDeg = M_PI / 180;

// Unpolarised Fresnel transmission from index n1 into n2 at incidence phi.
double interface_transmission(double phi, double n1, double n2) {
  const double c1 = std::cos(phi);
  const double s = n1 / n2 * std::sin(phi);
  if (s >= 1) return 0;  // total internal reflection
  const double c2 = std::sqrt(1 - s * s);
  const double rs = std::pow((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2), 2);
  const double rp = std::pow((n1 * c2 - n2 * c1) / (n1 * c2 + n2 * c1), 2);
  const double t = 1 - 0.5 * (rs + rp);
  return std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
}

}  // namespace

SunPosition sun_position(double latitude_deg, double longitude_deg, double unix_seconds) {
  const double julian_day = unix_seconds / 86400.0 + 2440587.5;
  const double t = (julian_day - 2451545.0) / 36525.0;  // Julian centuries since J2000
  const double mean_longitude =
      std::fmod(280.46646 + t * (36000.76983 + t * 0.0003032), 360.0) * kDeg;
  const double anomaly = (357.52911 + t * (35999.05029 - 0.0001537 * t)) * kDeg;
  const double eccentricity = 0.016708634 - t * (0.000042037 + 0.0000001267 * t);
  const double centre =
      (std::sin(anomaly) * (1.914602 - t * (0.004817 + 0.000014 * t)) +
       std::sin(2 * anomaly) * (0.019993 - 0.000101 * t) + std::sin(3 * anomaly) * 0.000289) *
      kDeg;
  const double node = (125.04 - 1934.136 * t) * kDeg;
  const double apparent_longitude =
      mean_longitude + centre - (0.00569 + 0.00478 * std::sin(node)) * kDeg;
  const double mean_obliquity =
      (23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0) * kDeg;
  const double obliquity = mean_obliquity + 0.00256 * std::cos(node) * kDeg;
  const double declination = std::asin(std::sin(obliquity) * std::sin(apparent_longitude));
  const double y = std::pow(std::tan(obliquity / 2), 2);
  const double equation_of_time_min =
      4.0 / kDeg *
      (y * std::sin(2 * mean_longitude) - 2 * eccentricity * std::sin(anomaly) +
       4 * eccentricity * y * std::sin(anomaly) * std::cos(2 * mean_longitude) -
       0.5 * y * y * std::sin(4 * mean_longitude) -
       1.25 * eccentricity * eccentricity * std::sin(2 * anomaly));
  const double day_minutes = std::fmod(unix_seconds, 86400.0) / 60.0;
  const double solar_minutes = day_minutes + equation_of_time_min + 4.0 * longitude_deg;
  const double hour_angle = (solar_minutes / 4.0 - 180.0) * kDeg;
  const double latitude = latitude_deg * kDeg;
  const double cos_zenith =
      std::clamp(std::sin(latitude) * std::sin(declination) +
                     std::cos(latitude) * std::cos(declination) * std::cos(hour_angle),
                 -1.0, 1.0);
  double elevation = M_PI / 2 - std::acos(cos_zenith);
  // Mean refraction (Saemundsson's formula, 10 C, 1010 hPa), in degrees.
  const double e_deg = elevation / kDeg;
  if (e_deg > -1.0)
    elevation += 1.02 / std::tan((e_deg + 10.3 / (e_deg + 5.11)) * kDeg) / 60.0 * kDeg;
  // Clockwise from north: the hour angle's azimuth is measured from south.
  double azimuth =
      std::atan2(std::sin(hour_angle), std::cos(hour_angle) * std::sin(latitude) -
                                           std::tan(declination) * std::cos(latitude)) +
      M_PI;
  azimuth = std::fmod(azimuth + 2 * M_PI, 2 * M_PI);
  return {elevation, azimuth};
}

std::array<double, 3> sun_direction_ned(const SunPosition& sun) {
  return {std::cos(sun.azimuth) * std::cos(sun.elevation),
          std::sin(sun.azimuth) * std::cos(sun.elevation), -std::sin(sun.elevation)};
}

std::array<double, 3> sensor_normal_ned(double yaw, double pitch, double roll) {
  // The body's up axis (0, 0, -1) turned by roll about x, pitch about y, yaw about z.
  const double x1 = 0, y1 = std::sin(roll), z1 = -std::cos(roll);
  const double x2 = std::cos(pitch) * x1 + std::sin(pitch) * z1;
  const double z2 = -std::sin(pitch) * x1 + std::cos(pitch) * z1;
  const double x3 = std::cos(yaw) * x2 - std::sin(yaw) * y1;
  const double y3 = std::sin(yaw) * x2 + std::cos(yaw) * y1;
  return {x3, y3, z2};
}

double dls_transmission(double theta) {
  // Air -> polycarbonate -> PTFE; at each interface the angle inside is
  // taken as asin(sin(angle) / n) of the medium the light comes from, as the
  // camera maker's model does (it reproduces its published figures).
  const double n[3] = {1.000277, 1.6, 1.38};
  double t = 1, angle = theta;
  for (int i = 0; i < 2; ++i) {
    angle = std::asin(std::sin(angle) / n[i]);
    t *= interface_transmission(angle, n[i], n[i + 1]);
  }
  return t;
}

double dls1_horizontal_irradiance(double measured, double theta, double elevation) {
  constexpr double diffuse_share = 1.0 / 6.0;  // clear sky: direct / diffuse = 6
  const double transmission = dls_transmission(theta);
  if (!(transmission > 0)) return 0;
  const double direct = measured / transmission / (diffuse_share + std::cos(theta));
  return direct * (std::sin(elevation) + diffuse_share);
}

}  // namespace ddhgs::io
