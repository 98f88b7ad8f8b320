// A synthetic survey's place on the earth and the truths a georeferenced
// model is measured against. The world's origin lies at the GPS origin;
// world x is grid east and y grid north in the origin's UTM zone and z is
// height, all in metres, so the world maps to the projected CRS by a
// translation alone. Each capture's EXIF GPS comes from its true position
// through that map (and UTM's inverse); the orthographic truth is the clean
// scene seen straight down over the flight's footprint; ground control
// points are marks on the ground with known projected coordinates.
#pragma once
#include <nlohmann/json.hpp>

#include <vector>

#include "core/camera.h"
#include "core/utm.h"
#include "synth/generate.h"
#include "synth/render.h"

namespace ddhgs::synth {

struct WorldPlacement {
  core::UtmZone zone;
  double easting_m = 0, northing_m = 0, height_m = 0;  // the world origin's
  // The projected coordinates (east, north, height) of a world point.
  core::Vec3 to_crs(const core::Vec3& world) const {
    return {easting_m + world.x, northing_m + world.y, height_m + world.z};
  }
};

// core::Error naming --gps-origin when the origin is outside UTM.
WorldPlacement world_placement(const SynthConfig& config);

// The WGS84 position (degrees, metres above the ellipsoid) of a world point.
struct GpsFix {
  double latitude_deg = 0, longitude_deg = 0, altitude_m = 0;
};
GpsFix gps_fix(const WorldPlacement& place, const core::Vec3& world);

// The ground the nadir cameras see (the union of their footprints on z = 0)
// at the flight's own ground sample distance (the first camera's at z = 0),
// whole pixels, north up, its edges on whole multiples of the pixel in the
// projected CRS (as `render --ortho` aligns its grid).
OrthoGrid flight_footprint(const std::vector<core::Camera>& cameras, const WorldPlacement& place);

// Four marks on the ground (z = 0) around the world's origin, inside the
// grid and the ground disc (ground_radius, scene units), each with its
// world and projected coordinates.
nlohmann::json ground_control_points(const WorldPlacement& place, const OrthoGrid& grid,
                                     double ground_radius);

// The grid's GDAL geotransform in the projected CRS: left, pixel, 0, top,
// 0, -pixel (metres).
std::vector<double> geotransform(const WorldPlacement& place, const OrthoGrid& grid);

}  // namespace ddhgs::synth
