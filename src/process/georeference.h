// A rig flight's georeference: the similarity from the scene's frame (the
// poses COLMAP or --poses gave) to UTM, fitted to each capture's GPS
// (Umeyama, core::fit_similarity), with the residuals a user checks.
//
// The captures of a single straight strip lie on one line, about which GPS
// cannot fix the turn: then the rig's mean viewing axis (the frame its
// RigRelatives are given in) is taken as straight down (a nadir survey's),
// added to the fit as a second point per capture one spread below it. Captures spread over a plane
// (flight lines, a ring) fix the turn themselves and the fit uses their centres alone.
#pragma once
#include <string>
#include <vector>

#include "core/mat.h"
#include "io/geo/georef.h"

namespace ddhgs::process {

struct GpsCapture {
  std::string id;
  double latitude_deg = 0, longitude_deg = 0, altitude_m = 0;  // WGS84, EXIF GPS
  core::Vec3 centre;   // the posed camera's centre, scene frame
  core::Vec3 forward;  // the rig's viewing axis (its frame's +z), scene frame
};

// The UTM zone of the captures' mean position. core::Error when there are
// fewer than 3 captures, or their GPS positions (or their centres) all
// coincide, so that no scale can be fitted.
io::Georeference fit_georeference(const std::vector<GpsCapture>& captures);

}  // namespace ddhgs::process
