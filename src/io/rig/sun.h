// Where the sun stands, and what a downwelling light sensor (DLS) on a
// multispectral rig therefore measured.
//
// A DLS 1 (MicaSense RedEdge's first light sensor) reports the spectral
// irradiance on its own diffuser, which tilts with the aircraft and sits
// behind two layers (polycarbonate over PTFE) that reflect part of the light
// that reaches them at a slant. MicaSense's library turns that reading into
// the irradiance on level ground under a clear sky:
//   sensor  = measured / T(theta)                 theta: sun-to-sensor-normal angle
//   direct  = sensor / (cos(theta) + 1/6)         a clear sky: direct / diffuse = 6
//   ground  = direct * (sin(elevation) + 1/6)
// with T the unpolarised Fresnel transmission of air -> polycarbonate (n 1.6)
// -> PTFE (n 1.38). The functions here compute each step; io/rig/rig_capture
// applies them to a DLS 1 reading whose file gives the time, the position and
// the sensor's attitude.
#pragma once
#include <array>

namespace ddhgs::io {

// The sun seen from a place on Earth at a moment: elevation above the
// horizon (radians, with the mean atmospheric refraction) and azimuth
// (radians clockwise from north, [0, 2 pi)). NOAA's solar position
// equations (after Meeus), accurate to about 0.01 degree between 1900 and
// 2100. unix_seconds: UTC seconds since 1970-01-01.
struct SunPosition {
  double elevation = 0;
  double azimuth = 0;
};
SunPosition sun_position(double latitude_deg, double longitude_deg, double unix_seconds);

// The unit vector towards the sun in local North-East-Down axes.
std::array<double, 3> sun_direction_ned(const SunPosition& sun);

// The DLS's upward normal in North-East-Down axes for the sensor's attitude
// (yaw, pitch, roll in radians, body axes x forward, y right, z down, turned
// by yaw about z, then pitch about y, then roll about x).
std::array<double, 3> sensor_normal_ned(double yaw, double pitch, double roll);

// The DLS diffuser's transmission for light arriving `theta` radians off its
// normal (0.9416 straight on).
double dls_transmission(double theta);

// A DLS 1 reading (W/m^2/nm on the tilted sensor) as irradiance on level
// ground, by the model above. theta: the sun-to-normal angle; elevation: the
// sun's, both radians.
double dls1_horizontal_irradiance(double measured, double theta, double elevation);

}  // namespace ddhgs::io
