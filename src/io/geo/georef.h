// A georeferenced scene's place in a projected CRS: georef.json in the
// scene folder (docs/data-formats.md). A similarity takes the scene's frame
// to the CRS's metres (east, north, height): crs = scale R x + t. Written by
// `ddhgs process --rig` from the captures' GPS, copied into a run folder by
// training, read by `info` and `render --ortho`.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

#include "core/similarity.h"

namespace ddhgs::io {

struct Georeference {
  int epsg = 0;  // the projected CRS (UTM: 326zz north, 327zz south)
  core::Similarity scene_to_crs;
  // How the fit went: captures used, GPS residuals after the fit (m) and the
  // capture with the largest, and what fixed the turn about a single line
  // of captures ("camera centres" when they span a plane, else "nadir").
  int captures = 0;
  double rms_m = 0, worst_m = 0;
  std::string worst_capture;
  std::string orientation_from = "camera centres";

  // The scene frame's unit vector that points up in the CRS.
  core::Vec3 scene_up() const;
};

inline const char* kGeorefFile = "georef.json";

void write_georeference(const std::filesystem::path& path, const Georeference& georef);

// core::Error naming the file when it is not JSON, lacks a field, or holds
// a value out of range (an EPSG code that is not a positive integer, a
// scale that is not positive and finite, a rotation that is not one).
Georeference read_georeference(const std::filesystem::path& path);

// dir/georef.json when it exists, else nullopt.
std::optional<Georeference> find_georeference(const std::filesystem::path& dir);

// One line for `info` and logs: CRS, scale, residuals.
std::string describe_georeference(const Georeference& georef);

}  // namespace ddhgs::io
