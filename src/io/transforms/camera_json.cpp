#include "io/transforms/camera_json.h"

#include <nlohmann/json.hpp>

#include <cmath>

#include "core/error.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Rotation blocks further than this from orthonormal are a scaled or sheared
// matrix, which the renderer would silently misinterpret.
constexpr double kRigidTolerance = 1e-4;

double finite_number(const fs::path& path, const json& value, const std::string& key) {
  if (!value.is_number())
    throw core::Error(path,
                      "\"" + key + "\" must be a number, got " + std::string(value.type_name()));
  double number = value.get<double>();
  if (!std::isfinite(number)) throw core::Error(path, "\"" + key + "\" must be finite");
  return number;
}

const json& member(const fs::path& path, const json& object, const std::string& key) {
  auto it = object.find(key);
  if (it == object.end()) throw core::Error(path, "missing key \"" + key + "\"");
  return *it;
}

int positive_size(const fs::path& path, const json& object, const std::string& key) {
  double value = finite_number(path, member(path, object, key), key);
  if (value < 1 || value != std::floor(value) || value > 1 << 20)
    throw core::Error(path, "\"" + key + "\" must be a positive whole number of pixels");
  return int(value);
}

core::Mat4 read_matrix(const fs::path& path, const json& rows) {
  const std::string key = "world_to_camera";
  if (!rows.is_array() || (rows.size() != 4 && rows.size() != 3))
    throw core::Error(path, "\"" + key + "\" must be a 4 x 4 (or 3 x 4) array of rows");
  core::Mat4 m;
  for (size_t r = 0; r < rows.size(); ++r) {
    if (!rows[r].is_array() || rows[r].size() != 4)
      throw core::Error(path, "\"" + key + "\" row " + std::to_string(r) + " must have 4 numbers");
    for (size_t c = 0; c < 4; ++c)
      m(int(r), int(c)) = finite_number(
          path, rows[r][c], key + "[" + std::to_string(r) + "][" + std::to_string(c) + "]");
  }
  if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1)
    throw core::Error(path, "\"" + key + "\" last row must be [0, 0, 0, 1]");
  const core::Mat3 R = m.rotation();
  const double det = R.determinant();
  if (std::abs(det) < 1e-12) throw core::Error(path, "\"" + key + "\" is not invertible");
  const core::Mat3 RRt = R * R.transposed();
  double deviation = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) deviation = std::max(deviation, std::abs(RRt(i, j) - (i == j)));
  if (deviation > kRigidTolerance || det < 0)
    throw core::Error(path, "\"" + key +
                                "\" must be a rigid transform (orthonormal rotation block with "
                                "determinant +1); deviation " +
                                std::to_string(deviation) + ", determinant " + std::to_string(det));
  return m;
}

}  // namespace

core::Camera read_camera_json(const fs::path& path) {
  const std::string text = read_file(path);
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {
    throw core::Error(path, "not valid JSON: " + core::message_of(e));
  }
  if (!root.is_object()) throw core::Error(path, "expected a JSON object describing one camera");
  core::Camera camera;
  auto& in = camera.intrinsics;
  in.width = positive_size(path, root, "width");
  in.height = positive_size(path, root, "height");
  in.fx = finite_number(path, member(path, root, "fx"), "fx");
  in.fy = finite_number(path, member(path, root, "fy"), "fy");
  in.cx = finite_number(path, member(path, root, "cx"), "cx");
  in.cy = finite_number(path, member(path, root, "cy"), "cy");
  if (in.fx <= 0 || in.fy <= 0) throw core::Error(path, "\"fx\" and \"fy\" must be positive");
  camera.world_to_camera = read_matrix(path, member(path, root, "world_to_camera"));
  if (const std::string problem = core::camera_problem(camera); !problem.empty())
    throw core::Error(path, problem);
  return camera;
}

void write_camera_json(const fs::path& path, const core::Camera& camera) {
  const auto& in = camera.intrinsics;
  json rows = json::array();
  for (int r = 0; r < 4; ++r) {
    json row = json::array();
    for (int c = 0; c < 4; ++c) row.push_back(camera.world_to_camera(r, c));
    rows.push_back(row);
  }
  json root = {
      {"width", in.width}, {"height", in.height},    {"fx", in.fx}, {"fy", in.fy}, {"cx", in.cx},
      {"cy", in.cy},       {"world_to_camera", rows}};
  write_file_atomically(path, root.dump(2) + "\n");
}

}  // namespace ddhgs::io
