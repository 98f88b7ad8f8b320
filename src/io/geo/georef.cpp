#include "io/geo/georef.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/text.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

double georef_number(const json& value, const fs::path& path, const std::string& key) {
  if (!value.is_number() || !std::isfinite(value.get<double>()))
    throw core::Error(path, key + ": expected a finite number");
  return value.get<double>();
}

const json& georef_field(const json& object, const char* key, const fs::path& path,
                         const std::string& where) {
  if (!object.is_object() || !object.contains(key))
    throw core::Error(path, "expected " + where + key);
  return object[key];
}

}  // namespace

core::Vec3 Georeference::scene_up() const {
  // The CRS's up (0, 0, 1) in the scene: the third row of the rotation.
  const core::Mat3& r = scene_to_crs.rotation;
  return {r(2, 0), r(2, 1), r(2, 2)};
}

void write_georeference(const fs::path& path, const Georeference& g) {
  const core::Similarity& s = g.scene_to_crs;
  json rotation = json::array();
  for (int i = 0; i < 3; ++i)
    rotation.push_back({s.rotation(i, 0), s.rotation(i, 1), s.rotation(i, 2)});
  const json root = {
      {"crs", "EPSG:" + std::to_string(g.epsg)},
      {"epsg", g.epsg},
      {"scene_to_crs",
       {{"scale", s.scale},
        {"rotation", rotation},
        {"translation", {s.translation.x, s.translation.y, s.translation.z}},
        {"meaning", "crs = scale * rotation * scene + translation (metres east, north, height)"}}},
      {"fit",
       {{"captures", g.captures},
        {"gps_rms_m", g.rms_m},
        {"gps_worst_m", g.worst_m},
        {"gps_worst_capture", g.worst_capture},
        {"orientation_from", g.orientation_from}}}};
  write_file_atomically(path, root.dump(2) + "\n");
}

Georeference read_georeference(const fs::path& path) {
  require_regular_file(path);
  json root;
  try {
    root = json::parse(read_file(path));
  } catch (const json::exception& e) {
    throw core::Error(path, "not valid JSON: " + core::message_of(e));
  }
  Georeference g;
  const json& epsg = georef_field(root, "epsg", path, "");
  if (!epsg.is_number_integer() || epsg.get<int64_t>() <= 0 || epsg.get<int64_t>() > 1000000)
    throw core::Error(path, "epsg: expected a positive integer EPSG code, got " +
                                core::quoted_value(epsg.dump()));
  g.epsg = epsg.get<int>();
  const json& s = georef_field(root, "scene_to_crs", path, "");
  g.scene_to_crs.scale =
      georef_number(georef_field(s, "scale", path, "scene_to_crs."), path, "scene_to_crs.scale");
  if (!(g.scene_to_crs.scale > 0))
    throw core::Error(path, "scene_to_crs.scale: expected a positive number");
  const json& r = georef_field(s, "rotation", path, "scene_to_crs.");
  const json& t = georef_field(s, "translation", path, "scene_to_crs.");
  if (!r.is_array() || r.size() != 3 || !t.is_array() || t.size() != 3)
    throw core::Error(path, "scene_to_crs: expected a 3x3 rotation and a translation of 3");
  for (int i = 0; i < 3; ++i) {
    if (!r[size_t(i)].is_array() || r[size_t(i)].size() != 3)
      throw core::Error(path, "scene_to_crs.rotation: expected 3 rows of 3 numbers");
    for (int k = 0; k < 3; ++k)
      g.scene_to_crs.rotation(i, k) =
          georef_number(r[size_t(i)][size_t(k)], path, "scene_to_crs.rotation");
  }
  g.scene_to_crs.translation = {georef_number(t[0], path, "scene_to_crs.translation"),
                                georef_number(t[1], path, "scene_to_crs.translation"),
                                georef_number(t[2], path, "scene_to_crs.translation")};
  // A rotation: orthonormal rows, determinant +1 (to the digits JSON keeps).
  const core::Mat3 rr = g.scene_to_crs.rotation * g.scene_to_crs.rotation.transposed();
  double off = std::abs(g.scene_to_crs.rotation.determinant() - 1);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) off = std::max(off, std::abs(rr(i, k) - (i == k ? 1.0 : 0.0)));
  if (off > 1e-6)
    throw core::Error(path, "scene_to_crs.rotation is not a rotation (orthonormal, determinant 1)");
  if (root.contains("fit") && root["fit"].is_object()) {
    const json& f = root["fit"];
    try {
      g.captures = f.value("captures", 0);
      g.rms_m = f.value("gps_rms_m", 0.0);
      g.worst_m = f.value("gps_worst_m", 0.0);
      g.worst_capture = f.value("gps_worst_capture", std::string());
      g.orientation_from = f.value("orientation_from", std::string());
    } catch (const json::exception& e) {
      throw core::Error(path, "fit: " + core::message_of(e));
    }
  }
  return g;
}

std::optional<Georeference> find_georeference(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir / kGeorefFile, ec)) return std::nullopt;
  return read_georeference(dir / kGeorefFile);
}

std::string describe_georeference(const Georeference& g) {
  char line[320];
  std::snprintf(line, sizeof line,
                "EPSG:%d, %.6g m per scene unit; GPS residuals over %d captures: RMS %.3g m, "
                "worst %.3g m (%s); orientation from %s",
                g.epsg, g.scene_to_crs.scale, g.captures, g.rms_m, g.worst_m,
                g.worst_capture.empty() ? "-" : g.worst_capture.c_str(),
                g.orientation_from.c_str());
  return line;
}

}  // namespace ddhgs::io
