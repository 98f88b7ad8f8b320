// COLMAP sparse models: cameras, images and points3D, binary (.bin) and text
// (.txt). COLMAP stores world-to-camera poses in OpenCV axes already, so a
// core::Camera needs no axis change: R from the quaternion, t as given.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"

namespace ddhgs::io {

// Larger than any camera's width or height in pixels; readers refuse more.
constexpr int64_t kColmapMaxPixels = 1 << 20;

struct ColmapCamera {
  int camera_id = 0;
  // COLMAP model name: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV,
  // FULL_OPENCV (without rational terms), OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE
  // or RADIAL_FISHEYE.
  std::string model;
  int64_t width = 0, height = 0;  // pixels
  std::vector<double> params;     // in COLMAP's order for the model
};

struct ColmapImage {
  int image_id = 0;
  std::array<double, 4> qvec{1, 0, 0, 0};  // world-to-camera rotation (w, x, y, z)
  core::Vec3 tvec;                         // world-to-camera translation
  int camera_id = 0;
  std::string name;                        // path relative to the image folder
  std::vector<std::array<double, 2>> xys;  // 2D keypoints, pixels
  std::vector<int64_t> point3d_ids;        // per keypoint; -1 when untriangulated
};

struct ColmapPoint {
  int64_t point3d_id = 0;
  core::Vec3 xyz;
  std::array<uint8_t, 3> rgb{0, 0, 0};
  double error = 0;                        // mean reprojection error, pixels
  std::vector<std::pair<int, int>> track;  // (image_id, keypoint index)
};

struct ColmapModel {
  std::map<int, ColmapCamera> cameras;  // by camera_id
  std::vector<ColmapImage> images;      // in file order
  std::vector<ColmapPoint> points;
  // The files the model was read from, named in errors; empty when it was
  // built in memory.
  std::filesystem::path cameras_file, images_file;
};

// The model folder below root: sparse/0, colmap/sparse/0 or sparse, the first
// that holds a cameras.bin or cameras.txt. Empty when there is none.
std::optional<std::filesystem::path> find_colmap_model(const std::filesystem::path& root);

// Reads dir/{cameras,images,points3D}.bin, or the .txt set when the .bin set
// is incomplete. points3D may be absent (no points). Throws core::Error naming
// the file on truncated or malformed input and unknown camera models.
ColmapModel read_colmap(const std::filesystem::path& dir);
ColmapModel read_colmap_binary(const std::filesystem::path& dir);
ColmapModel read_colmap_text(const std::filesystem::path& dir);

// Atomic writers (each file written to a temporary name, then renamed).
// Both first call check_colmap_model.
void write_colmap_binary(const std::filesystem::path& dir, const ColmapModel& model);
void write_colmap_text(const std::filesystem::path& dir, const ColmapModel& model);

// Number of parameters of a COLMAP camera model; core::Error naming origin
// when the model is not supported (FOV and thin-prism models).
size_t colmap_param_count(const std::string& model, const std::string& origin);
// COLMAP's numeric model id <-> name, for the binary format.
std::string colmap_model_name(int model_id, const std::string& origin);
int colmap_model_id(const std::string& model, const std::string& origin);

// core::Error unless every camera's parameter count fits its model and every
// image has one point3D id per keypoint: what both formats rely on.
void check_colmap_model(const ColmapModel& model);

// The camera's intrinsics and lens model (core::Error for FULL_OPENCV with
// rational terms), and back: the simplest COLMAP model that holds them
// (PINHOLE, OPENCV, FULL_OPENCV, OPENCV_FISHEYE; camera_id left 0).
core::Intrinsics colmap_intrinsics(const ColmapCamera& camera);
ColmapCamera colmap_camera_of(const core::Intrinsics& intrinsics);
// World-to-camera (OpenCV) of image; core::Error when its camera is missing.
core::Camera colmap_camera(const ColmapModel& model, const ColmapImage& image);

struct PointCloud;  // io/ply.h
// The model's 3D points as xyz [P, 3] float32 and rgb [P, 3] uint8 (no
// spectra); an empty cloud when the model has no points.
PointCloud colmap_points(const ColmapModel& model);

}  // namespace ddhgs::io
