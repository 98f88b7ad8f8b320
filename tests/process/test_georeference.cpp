// The georeference fit: a known similarity (scale, turn, translation) from
// a scene frame to UTM is recovered from GPS positions made through it,
// for captures over a plane (flight lines) and for a single straight strip
// (its roll from the nadir viewing direction); GPS noise shows in the
// residuals and the worst capture is named; coincident positions are
// refused.
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "core/utm.h"
#include "process/georeference.h"

namespace ddhgs::process {
namespace {

core::Similarity truth() {
  core::Similarity s;
  s.scale = 3.2;
  s.rotation = core::quat_to_rotation(0.7, -0.2, 0.5, 0.4);
  s.translation = {681200.0, 5743100.0, 150.0};
  return s;
}

const core::UtmZone kZone{30, true};

// Captures at CRS positions (east, north, height), looking straight down.
std::vector<GpsCapture> captures(const std::vector<core::Vec3>& crs, double noise_m,
                                 uint64_t seed) {
  const core::Similarity s = truth();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0, noise_m);
  std::vector<GpsCapture> out;
  for (size_t i = 0; i < crs.size(); ++i) {
    GpsCapture c;
    c.id = "capture" + std::to_string(i);
    c.centre = (s.rotation.transposed() * (crs[i] - s.translation)) * (1 / s.scale);
    c.forward = s.rotation.transposed() * core::Vec3{0, 0, -1};
    const core::Vec3 noisy =
        noise_m > 0 ? crs[i] + core::Vec3{normal(rng), normal(rng), normal(rng)} : crs[i];
    const core::LatLon ll = core::from_utm({noisy.x, noisy.y}, kZone);
    c.latitude_deg = ll.latitude_deg;
    c.longitude_deg = ll.longitude_deg;
    c.altitude_m = noisy.z;
    out.push_back(c);
  }
  return out;
}

void expect_truth(const io::Georeference& g, double tolerance_m) {
  const core::Similarity s = truth();
  EXPECT_EQ(g.epsg, 32630);
  EXPECT_NEAR(g.scene_to_crs.scale, s.scale, 1e-6 * s.scale + tolerance_m / 20);
  // A point 10 m from the captures lands where the truth puts it.
  for (const core::Vec3& p : {core::Vec3{0, 0, 0}, core::Vec3{3, -2, 1}}) {
    const core::Vec3 e = g.scene_to_crs.apply(p) - s.apply(p);
    EXPECT_LT(e.norm(), tolerance_m) << p.x << " " << p.y << " " << p.z;
  }
}

TEST(Georeference, RecoversTheSimilarityFromFlightLines) {
  std::vector<core::Vec3> crs;
  for (int line = 0; line < 3; ++line)
    for (int i = 0; i < 6; ++i)
      crs.push_back({681190.0 + 8 * i, 5743090.0 + 12 * line, 160.0 + 0.3 * line});
  const io::Georeference g = fit_georeference(captures(crs, 0, 1));
  expect_truth(g, 1e-3);
  EXPECT_EQ(g.captures, 18);
  EXPECT_LT(g.rms_m, 1e-3);
  EXPECT_EQ(g.orientation_from, "camera centres");
}

TEST(Georeference, AStraightStripTakesItsRollFromTheViewingDirection) {
  std::vector<core::Vec3> crs;
  for (int i = 0; i < 8; ++i) crs.push_back({681190.0 + 1.5 * i, 5743095.0 + 0.8 * i, 161.0});
  const io::Georeference g = fit_georeference(captures(crs, 0, 2));
  expect_truth(g, 1e-3);
  EXPECT_NE(g.orientation_from.find("nadir"), std::string::npos);
  // The centres alone could not have fixed it.
  std::vector<core::Vec3> from, to;
  for (const GpsCapture& c : captures(crs, 0, 2)) from.push_back(c.centre);
  EXPECT_THROW(core::fit_similarity(from, from), core::Error);
}

TEST(Georeference, GpsNoiseShowsInTheResidualsAndTheWorstCaptureIsNamed) {
  std::vector<core::Vec3> crs;
  for (int line = 0; line < 4; ++line)
    for (int i = 0; i < 10; ++i) crs.push_back({681150.0 + 10 * i, 5743050.0 + 15 * line, 180.0});
  std::vector<GpsCapture> c = captures(crs, 0.5, 3);
  // One capture's GPS 6 m off.
  const core::LatLon ll = core::from_utm({crs[17].x + 6, crs[17].y}, kZone);
  c[17].latitude_deg = ll.latitude_deg;
  c[17].longitude_deg = ll.longitude_deg;
  const io::Georeference g = fit_georeference(c);
  EXPECT_EQ(g.worst_capture, "capture17");
  EXPECT_GT(g.worst_m, 4);
  EXPECT_GT(g.rms_m, 0.5);
  EXPECT_LT(g.rms_m, 1.6);
  expect_truth(g, 1.0);  // 40 captures average the noise down
}

TEST(Georeference, RefusesTooFewOrCoincidentCaptures) {
  std::vector<core::Vec3> crs = {{681190.0, 5743095.0, 161.0}, {681192.0, 5743095.0, 161.0}};
  EXPECT_THROW(fit_georeference(captures(crs, 0, 4)), core::Error);
  crs.push_back({681194.0, 5743095.0, 161.0});
  std::vector<GpsCapture> same = captures(crs, 0, 4);
  for (GpsCapture& c : same)
    c.latitude_deg = same[0].latitude_deg, c.longitude_deg = same[0].longitude_deg,
    c.altitude_m = same[0].altitude_m;
  EXPECT_THROW(fit_georeference(same), core::Error);
}

}  // namespace
}  // namespace ddhgs::process
