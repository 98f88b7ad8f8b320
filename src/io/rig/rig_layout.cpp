#include "io/rig/rig_layout.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/rig/rig_capture.h"

namespace ddhgs::io {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kDegrees = 180 / 3.14159265358979323846;

json vec_json(const core::Vec3& v, double scale = 1) {
  return json::array({v.x * scale, v.y * scale, v.z * scale});
}

core::Vec3 read_vec(const json& value, const fs::path& path, const std::string& where) {
  if (!value.is_array() || value.size() != 3)
    throw core::Error(path, where + ": expected 3 numbers");
  double v[3];
  for (int i = 0; i < 3; ++i) {
    if (!value[size_t(i)].is_number() || !std::isfinite(value[size_t(i)].get<double>()))
      throw core::Error(path, where + ": expected 3 finite numbers");
    v[i] = value[size_t(i)].get<double>();
  }
  return {v[0], v[1], v[2]};
}

}  // namespace

core::Mat3 rotation_from_vector(const core::Vec3& r) {
  const double angle = r.norm();
  if (angle == 0) return core::Mat3{};
  const core::Vec3 v = r * (std::sin(0.5 * angle) / angle);
  return core::quat_to_rotation(std::cos(0.5 * angle), v.x, v.y, v.z);
}

core::Vec3 rotation_vector(const core::Mat3& rotation) {
  std::array<double, 4> q = core::rotation_to_quat(rotation);
  if (q[0] < 0)
    for (double& c : q) c = -c;
  const core::Vec3 v{q[1], q[2], q[3]};
  const double s = v.norm();
  if (s == 0) return {};
  return v * (2 * std::atan2(s, q[0]) / s);
}

const RigCameraInfo* TransformsRig::camera(int index) const {
  for (const RigCameraInfo& c : cameras)
    if (c.index == index) return &c;
  return nullptr;
}

core::Mat3 TransformsRig::turn(int index) const {
  const RigCameraInfo* c = camera(index);
  const RigCameraInfo* ref = camera(reference_camera);
  core::require(c && ref, "rig: no camera " + std::to_string(c ? reference_camera : index));
  return rig_relative_rotation(c->relatives_deg) *
         rig_relative_rotation(ref->relatives_deg).transposed();
}

core::Camera corrected_band_camera(const core::Camera& camera, const core::Mat3& turn,
                                   const RigCorrection& correction) {
  // x_cam = T D (x_ref - o) with x_ref = T^T W x: rotation T D T^T R_W,
  // translation T D T^T t_W - T D o.
  const core::Mat3 td = turn * rotation_from_vector(correction.rotation_rad);
  const core::Mat3 spin = td * turn.transposed();
  core::Camera out = camera;
  const core::Mat4& w = camera.world_to_camera;
  out.world_to_camera =
      core::Mat4::from(spin * w.rotation(), spin * w.translation() - td * correction.offset);
  return out;
}

json rig_corrections_json(const TransformsRig& rig,
                          const std::map<int, RigCorrection>& corrections) {
  json cameras = json::array();
  for (const auto& [index, c] : corrections) {
    const RigCameraInfo* info = rig.camera(index);
    json entry = {{"rig_camera", index},
                  {"band", info ? info->band : std::string()},
                  {"rotation_rad", vec_json(c.rotation_rad)},
                  {"rotation_deg", c.rotation_rad.norm() * kDegrees},
                  {"offset", vec_json(c.offset)}};
    if (rig.unit_m > 0) {
      entry["offset_cm"] = vec_json(c.offset, 100 * rig.unit_m);
      entry["offset_length_cm"] = c.offset.norm() * 100 * rig.unit_m;
    }
    cameras.push_back(entry);
  }
  json out = {{"reference_camera", rig.reference_camera},
              {"axes", "the reference camera's (OpenCV: x right, y down, z forward)"},
              {"offset_unit", "scene units"},
              {"cameras", cameras}};
  if (rig.unit_m > 0) out["unit_m"] = rig.unit_m;
  return out;
}

std::string describe_rig_correction(const TransformsRig& rig, int index,
                                    const RigCorrection& correction) {
  const RigCameraInfo* info = rig.camera(index);
  const bool metric = rig.unit_m > 0;
  const core::Vec3 o = correction.offset * (metric ? 100 * rig.unit_m : 1.0);
  char text[256];
  std::snprintf(text, sizeof text,
                "camera %d%s: turned %.3f deg, centre moved by (%.2f, %.2f, %.2f) %s (reference "
                "camera axes)",
                index, info && !info->band.empty() ? (" (" + info->band + ")").c_str() : "",
                correction.rotation_rad.norm() * kDegrees, o.x, o.y, o.z,
                metric ? "cm" : "scene units");
  return text;
}

void write_rig_corrections(const fs::path& path, const TransformsRig& rig,
                           const std::map<int, RigCorrection>& corrections) {
  write_file_atomically(path, rig_corrections_json(rig, corrections).dump(2) + "\n");
}

std::map<int, RigCorrection> read_rig_corrections(const fs::path& path, double unit_m) {
  json root;
  try {
    root = json::parse(read_file(path));
  } catch (const json::exception& e) {
    throw core::Error(path, "not valid JSON: " + core::message_of(e));
  }
  if (!root.is_object() || !root.contains("cameras") || !root["cameras"].is_array())
    throw core::Error(path, "expected an object with a \"cameras\" list");
  std::map<int, RigCorrection> out;
  for (size_t i = 0; i < root["cameras"].size(); ++i) {
    const json& c = root["cameras"][i];
    const std::string where = "cameras[" + std::to_string(i) + "]";
    if (!c.is_object() || !c.contains("rig_camera") || !c["rig_camera"].is_number_integer() ||
        !(c.contains("offset") || c.contains("offset_cm")))
      throw core::Error(path,
                        where + ": expected rig_camera and offset (scene units) or offset_cm");
    const int index = c["rig_camera"].get<int>();
    if (out.count(index))
      throw core::Error(path, where + ": rig camera " + std::to_string(index) + " is given twice");
    RigCorrection correction;
    if (c.contains("rotation_rad"))
      correction.rotation_rad = read_vec(c["rotation_rad"], path, where + ".rotation_rad");
    if (c.contains("offset")) {
      correction.offset = read_vec(c["offset"], path, where + ".offset");
    } else {
      if (!(unit_m > 0))
        throw core::Error(path, where +
                                    ": gives offset_cm, but this scene's unit is unknown (posed "
                                    "without GPS or metric poses): give offset in scene units");
      correction.offset = read_vec(c["offset_cm"], path, where + ".offset_cm") * (0.01 / unit_m);
    }
    out[index] = correction;
  }
  return out;
}

}  // namespace ddhgs::io
