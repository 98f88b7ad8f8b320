#include "process/georeference.h"

#include "core/tensor.h"

#include <torch/linalg.h>
#include <cmath>

#include "core/error.h"
#include "core/similarity.h"
#include "core/utm.h"

namespace ddhgs::process {

namespace {

// The square root of the second largest over the largest eigenvalue of the
// points' scatter: 0 for points on a line, about 1 for a round cloud.
double planarity(const std::vector<core::Vec3>& points) {
  core::Vec3 mean;
  for (const core::Vec3& p : points) mean = mean + p * (1.0 / double(points.size()));
  torch::Tensor scatter = torch::zeros({3, 3}, torch::kFloat64);
  auto s = scatter.accessor<double, 2>();
  for (const core::Vec3& p : points) {
    const core::Vec3 d = p - mean;
    const double v[3] = {d.x, d.y, d.z};
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) s[i][k] += v[i] * v[k];
  }
  const torch::Tensor eig = torch::linalg_eigvalsh(scatter, "L");  // ascending
  const double largest = eig[2].item<double>(), second = eig[1].item<double>();
  return largest > 0 ? std::sqrt(std::max(second, 0.0) / largest) : 0;
}

}  // namespace

io::Georeference fit_georeference(const std::vector<GpsCapture>& captures) {
  core::require(captures.size() >= 3, "georeference: " + std::to_string(captures.size()) +
                                          " captures with GPS; at least 3 are needed");
  double lat = 0, lon = 0;
  for (const GpsCapture& c : captures) {
    lat += c.latitude_deg / double(captures.size());
    lon += c.longitude_deg / double(captures.size());
  }
  const core::UtmZone zone = core::utm_zone(lat, lon);
  std::vector<core::Vec3> from, to;
  for (const GpsCapture& c : captures) {
    const core::UtmPoint p = core::to_utm(c.latitude_deg, c.longitude_deg, zone);
    from.push_back(c.centre);
    to.push_back({p.easting_m, p.northing_m, c.altitude_m});
  }
  const double spread_from = core::rms_spread(from), spread_to = core::rms_spread(to);
  core::require(spread_from > 0 && spread_to > 0,
                "georeference: the captures' GPS positions (or their poses) all coincide; no "
                "scale can be fitted");
  io::Georeference g;
  g.epsg = zone.epsg();
  g.captures = int(captures.size());
  // A line of captures (the second spread under a tenth of the first): the
  // mean viewing direction is down.
  std::vector<core::Vec3> fit_from = from, fit_to = to;
  if (planarity(from) < 0.1) {
    g.orientation_from = "nadir (one line of captures: the rig's mean viewing axis is down)";
    const double scale = spread_to / spread_from;
    for (const GpsCapture& c : captures) {
      fit_from.push_back(c.centre + c.forward.normalized() * spread_from);
      const core::UtmPoint p = core::to_utm(c.latitude_deg, c.longitude_deg, zone);
      fit_to.push_back({p.easting_m, p.northing_m, c.altitude_m - spread_from * scale});
    }
  }
  g.scene_to_crs = core::fit_similarity(fit_from, fit_to);
  double sum = 0;
  for (size_t i = 0; i < from.size(); ++i) {
    const double e = (to[i] - g.scene_to_crs.apply(from[i])).norm();
    sum += e * e;
    if (e >= g.worst_m) {
      g.worst_m = e;
      g.worst_capture = captures[i].id;
    }
  }
  g.rms_m = std::sqrt(sum / double(from.size()));
  return g;
}

}  // namespace ddhgs::process
