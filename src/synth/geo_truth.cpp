#include "synth/geo_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace ddhgs::synth {

WorldPlacement world_placement(const SynthConfig& config) {
  WorldPlacement place;
  try {
    place.zone = core::utm_zone(config.gps_latitude_deg, config.gps_longitude_deg);
  } catch (const core::Error& e) {
    throw core::Error("--gps-origin", e.what());
  }
  const core::UtmPoint origin =
      core::to_utm(config.gps_latitude_deg, config.gps_longitude_deg, place.zone);
  place.easting_m = origin.easting_m;
  place.northing_m = origin.northing_m;
  place.height_m = config.gps_ground_m;
  return place;
}

GpsFix gps_fix(const WorldPlacement& place, const core::Vec3& world) {
  const core::Vec3 crs = place.to_crs(world);
  const core::LatLon ll = core::from_utm({crs.x, crs.y}, place.zone);
  return {ll.latitude_deg, ll.longitude_deg, crs.z};
}

OrthoGrid flight_footprint(const std::vector<core::Camera>& cameras, const WorldPlacement& place) {
  core::require(!cameras.empty(), "synth: a footprint needs cameras");
  double left = std::numeric_limits<double>::max(), right = -left, bottom = left, top = -left;
  double pixel = 0;
  for (const core::Camera& camera : cameras) {
    const core::Intrinsics& k = camera.intrinsics;
    const core::Mat4 c2w = camera.camera_to_world();
    const core::Vec3 eye = c2w.translation();
    for (double u : {0.0, double(k.width)})
      for (double v : {0.0, double(k.height)}) {
        const core::Vec3 d = c2w.rotation() * core::Vec3{(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1};
        core::require(d.z < 0, "synth: a footprint needs cameras looking down");
        const core::Vec3 ground = eye + d * (-eye.z / d.z);
        left = std::min(left, ground.x);
        right = std::max(right, ground.x);
        bottom = std::min(bottom, ground.y);
        top = std::max(top, ground.y);
      }
    if (pixel == 0) pixel = eye.z / k.fx;
  }
  // Edges on whole multiples of the pixel in the CRS, as `render --ortho`
  // puts its own (GDAL's target-aligned pixels): a mosaic at this GSD then
  // shares the truth's pixels, and no resampling blurs the comparison.
  OrthoGrid grid;
  grid.pixel = pixel;
  grid.left = std::floor((place.easting_m + left) / pixel) * pixel - place.easting_m;
  grid.top = std::ceil((place.northing_m + top) / pixel) * pixel - place.northing_m;
  grid.width = int(std::ceil((right - grid.left) / pixel));
  grid.height = int(std::ceil((grid.top - bottom) / pixel));
  return grid;
}

nlohmann::json ground_control_points(const WorldPlacement& place, const OrthoGrid& grid,
                                     double ground_radius) {
  // Four marks on the textured ground around the plant (at the origin),
  // inside the footprint.
  const double hx = std::min(0.7 * ground_radius, 0.35 * grid.width * grid.pixel);
  const double hy = std::min(0.3 * ground_radius, 0.3 * grid.height * grid.pixel);
  const double cy = grid.top - 0.5 * grid.height * grid.pixel;
  const double offsets[][2] = {{-1, -1}, {1, -1}, {-1, 1}, {1, 1}};
  nlohmann::json points = nlohmann::json::array();
  int i = 1;
  for (const auto& o : offsets) {
    const core::Vec3 world{o[0] * hx, cy + o[1] * hy, 0};
    const core::Vec3 crs = place.to_crs(world);
    points.push_back({{"name", "GCP" + std::to_string(i++)},
                      {"world_xyz", {world.x, world.y, world.z}},
                      {"easting_m", crs.x},
                      {"northing_m", crs.y},
                      {"height_m", crs.z}});
  }
  return points;
}

std::vector<double> geotransform(const WorldPlacement& place, const OrthoGrid& grid) {
  const core::Vec3 corner = place.to_crs({grid.left, grid.top, 0});
  return {corner.x, grid.pixel, 0, corner.y, 0, -grid.pixel};
}

}  // namespace ddhgs::synth
