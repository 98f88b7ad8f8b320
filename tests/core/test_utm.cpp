// WGS84 <-> UTM against PROJ 9.1.1's values (gdaltransform -s_srs EPSG:4326
// -t_srs EPSG:326zz/327zz, printed to the micrometre) in four zones, both
// hemispheres and the Norway exception; the inverse returns the position.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/utm.h"

namespace ddhgs::core {
namespace {

struct Known {
  double lat, lon;
  int zone;
  bool north;
  double easting, northing;
};

const Known kKnown[] = {
    {55.9533, -3.1883, 30, true, 488241.991074286, 6200898.03266121},     // Edinburgh
    {37.7749, -122.4194, 10, true, 551130.768481284, 4180998.88149906},   // San Francisco
    {-33.8688, 151.2093, 56, false, 334368.633648097, 6250948.34538501},  // Sydney
    {60.2, 10.5, 32, true, 583156.206022087, 6674629.72822505},           // Norway, zone 32
};

TEST(Utm, MatchesProjAtKnownPoints) {
  for (const Known& k : kKnown) {
    const UtmZone zone = utm_zone(k.lat, k.lon);
    EXPECT_EQ(zone.number, k.zone);
    EXPECT_EQ(zone.north, k.north);
    EXPECT_EQ(zone.epsg(), (k.north ? 32600 : 32700) + k.zone);
    const UtmPoint p = to_utm(k.lat, k.lon, zone);
    EXPECT_NEAR(p.easting_m, k.easting, 1e-4) << k.lat << ", " << k.lon;
    EXPECT_NEAR(p.northing_m, k.northing, 1e-4) << k.lat << ", " << k.lon;
  }
}

TEST(Utm, InverseReturnsThePosition) {
  for (const Known& k : kKnown) {
    const UtmZone zone = utm_zone(k.lat, k.lon);
    const LatLon back = from_utm({k.easting, k.northing}, zone);
    // 1e-9 degrees is about 0.1 mm.
    EXPECT_NEAR(back.latitude_deg, k.lat, 1e-9);
    EXPECT_NEAR(back.longitude_deg, k.lon, 1e-9);
  }
  // Far from the central meridian (3.5 degrees) the series still holds.
  const UtmZone zone{33, true};
  const UtmPoint p = to_utm(47.25, 11.5, zone);
  const LatLon back = from_utm(p, zone);
  EXPECT_NEAR(back.latitude_deg, 47.25, 1e-9);
  EXPECT_NEAR(back.longitude_deg, 11.5, 1e-9);
}

TEST(Utm, RefusesPositionsOutsideUtm) {
  EXPECT_THROW(utm_zone(85, 0), Error);
  EXPECT_THROW(utm_zone(0, 181), Error);
  EXPECT_THROW(to_utm(0, 0, UtmZone{0, true}), Error);
}

}  // namespace
}  // namespace ddhgs::core
