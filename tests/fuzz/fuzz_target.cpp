#include "fuzz/fuzz_target.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "core/error.h"
#include "io/colmap/colmap.h"
#include "io/cube/cube.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/transforms/camera_json.h"
#include "io/transforms/transforms.h"

namespace ddhgs::fuzz {
namespace fs = std::filesystem;

namespace {

void put(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), std::streamsize(bytes.size()));
}

// The cube readers, and the header probe that `ddhgs info` uses.
void read_cube_both_ways(const fs::path& path) {
  try {
    io::probe_cube(path);
  } catch (const core::Error&) {
  }
  io::Cube cube = io::read_cube(path);
  io::cube_to_float(cube);
}

// A COLMAP model with one file from the input and the other two empty (a
// zero count in binary, nothing in text), then what load_scene does with it.
void read_colmap(const fs::path& dir, const std::string& file, const std::string& bytes,
                 bool binary) {
  const std::string empty = binary ? std::string(8, '\0') : std::string();
  const std::string ext = binary ? ".bin" : ".txt";
  for (const char* name : {"cameras", "images", "points3D"}) put(dir / (name + ext), empty);
  put(dir / file, bytes);
  io::ColmapModel model = binary ? io::read_colmap_binary(dir) : io::read_colmap_text(dir);
  for (const auto& image : model.images) {
    try {
      io::colmap_camera(model, image);
    } catch (const core::Error&) {
    }
  }
  io::colmap_points(model);
}

void run_reader(ReaderKind kind, const std::string& bytes, const fs::path& dir) {
  switch (kind) {
    case ReaderKind::Npy:
      put(dir / "cube.npy", bytes);
      return read_cube_both_ways(dir / "cube.npy");
    case ReaderKind::TorchPt:
      put(dir / "cube.pt", bytes);
      return read_cube_both_ways(dir / "cube.pt");
    case ReaderKind::Envi: {
      const size_t header = bytes.size() < 2 ? 0 : (uint8_t(bytes[0]) | uint8_t(bytes[1]) << 8);
      const std::string rest = bytes.size() < 2 ? std::string() : bytes.substr(2);
      put(dir / "cube.hdr", rest.substr(0, std::min(header, rest.size())));
      put(dir / "cube.img", rest.substr(std::min(header, rest.size())));
      return read_cube_both_ways(dir / "cube.hdr");
    }
    case ReaderKind::Tiff:
      put(dir / "cube.tif", bytes);
      return read_cube_both_ways(dir / "cube.tif");
    case ReaderKind::Png:
      put(dir / "image.png", bytes);
      return read_cube_both_ways(dir / "image.png");
    case ReaderKind::Jpeg:
      put(dir / "image.jpg", bytes);
      return read_cube_both_ways(dir / "image.jpg");
    case ReaderKind::GaussianPly:
      put(dir / "gaussians.ply", bytes);
      io::read_gaussian_ply(dir / "gaussians.ply");
      return;
    case ReaderKind::PointPly:
      put(dir / "points.ply", bytes);
      io::read_point_ply(dir / "points.ply");
      return;
    case ReaderKind::ColmapCamerasBin:
      return read_colmap(dir, "cameras.bin", bytes, true);
    case ReaderKind::ColmapImagesBin:
      return read_colmap(dir, "images.bin", bytes, true);
    case ReaderKind::ColmapPointsBin:
      return read_colmap(dir, "points3D.bin", bytes, true);
    case ReaderKind::ColmapCamerasTxt:
      return read_colmap(dir, "cameras.txt", bytes, false);
    case ReaderKind::ColmapImagesTxt:
      return read_colmap(dir, "images.txt", bytes, false);
    case ReaderKind::ColmapPointsTxt:
      return read_colmap(dir, "points3D.txt", bytes, false);
    case ReaderKind::Transforms:
      put(dir / "transforms.json", bytes);
      io::read_transforms(dir / "transforms.json");
      return;
    case ReaderKind::CameraJson:
      put(dir / "camera.json", bytes);
      io::read_camera_json(dir / "camera.json");
      return;
    case ReaderKind::Count:
      return;
  }
}

}  // namespace

std::string encode(ReaderKind kind, const std::string& file, const std::string& envi_data) {
  std::string input(1, char(kind));
  if (kind == ReaderKind::Envi) {
    input += char(file.size() & 0xff);
    input += char((file.size() >> 8) & 0xff);
    return input + file + envi_data;
  }
  return input + file;
}

void run_input(const uint8_t* data, size_t size, const fs::path& scratch) {
  if (size == 0) return;
  const auto kind = ReaderKind(data[0] % uint8_t(ReaderKind::Count));
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    run_reader(kind, bytes, scratch);
  } catch (const core::Error&) {
    // A refusal naming the file: what a reader must do with bad input.
  } catch (const std::exception& e) {
    std::fprintf(stderr, "reader %d threw a %s instead of core::Error: %s\n", int(kind),
                 typeid(e).name(), e.what());
    std::abort();
  }
}

}  // namespace ddhgs::fuzz
