// WGS84 latitude and longitude to Universal Transverse Mercator and back:
// the projected CRS a georeferenced flight is placed in (metres east and
// north in its zone, EPSG 326zz north of the equator, 327zz south).
// Krueger's series to sixth order in the third flattening (Karney 2011,
// "Transverse Mercator with an accuracy of a few nanometers"): well under a
// millimetre within a zone.
#pragma once

namespace ddhgs::core {

struct UtmZone {
  int number = 0;  // 1..60
  bool north = true;
  int epsg() const { return (north ? 32600 : 32700) + number; }
};

struct UtmPoint {
  double easting_m = 0, northing_m = 0;
};

// The zone a position lies in (with the Norway and Svalbard exceptions);
// north from latitude >= 0. core::Error when latitude is outside -80..84 or
// longitude outside -180..180 degrees (no UTM there).
UtmZone utm_zone(double latitude_deg, double longitude_deg);

// The position in `zone` (any zone: a flight crossing a zone boundary stays
// in its first one, as surveys do).
UtmPoint to_utm(double latitude_deg, double longitude_deg, const UtmZone& zone);

struct LatLon {
  double latitude_deg = 0, longitude_deg = 0;
};
// The inverse of to_utm.
LatLon from_utm(const UtmPoint& point, const UtmZone& zone);

}  // namespace ddhgs::core
