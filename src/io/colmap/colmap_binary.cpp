// COLMAP's binary model format: little-endian, counts as uint64, image names
// NUL-terminated (src/colmap/scene/reconstruction_io.cc describes the layout).
#include <cmath>
#include <cstring>
#include <type_traits>

#include "core/error.h"
#include "io/colmap/colmap.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

static_assert(sizeof(double) == 8, "COLMAP binaries hold IEEE doubles");

// Bounds-checked reads: a truncated file ends in an error naming the offset,
// never a read past the buffer or a giant allocation from a corrupt count.
class Cursor {
 public:
  Cursor(fs::path path, std::string bytes) : path_(std::move(path)), bytes_(std::move(bytes)) {}

  template <typename T>
  T read(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T), what);
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }

  std::string read_name() {
    size_t end = bytes_.find('\0', pos_);
    if (end == std::string::npos) fail("image name is not terminated");
    std::string name = bytes_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return name;
  }

  // A double that must be a finite number (NaN poses or points poison training).
  double read_finite(const char* what) {
    double value = read<double>(what);
    if (!std::isfinite(value)) fail(std::string(what) + " is not a finite number");
    return value;
  }

  // Image sizes: COLMAP stores uint64, ddhgs works with int pixel counts.
  int64_t read_pixels(const char* what) {
    uint64_t value = read<uint64_t>(what);
    if (value < 1 || value > uint64_t(kColmapMaxPixels))
      fail(std::string(what) + " " + std::to_string(value) + " is not between 1 and " +
           std::to_string(kColmapMaxPixels));
    return int64_t(value);
  }

  // A count of items each at least min_bytes long must fit in what is left.
  uint64_t read_count(const char* what, size_t min_bytes) {
    uint64_t n = read<uint64_t>(what);
    if (n > (bytes_.size() - pos_) / min_bytes)
      fail(std::string(what) + " " + std::to_string(n) + " exceeds the file size (truncated?)");
    return n;
  }

  void expect_end() const {
    if (pos_ != bytes_.size())
      fail(std::to_string(bytes_.size() - pos_) + " unexpected bytes after the last record");
  }

  [[noreturn]] void fail(const std::string& problem) const {
    throw core::Error(path_, problem + " (at byte " + std::to_string(pos_) + ")");
  }
  const fs::path& path() const { return path_; }

 private:
  void need(size_t n, const char* what) const {
    if (bytes_.size() - pos_ < n) fail(std::string("truncated: expected ") + what + ", file ends");
  }
  fs::path path_;
  std::string bytes_;
  size_t pos_ = 0;
};

class Writer {
 public:
  template <typename T>
  void put(T value) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  std::string bytes;
};

Cursor open(const fs::path& path) {
  std::string bytes = read_file(path);
  return Cursor(path, std::move(bytes));
}

void read_cameras(const fs::path& path, ColmapModel& model) {
  Cursor in = open(path);
  uint64_t n = in.read_count("camera count", 24);
  for (uint64_t i = 0; i < n; ++i) {
    ColmapCamera camera;
    camera.camera_id = in.read<int32_t>("camera id");
    camera.model = colmap_model_name(in.read<int32_t>("camera model"), path.string());
    camera.width = in.read_pixels("camera width");
    camera.height = in.read_pixels("camera height");
    size_t count = colmap_param_count(camera.model, path.string());
    for (size_t j = 0; j < count; ++j) camera.params.push_back(in.read_finite("camera parameter"));
    if (!model.cameras.emplace(camera.camera_id, camera).second)
      in.fail("camera id " + std::to_string(camera.camera_id) + " appears twice");
  }
  in.expect_end();
}

void read_images(const fs::path& path, ColmapModel& model) {
  Cursor in = open(path);
  uint64_t n = in.read_count("image count", 64);
  for (uint64_t i = 0; i < n; ++i) {
    ColmapImage image;
    image.image_id = in.read<int32_t>("image id");
    for (double& q : image.qvec) q = in.read_finite("quaternion");
    image.tvec.x = in.read_finite("translation");
    image.tvec.y = in.read_finite("translation");
    image.tvec.z = in.read_finite("translation");
    image.camera_id = in.read<int32_t>("camera id");
    image.name = in.read_name();
    uint64_t points = in.read_count("keypoint count", 24);
    image.xys.reserve(points);
    image.point3d_ids.reserve(points);
    for (uint64_t j = 0; j < points; ++j) {
      double x = in.read<double>("keypoint x");
      double y = in.read<double>("keypoint y");
      image.xys.push_back({x, y});
      image.point3d_ids.push_back(in.read<int64_t>("keypoint point3D id"));
    }
    model.images.push_back(std::move(image));
  }
  in.expect_end();
}

void read_points(const fs::path& path, ColmapModel& model) {
  Cursor in = open(path);
  uint64_t n = in.read_count("point count", 43);
  model.points.reserve(n);
  for (uint64_t i = 0; i < n; ++i) {
    ColmapPoint point;
    point.point3d_id = int64_t(in.read<uint64_t>("point id"));
    point.xyz.x = in.read_finite("point x");
    point.xyz.y = in.read_finite("point y");
    point.xyz.z = in.read_finite("point z");
    for (uint8_t& c : point.rgb) c = in.read<uint8_t>("point colour");
    point.error = in.read<double>("point error");
    uint64_t track = in.read_count("track length", 8);
    point.track.reserve(track);
    for (uint64_t j = 0; j < track; ++j) {
      int image_id = in.read<int32_t>("track image id");
      point.track.emplace_back(image_id, in.read<int32_t>("track keypoint index"));
    }
    model.points.push_back(std::move(point));
  }
  in.expect_end();
}

}  // namespace

ColmapModel read_colmap_binary(const fs::path& dir) {
  ColmapModel model;
  read_cameras(dir / "cameras.bin", model);
  read_images(dir / "images.bin", model);
  if (fs::exists(dir / "points3D.bin")) read_points(dir / "points3D.bin", model);
  model.cameras_file = dir / "cameras.bin";
  model.images_file = dir / "images.bin";
  return model;
}

void write_colmap_binary(const fs::path& dir, const ColmapModel& model) {
  check_colmap_model(model);
  fs::create_directories(dir);
  Writer cameras;
  cameras.put<uint64_t>(model.cameras.size());
  for (const auto& [id, camera] : model.cameras) {
    cameras.put<int32_t>(id);
    cameras.put<int32_t>(colmap_model_id(camera.model, "COLMAP camera " + std::to_string(id)));
    cameras.put<uint64_t>(uint64_t(camera.width));
    cameras.put<uint64_t>(uint64_t(camera.height));
    for (double p : camera.params) cameras.put(p);
  }

  Writer images;
  images.put<uint64_t>(model.images.size());
  for (const auto& image : model.images) {
    images.put<int32_t>(image.image_id);
    for (double q : image.qvec) images.put(q);
    images.put(image.tvec.x);
    images.put(image.tvec.y);
    images.put(image.tvec.z);
    images.put<int32_t>(image.camera_id);
    images.bytes.append(image.name);
    images.bytes.push_back('\0');
    images.put<uint64_t>(image.xys.size());
    for (size_t j = 0; j < image.xys.size(); ++j) {
      images.put(image.xys[j][0]);
      images.put(image.xys[j][1]);
      images.put<int64_t>(image.point3d_ids[j]);
    }
  }

  Writer points;
  points.put<uint64_t>(model.points.size());
  for (const auto& point : model.points) {
    points.put<uint64_t>(uint64_t(point.point3d_id));
    points.put(point.xyz.x);
    points.put(point.xyz.y);
    points.put(point.xyz.z);
    for (uint8_t c : point.rgb) points.put(c);
    points.put(point.error);
    points.put<uint64_t>(point.track.size());
    for (const auto& [image_id, index] : point.track) {
      points.put<int32_t>(image_id);
      points.put<int32_t>(index);
    }
  }

  write_file_atomically(dir / "cameras.bin", cameras.bytes);
  write_file_atomically(dir / "images.bin", images.bytes);
  write_file_atomically(dir / "points3D.bin", points.bytes);
}

}  // namespace ddhgs::io
