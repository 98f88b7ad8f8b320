#include "io/colmap/colmap.h"

#include <map>

#include <cmath>

#include "core/error.h"
#include "io/ply/ply.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

struct ModelSpec {
  int id;
  const char* name;
  size_t params;
  bool supported;
};

// COLMAP's model table (src/colmap/sensor/models.h). FOV and thin-prism
// models cannot be expressed by core::Intrinsics; FULL_OPENCV only without
// its rational terms (k4 k5 k6 = 0, checked by colmap_intrinsics).
constexpr ModelSpec kModels[] = {
    {0, "SIMPLE_PINHOLE", 3, true},
    {1, "PINHOLE", 4, true},
    {2, "SIMPLE_RADIAL", 4, true},
    {3, "RADIAL", 5, true},
    {4, "OPENCV", 8, true},
    {5, "OPENCV_FISHEYE", 8, true},
    {6, "FULL_OPENCV", 12, true},
    {7, "FOV", 5, false},
    {8, "SIMPLE_RADIAL_FISHEYE", 4, true},
    {9, "RADIAL_FISHEYE", 5, true},
    {10, "THIN_PRISM_FISHEYE", 12, false},
};

const char* kSupportedList =
    "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE, "
    "SIMPLE_RADIAL_FISHEYE or RADIAL_FISHEYE";

const ModelSpec& supported_spec(const ModelSpec* spec, const std::string& shown,
                                const std::string& origin) {
  if (!spec || !spec->supported)
    throw core::Error(origin + ": unsupported camera model " + shown + " (expected " +
                      kSupportedList + ")");
  return *spec;
}

const ModelSpec* spec_by_name(const std::string& model) {
  for (const auto& s : kModels)
    if (model == s.name) return &s;
  return nullptr;
}

}  // namespace

size_t colmap_param_count(const std::string& model, const std::string& origin) {
  return supported_spec(spec_by_name(model), model, origin).params;
}

std::string colmap_model_name(int model_id, const std::string& origin) {
  const ModelSpec* spec = nullptr;
  for (const auto& s : kModels)
    if (s.id == model_id) spec = &s;
  std::string shown = spec ? std::string(spec->name) : "id " + std::to_string(model_id);
  return supported_spec(spec, shown, origin).name;
}

int colmap_model_id(const std::string& model, const std::string& origin) {
  return supported_spec(spec_by_name(model), model, origin).id;
}

std::optional<fs::path> find_colmap_model(const fs::path& root) {
  for (const char* sub : {"sparse/0", "colmap/sparse/0", "sparse"}) {
    fs::path dir = root / sub;
    if (fs::exists(dir / "cameras.bin") || fs::exists(dir / "cameras.txt")) return dir;
  }
  return std::nullopt;
}

namespace {

// One pose per image: a name or an id given twice would give one view two
// poses and another none.
void require_unique_images(const ColmapModel& model) {
  std::map<int, const ColmapImage*> by_id;
  std::map<std::string, const ColmapImage*> by_name;
  for (const auto& image : model.images) {
    if (auto [it, fresh] = by_id.emplace(image.image_id, &image); !fresh)
      throw core::Error(model.images_file, "image id " + std::to_string(image.image_id) +
                                               " is given twice (" + it->second->name + " and " +
                                               image.name + ")");
    if (auto [it, fresh] = by_name.emplace(image.name, &image); !fresh)
      throw core::Error(model.images_file, "image " + image.name + " is given twice (ids " +
                                               std::to_string(it->second->image_id) + " and " +
                                               std::to_string(image.image_id) + ")");
  }
}

}  // namespace

ColmapModel read_colmap(const fs::path& dir) {
  bool binary = true;
  for (const char* name : {"cameras.bin", "images.bin"}) binary = binary && fs::exists(dir / name);
  if (!binary)
    core::require(fs::exists(dir / "cameras.txt") && fs::exists(dir / "images.txt"), dir,
                  "expected a COLMAP model: cameras.bin and images.bin, or cameras.txt and "
                  "images.txt");
  ColmapModel model = binary ? read_colmap_binary(dir) : read_colmap_text(dir);
  require_unique_images(model);
  return model;
}

void check_colmap_model(const ColmapModel& model) {
  for (const auto& [id, camera] : model.cameras) {
    std::string origin = "COLMAP camera " + std::to_string(id);
    core::require(camera.params.size() == colmap_param_count(camera.model, origin),
                  origin + ": parameter count does not match model " + camera.model);
  }
  for (const auto& image : model.images)
    core::require(image.xys.size() == image.point3d_ids.size(),
                  "COLMAP image " + image.name + ": keypoints and point ids differ in count");
}

core::Intrinsics colmap_intrinsics(const ColmapCamera& camera) {
  std::string origin = "COLMAP camera " + std::to_string(camera.camera_id);
  size_t expected = colmap_param_count(camera.model, origin);
  if (camera.params.size() != expected)
    throw core::Error(origin + ": model " + camera.model + " needs " + std::to_string(expected) +
                      " parameters, found " + std::to_string(camera.params.size()));
  const std::string& m = camera.model;
  const auto& p = camera.params;
  core::Intrinsics k;
  k.width = int(camera.width);
  k.height = int(camera.height);
  // One focal length (f, cx, cy, ...) or two (fx, fy, cx, cy, ...).
  const bool one_focal = m == "SIMPLE_PINHOLE" || m == "SIMPLE_RADIAL" || m == "RADIAL" ||
                         m == "SIMPLE_RADIAL_FISHEYE" || m == "RADIAL_FISHEYE";
  const size_t first = one_focal ? 3 : 4;  // index of the first distortion parameter
  k.fx = p[0];
  k.fy = one_focal ? p[0] : p[1];
  k.cx = p[first - 2];
  k.cy = p[first - 1];
  k.fisheye = m.find("FISHEYE") != std::string::npos;
  auto param = [&](size_t i) { return first + i < p.size() ? p[first + i] : 0.0; };
  if (m == "OPENCV" || m == "FULL_OPENCV") {
    k.k1 = param(0);
    k.k2 = param(1);
    k.p1 = param(2);
    k.p2 = param(3);
    k.k3 = param(4);
    if (param(5) != 0 || param(6) != 0 || param(7) != 0)
      throw core::Error(origin +
                        ": FULL_OPENCV with rational terms (k4 k5 k6 not 0) is not "
                        "supported");
  } else if (m != "SIMPLE_PINHOLE" && m != "PINHOLE") {
    // SIMPLE_RADIAL, RADIAL and the fisheye models list k1, k2, ... in order.
    k.k1 = param(0);
    k.k2 = param(1);
    k.k3 = param(2);
    k.k4 = param(3);
  }
  if (!(k.fx > 0 && k.fy > 0) || k.width < 1 || k.height < 1)
    throw core::Error(origin + ": expected positive focal lengths and image size");
  return k;
}

ColmapCamera colmap_camera_of(const core::Intrinsics& k) {
  ColmapCamera camera;
  camera.width = k.width;
  camera.height = k.height;
  camera.params = {k.fx, k.fy, k.cx, k.cy};
  if (k.fisheye) {
    camera.model = "OPENCV_FISHEYE";
    camera.params.insert(camera.params.end(), {k.k1, k.k2, k.k3, k.k4});
  } else if (k.k4 != 0) {
    throw core::Error("camera with a radial r^8 term (k4 " + std::to_string(k.k4) +
                      "): no COLMAP model holds it");
  } else if (k.k3 != 0) {
    camera.model = "FULL_OPENCV";
    camera.params.insert(camera.params.end(), {k.k1, k.k2, k.p1, k.p2, k.k3, 0, 0, 0});
  } else if (k.has_distortion()) {
    camera.model = "OPENCV";
    camera.params.insert(camera.params.end(), {k.k1, k.k2, k.p1, k.p2});
  } else {
    camera.model = "PINHOLE";
  }
  return camera;
}

core::Camera colmap_camera(const ColmapModel& model, const ColmapImage& image) {
  auto in = [](const fs::path& file) {
    return file.empty() ? std::string() : file.string() + ": ";
  };
  auto it = model.cameras.find(image.camera_id);
  if (it == model.cameras.end())
    throw core::Error(in(model.images_file) + "COLMAP image " + image.name + ": camera " +
                      std::to_string(image.camera_id) + " is not in cameras");
  const auto& q = image.qvec;
  double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(norm > 1e-12) || !std::isfinite(norm))
    throw core::Error(in(model.images_file) + "COLMAP image " + image.name +
                      ": quaternion is zero or not finite");
  core::Camera camera;
  try {
    camera.intrinsics = colmap_intrinsics(it->second);
  } catch (const core::Error& e) {
    throw core::Error(in(model.cameras_file) + e.what());
  }
  camera.world_to_camera =
      core::Mat4::from(core::quat_to_rotation(q[0], q[1], q[2], q[3]), image.tvec);
  return camera;
}

PointCloud colmap_points(const ColmapModel& model) {
  PointCloud cloud;
  const int64_t n = int64_t(model.points.size());
  if (n == 0) return cloud;
  cloud.xyz = torch::empty({n, 3}, torch::kFloat32);
  cloud.rgb = torch::empty({n, 3}, torch::kUInt8);
  auto xyz = cloud.xyz.accessor<float, 2>();
  auto rgb = cloud.rgb.accessor<uint8_t, 2>();
  for (int64_t i = 0; i < n; ++i) {
    const auto& p = model.points[size_t(i)];
    xyz[i][0] = float(p.xyz.x);
    xyz[i][1] = float(p.xyz.y);
    xyz[i][2] = float(p.xyz.z);
    for (int c = 0; c < 3; ++c) rgb[i][c] = p.rgb[size_t(c)];
  }
  return cloud;
}

}  // namespace ddhgs::io
