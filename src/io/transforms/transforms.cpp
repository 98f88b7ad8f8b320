#include "io/transforms/transforms.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>

#include "core/error.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Every lookup names the file and the JSON location, so a user can fix the
// file from the message alone (nlohmann's own type errors name neither).
class Reader {
 public:
  explicit Reader(fs::path path) : path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
    throw core::Error(path_, where + ": " + problem);
  }

  const json* find(const json& object, const std::string& key) const {
    auto it = object.find(key);
    return it == object.end() || it->is_null() ? nullptr : &*it;
  }

  double number(const json& value, const std::string& where) const {
    if (!value.is_number()) fail(where, "expected a number, found " + type_name(value));
    double v = value.get<double>();
    if (!std::isfinite(v)) fail(where, "expected a finite number");
    return v;
  }

  double positive(const json& value, const std::string& where, const std::string& what) const {
    double v = number(value, where);
    if (v <= 0) fail(where, "expected " + what + " > 0, found " + value.dump());
    return v;
  }

  std::string string(const json& value, const std::string& where) const {
    if (!value.is_string()) fail(where, "expected a string, found " + type_name(value));
    std::string text = value.get<std::string>();
    // No value here (file names, camera models) holds a NUL byte; the
    // system would cut a file name at it and read another file.
    if (text.find('\0') != std::string::npos) fail(where, "holds a NUL byte (\\u0000)");
    return text;
  }

  const json& array(const json& value, const std::string& where) const {
    if (!value.is_array()) fail(where, "expected an array, found " + type_name(value));
    return value;
  }

  std::vector<std::string> strings(const json& value, const std::string& where) const {
    std::vector<std::string> out;
    const json& list = array(value, where);
    for (size_t i = 0; i < list.size(); ++i)
      out.push_back(string(list[i], where + "[" + std::to_string(i) + "]"));
    return out;
  }

  // A key given per frame wins over the top-level one (nerfstudio semantics).
  const json* lookup(const json& frame, const json& root, const std::string& key) const {
    if (const json* v = find(frame, key)) return v;
    return find(root, key);
  }

  core::Mat4 matrix(const json& value, const std::string& where) const {
    const json& rows = array(value, where);
    // 3x4 is accepted too: some tools drop the constant last row.
    if (rows.size() != 4 && rows.size() != 3)
      fail(where, "expected a 4x4 matrix, found " + std::to_string(rows.size()) + " rows");
    core::Mat4 m;
    for (size_t r = 0; r < rows.size(); ++r) {
      std::string row_where = where + "[" + std::to_string(r) + "]";
      const json& row = array(rows[r], row_where);
      if (row.size() != 4)
        fail(row_where, "expected 4 columns, found " + std::to_string(row.size()));
      for (size_t c = 0; c < 4; ++c)
        m(int(r), int(c)) = number(row[c], row_where + "[" + std::to_string(c) + "]");
    }
    if (rows.size() == 4 &&
        (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || std::abs(m(3, 3) - 1) > 1e-9))
      fail(where + "[3]", "expected the last row to be [0, 0, 0, 1]");
    const double det = m.rotation().determinant();
    if (std::abs(det) < 1e-12) fail(where, "rotation block is singular");
    // A mirror image of a camera: no real pose, and it flips every view.
    if (det < 0) fail(where, "rotation block is a reflection (determinant < 0), not a rotation");
    return m;
  }

 private:
  static std::string type_name(const json& value) { return value.type_name(); }
  fs::path path_;
};

core::Intrinsics read_intrinsics(const Reader& in, const json& frame, const json& root,
                                 const std::string& where) {
  auto required = [&](const std::string& key) {
    const json* v = in.lookup(frame, root, key);
    if (!v) in.fail(where, "missing key \"" + key + "\" (per frame or top level)");
    return in.number(*v, where + "." + key);
  };
  auto optional = [&](const std::string& key, double fallback) {
    const json* v = in.lookup(frame, root, key);
    return v ? in.number(*v, where + "." + key) : fallback;
  };

  core::Intrinsics k;
  double w = required("w"), h = required("h");
  // At most 2^20 pixels a side, as the camera JSON and COLMAP readers allow.
  if (w < 1 || h < 1 || w != std::floor(w) || h != std::floor(h) || w > 1 << 20 || h > 1 << 20)
    in.fail(where, "w and h must be positive whole numbers of pixels, at most 1048576");
  k.width = int(w);
  k.height = int(h);
  k.fx = required("fl_x");
  k.fy = optional("fl_y", k.fx);
  if (k.fx <= 0 || k.fy <= 0) in.fail(where, "focal lengths must be positive");
  // Missing principal point: the image centre, as nerfstudio assumes.
  k.cx = optional("cx", 0.5 * k.width);
  k.cy = optional("cy", 0.5 * k.height);
  k.k1 = optional("k1", 0);
  k.k2 = optional("k2", 0);
  k.k3 = optional("k3", 0);
  k.k4 = optional("k4", 0);
  k.p1 = optional("p1", 0);
  k.p2 = optional("p2", 0);
  // No camera_model: OPENCV, nerfstudio's default.
  std::string model = "OPENCV";
  if (const json* v = in.lookup(frame, root, "camera_model"))
    model = in.string(*v, where + ".camera_model");
  if (model == "OPENCV_FISHEYE") {
    k.fisheye = true;
    if (k.p1 != 0 || k.p2 != 0)
      in.fail(where, "OPENCV_FISHEYE has no tangential terms, but p1 or p2 is not 0");
  } else if (model == "PINHOLE" || model == "SIMPLE_PINHOLE") {
    if (k.has_distortion())
      in.fail(where, "camera_model " + model +
                         " has no lens distortion, but k1..k4, p1 or p2 is not 0 (use OPENCV)");
  } else if (model != "OPENCV") {
    in.fail(where + ".camera_model",
            "unsupported camera model \"" + model +
                "\" (expected OPENCV, OPENCV_FISHEYE, PINHOLE or SIMPLE_PINHOLE)");
  }
  return k;
}

// Two frames reading one file: a copy-paste slip that would weigh that view
// twice (or give it two poses).
void require_unique_files(const Reader& in, const std::vector<TransformsFrame>& frames) {
  std::map<std::string, size_t> first;
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::string& file = frames[i].hyperspectral_file_path.empty()
                                  ? frames[i].file_path
                                  : frames[i].hyperspectral_file_path;
    auto [it, inserted] = first.emplace(fs::path(file).lexically_normal().generic_string(), i);
    if (!inserted)
      in.fail("frames[" + std::to_string(i) + "]", "reads " + file + " like frames[" +
                                                       std::to_string(it->second) +
                                                       "]; each view must appear once");
  }
}

// A whole number from 0 (a rig camera index).
int index_value(const Reader& in, const json& value, const std::string& where) {
  const double v = in.number(value, where);
  if (v < 0 || v != std::floor(v) || v > 1e6) in.fail(where, "expected a camera index (0, 1, ...)");
  return int(v);
}

TransformsRig parse_rig(const Reader& in, const json& value) {
  if (!value.is_object()) in.fail("rig", "expected an object");
  TransformsRig rig;
  const json* reference = in.find(value, "reference_camera");
  if (!reference) in.fail("rig", "missing key \"reference_camera\"");
  rig.reference_camera = index_value(in, *reference, "rig.reference_camera");
  if (const json* v = in.find(value, "unit_m"))
    rig.unit_m = in.positive(*v, "rig.unit_m", "metres");
  const json* cameras = in.find(value, "cameras");
  if (!cameras) in.fail("rig", "missing key \"cameras\"");
  in.array(*cameras, "rig.cameras");
  for (size_t i = 0; i < cameras->size(); ++i) {
    const std::string where = "rig.cameras[" + std::to_string(i) + "]";
    const json& c = (*cameras)[i];
    if (!c.is_object()) in.fail(where, "expected an object");
    RigCameraInfo camera;
    const json* index = in.find(c, "index");
    if (!index) in.fail(where, "missing key \"index\"");
    camera.index = index_value(in, *index, where + ".index");
    if (rig.camera(camera.index))
      in.fail(where, "camera " + std::to_string(camera.index) + " is listed twice");
    if (const json* v = in.find(c, "band")) camera.band = in.string(*v, where + ".band");
    if (const json* v = in.find(c, "rig_relatives_deg")) {
      const json& angles = in.array(*v, where + ".rig_relatives_deg");
      if (angles.size() != 3) in.fail(where + ".rig_relatives_deg", "expected 3 angles in degrees");
      for (size_t a = 0; a < 3; ++a)
        camera.relatives_deg.push_back(
            in.number(angles[a], where + ".rig_relatives_deg[" + std::to_string(a) + "]"));
    }
    rig.cameras.push_back(camera);
  }
  if (!rig.camera(rig.reference_camera))
    in.fail("rig.reference_camera",
            "camera " + std::to_string(rig.reference_camera) + " is not one of rig.cameras");
  return rig;
}

TransformsFile parse(const Reader& in, const json& root) {
  if (!root.is_object()) in.fail("top level", "expected a JSON object");
  TransformsFile file;
  const json* frames = in.find(root, "frames");
  if (!frames) in.fail("top level", "missing key \"frames\"");
  in.array(*frames, "frames");
  if (frames->empty()) in.fail("frames", "expected at least one frame");

  for (size_t i = 0; i < frames->size(); ++i) {
    std::string where = "frames[" + std::to_string(i) + "]";
    const json& f = (*frames)[i];
    if (!f.is_object()) in.fail(where, "expected an object");
    TransformsFrame frame;
    if (const json* v = in.find(f, "file_path"))
      frame.file_path = in.string(*v, where + ".file_path");
    if (const json* v = in.find(f, "hyperspectral_file_path"))
      frame.hyperspectral_file_path = in.string(*v, where + ".hyperspectral_file_path");
    if (frame.file_path.empty() && frame.hyperspectral_file_path.empty())
      in.fail(where, "missing key \"file_path\" or \"hyperspectral_file_path\"");
    const json* m = in.find(f, "transform_matrix");
    if (!m) in.fail(where, "missing key \"transform_matrix\"");
    frame.camera_to_world_gl = in.matrix(*m, where + ".transform_matrix");
    frame.intrinsics = read_intrinsics(in, f, root, where);
    if (const json* v = in.find(f, "bands")) {
      const json& list = in.array(*v, where + ".bands");
      if (list.empty())
        in.fail(where + ".bands", "an empty list (leave the key out for every band)");
      for (size_t b = 0; b < list.size(); ++b) {
        const std::string at = where + ".bands[" + std::to_string(b) + "]";
        const double index = in.number(list[b], at);
        if (index < 0 || index != std::floor(index) || index > 1e6)
          in.fail(at, "expected a band index (0, 1, ... into \"wavelengths\")");
        if (std::find(frame.bands.begin(), frame.bands.end(), int(index)) != frame.bands.end())
          in.fail(at, "band " + std::to_string(int(index)) + " is listed twice");
        frame.bands.push_back(int(index));
      }
    }
    if (const json* v = in.find(f, "rig_camera"))
      frame.rig_camera = index_value(in, *v, where + ".rig_camera");
    file.frames.push_back(std::move(frame));
  }
  require_unique_files(in, file.frames);

  if (const json* v = in.find(root, "wavelengths")) {
    const json& list = in.array(*v, "wavelengths");
    if (list.empty())
      in.fail("wavelengths", "an empty list (leave the key out, or give one wavelength per band)");
    for (size_t i = 0; i < list.size(); ++i)
      file.wavelengths_nm.push_back(
          in.positive(list[i], "wavelengths[" + std::to_string(i) + "]", "a wavelength in nm"));
  }
  for (size_t i = 0; i < file.frames.size(); ++i)
    for (int b : file.frames[i].bands) {
      const std::string where = "frames[" + std::to_string(i) + "].bands";
      if (file.wavelengths_nm.empty())
        in.fail(where, "frames name their bands, but there is no top-level \"wavelengths\" list");
      if (size_t(b) >= file.wavelengths_nm.size())
        in.fail(where, "band " + std::to_string(b) + " is past the " +
                           std::to_string(file.wavelengths_nm.size()) + " wavelengths listed");
    }
  if (const json* v = in.find(root, "rig")) file.rig = parse_rig(in, *v);
  for (size_t i = 0; i < file.frames.size(); ++i) {
    const int camera = file.frames[i].rig_camera;
    if (camera >= 0 && !(file.rig && file.rig->camera(camera)))
      in.fail("frames[" + std::to_string(i) + "].rig_camera",
              "camera " + std::to_string(camera) + " is not one of the top-level rig's cameras");
  }
  if (const json* v = in.find(root, "ply_file_path"))
    file.ply_file_path = in.string(*v, "ply_file_path");
  if (const json* v = in.find(root, "applied_transform"))
    file.applied_transform = in.matrix(*v, "applied_transform");
  if (const json* v = in.find(root, "scale")) {
    double s = in.number(*v, "scale");
    if (s <= 0) in.fail("scale", "expected a positive divisor");
    file.scale = s;
  }
  if (const json* v = in.find(root, "train_filenames")) {
    file.train_files = in.strings(*v, "train_filenames");
    if (file.train_files.empty())
      in.fail("train_filenames",
              "an empty list: no view to train on (list the training views, "
              "or leave out both split lists for the default split)");
  }
  if (const json* v = in.find(root, "test_filenames"))
    file.test_files = in.strings(*v, "test_filenames");
  return file;
}

void put_intrinsics(json& out, const core::Intrinsics& k) {
  out["camera_model"] = k.fisheye ? "OPENCV_FISHEYE" : k.has_distortion() ? "OPENCV" : "PINHOLE";
  out["fl_x"] = k.fx;
  out["fl_y"] = k.fy;
  out["cx"] = k.cx;
  out["cy"] = k.cy;
  out["w"] = k.width;
  out["h"] = k.height;
  if (!k.has_distortion()) return;
  out["k1"] = k.k1;
  out["k2"] = k.k2;
  out["k3"] = k.k3;
  out["k4"] = k.k4;
  if (!k.fisheye) {
    out["p1"] = k.p1;
    out["p2"] = k.p2;
  }
}

json matrix_json(const core::Mat4& m, int rows) {
  json out = json::array();
  for (int r = 0; r < rows; ++r) out.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return out;
}

}  // namespace

TransformsFile read_transforms(const fs::path& path) {
  std::string text = read_file(path);
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {
    // The message carries the line and column, the useful part for a hand-edited
    // file. A number too large for a double is out_of_range, not parse_error.
    throw core::Error(path, "not valid JSON: " + core::message_of(e));
  }
  Reader in(path);
  try {
    return parse(in, root);
  } catch (const json::exception& e) {
    throw core::Error(path, "unexpected content: " + core::message_of(e));
  }
}

void write_transforms(const fs::path& path, const TransformsFile& file) {
  core::require(!file.frames.empty(), path, "refusing to write transforms.json without frames");
  bool shared = true;
  for (const auto& f : file.frames)
    shared = shared && f.intrinsics == file.frames.front().intrinsics;

  json root = json::object();
  if (shared) put_intrinsics(root, file.frames.front().intrinsics);
  json frames = json::array();
  for (const auto& f : file.frames) {
    json frame = json::object();
    if (!f.file_path.empty()) frame["file_path"] = f.file_path;
    if (!f.hyperspectral_file_path.empty())
      frame["hyperspectral_file_path"] = f.hyperspectral_file_path;
    frame["transform_matrix"] = matrix_json(f.camera_to_world_gl, 4);
    if (!shared) put_intrinsics(frame, f.intrinsics);
    if (!f.bands.empty()) frame["bands"] = f.bands;
    if (f.rig_camera >= 0) frame["rig_camera"] = f.rig_camera;
    frames.push_back(std::move(frame));
  }
  root["frames"] = std::move(frames);
  if (!file.wavelengths_nm.empty()) root["wavelengths"] = file.wavelengths_nm;
  if (!file.ply_file_path.empty()) root["ply_file_path"] = file.ply_file_path;
  // 3 x 4, as nerfstudio writes it.
  if (file.applied_transform) root["applied_transform"] = matrix_json(*file.applied_transform, 3);
  if (file.scale) root["scale"] = *file.scale;
  if (file.rig) {
    json cameras = json::array();
    for (const RigCameraInfo& c : file.rig->cameras) {
      json camera = {{"index", c.index}, {"band", c.band}};
      if (!c.relatives_deg.empty()) camera["rig_relatives_deg"] = c.relatives_deg;
      cameras.push_back(camera);
    }
    json rig = {{"reference_camera", file.rig->reference_camera}, {"cameras", cameras}};
    if (file.rig->unit_m > 0) rig["unit_m"] = file.rig->unit_m;
    root["rig"] = rig;
  }
  if (!file.train_files.empty()) root["train_filenames"] = file.train_files;
  if (!file.test_files.empty()) root["test_filenames"] = file.test_files;
  // dump() prints doubles with 17 significant digits, so poses round-trip exactly.
  write_file_atomically(path, root.dump(2) + "\n");
}

}  // namespace ddhgs::io
