// The sun's position and the DLS correction (io/rig/sun.h) against figures of
// an independent implementation: MicaSense's library and its test suite
// (pysolar for the sun), for an equinox noon at Greenwich and the equator and
// for the sample panel capture's moment, place and sensor attitude.
#include "io/rig/sun.h"

#include <gtest/gtest.h>

#include <cmath>
#include <ctime>

namespace ddhgs::io {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180;

double utc(int year, int month, int day, int hour, int minute, double second) {
  std::tm t{};
  t.tm_year = year - 1900;
  t.tm_mon = month - 1;
  t.tm_mday = day;
  t.tm_hour = hour;
  t.tm_min = minute;
  return double(timegm(&t)) + second;
}

TEST(Sun, EquinoxNoonStandsAtNinetyMinusTheLatitude) {
  // 2019-03-21 12:08 UTC at Greenwich: the sun due south, 90 - 51.48 degrees high.
  const SunPosition greenwich = sun_position(51.4769, 0, utc(2019, 3, 21, 12, 8, 0));
  EXPECT_NEAR(greenwich.elevation, (90 - 51.4769) * kDeg, 0.01);
  EXPECT_NEAR(greenwich.azimuth, kPi, 0.01);
  const SunPosition equator = sun_position(0, 0, utc(2019, 3, 20, 12, 8, 0));
  EXPECT_NEAR(equator.elevation, 90 * kDeg, 0.01);
  const SunPosition south = sun_position(-45, 0, utc(2019, 3, 20, 12, 8, 0));
  EXPECT_NEAR(south.elevation, 45 * kDeg, 0.01);
  EXPECT_NEAR(std::cos(south.azimuth), 1, 1e-3);  // due north
}

TEST(Sun, SamplePanelCaptureAsMicasenseComputesIt) {
  // IMG_0000_1.tif: 2017-10-19 20:40:39.2 UTC at 36.576096 N, 119.4352689 W,
  // DLS yaw / pitch / roll -3.0702, -0.18813, -0.013388 rad.
  const SunPosition sun = sun_position(36.576096, -119.4352689, utc(2017, 10, 19, 20, 40, 39.2));
  EXPECT_NEAR(sun.elevation, 0.7193, 1e-3);
  EXPECT_NEAR(sun.azimuth, 3.4756, 1e-3);
  const auto to_sun = sun_direction_ned(sun);
  EXPECT_NEAR(to_sun[0], -0.711, 1e-3);
  EXPECT_NEAR(to_sun[1], -0.247, 1e-3);
  EXPECT_NEAR(to_sun[2], -0.659, 1e-3);
  const auto normal =
      sensor_normal_ned(-3.0702229923362689, -0.18812839845718335, -0.013387829297356699);
  EXPECT_NEAR(normal[0], -1.87482468e-01, 1e-3);
  EXPECT_NEAR(normal[1], 1.82720334e-05, 1e-3);
  EXPECT_NEAR(normal[2], -9.82267949e-01, 1e-3);
  const double theta =
      std::acos(to_sun[0] * normal[0] + to_sun[1] * normal[1] + to_sun[2] * normal[2]);
  EXPECT_NEAR(theta, 0.6754, 1e-3);
  // The library's DLS irradiance for this file: 1.010102 from 1.0848248 as read.
  EXPECT_NEAR(dls1_horizontal_irradiance(1.084824800491333, theta, sun.elevation), 1.010102, 1e-3);
}

TEST(Sun, SensorNormalPointsWhereTheAttitudeTurnsIt) {
  auto near = [](const std::array<double, 3>& v, double x, double y, double z) {
    EXPECT_NEAR(v[0], x, 1e-12);
    EXPECT_NEAR(v[1], y, 1e-12);
    EXPECT_NEAR(v[2], z, 1e-12);
  };
  near(sensor_normal_ned(0, 0, 0), 0, 0, -1);                  // level: up
  near(sensor_normal_ned(0, -90 * kDeg, 0), 1, 0, 0);          // nose up 90: north
  near(sensor_normal_ned(90 * kDeg, -90 * kDeg, 0), 0, 1, 0);  // facing east: east
  near(sensor_normal_ned(0, 90 * kDeg, 0), -1, 0, 0);          // nose down: south
  near(sensor_normal_ned(-90 * kDeg, -90 * kDeg, 0), 0, -1, 0);
}

TEST(Sun, DiffuserTransmissionByHand) {
  // Straight on: two interfaces, R = ((n1 - n2) / (n1 + n2))^2 each.
  const double r1 = std::pow((1.6 - 1.000277) / (1.6 + 1.000277), 2);
  const double r2 = std::pow((1.38 - 1.6) / (1.38 + 1.6), 2);
  EXPECT_NEAR(dls_transmission(0), (1 - r1) * (1 - r2), 1e-12);
  // MicaSense's test figures at a slant.
  EXPECT_NEAR(dls_transmission(0.50), 0.940, 1e-3);
  EXPECT_NEAR(dls_transmission(0.99), 0.903, 1e-3);
  EXPECT_NEAR(dls_transmission(1.00), 0.901, 1e-3);
  // Straight overhead and level: the reading is direct + diffuse as is.
  EXPECT_NEAR(dls1_horizontal_irradiance(1.0, 0, kPi / 2), 1.0 / dls_transmission(0), 1e-12);
}

}  // namespace
}  // namespace ddhgs::io
