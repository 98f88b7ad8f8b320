// Writes the fuzzer's seed corpus: small valid files of every format the
// readers take, written by ddhgs's own writers, one input per file
// (tests/fuzz/fuzz_target.h).
//   fuzz_seeds DIR
#include <torch/serialize.h>
#include <cstdio>
#include <fstream>

#include <stb_image_write.h>
#include <torch/csrc/jit/serialization/pickle.h>
#include "core/camera.h"
#include "fuzz/fuzz_target.h"
#include "io/colmap/colmap.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/transforms/camera_json.h"
#include "io/transforms/transforms.h"

namespace {

namespace fs = std::filesystem;
using ddhgs::fuzz::ReaderKind;
namespace io = ddhgs::io;

fs::path g_out;
int g_count = 0;

void seed(ReaderKind kind, const std::string& file, const std::string& envi_data = {}) {
  const std::string input = ddhgs::fuzz::encode(kind, file, envi_data);
  std::ofstream(g_out / ("seed_" + std::to_string(g_count++)), std::ios::binary)
      .write(input.data(), std::streamsize(input.size()));
}

// Writes with a ddhgs writer into scratch, then seeds the file's bytes.
template <typename Write>
std::string written(const fs::path& path, Write&& write) {
  write(path);
  return io::read_file(path);
}

torch::Tensor small_cube(torch::ScalarType dtype) {
  return (torch::rand({3, 4, 2}) * (dtype == torch::kFloat ? 1.0 : 200.0)).to(dtype);
}

void cube_seeds(const fs::path& dir) {
  for (auto dtype : {torch::kUInt8, torch::kInt16, torch::kFloat}) {
    seed(ReaderKind::Npy,
         written(dir / "c.npy", [&](const fs::path& p) { io::write_npy(p, small_cube(dtype)); }));
    const std::vector<char> pt = torch::pickle_save(small_cube(dtype));
    seed(ReaderKind::TorchPt, std::string(pt.begin(), pt.end()));
    for (auto layout :
         {io::TiffLayout::Contiguous, io::TiffLayout::Separate, io::TiffLayout::Pages})
      seed(ReaderKind::Tiff, written(dir / "c.tif", [&](const fs::path& p) {
             io::write_tiff(p, small_cube(dtype), layout);
           }));
  }
  for (auto interleave :
       {io::EnviInterleave::BSQ, io::EnviInterleave::BIL, io::EnviInterleave::BIP}) {
    io::write_envi(dir / "c.hdr", small_cube(torch::kInt16), {450, 550}, interleave);
    seed(ReaderKind::Envi, io::read_file(dir / "c.hdr"), io::read_file(dir / "c.img"));
  }
  const std::string png = written(dir / "i.png", [&](const fs::path& p) {
    io::write_png(p, small_cube(torch::kUInt8).narrow(2, 0, 1).expand({-1, -1, 3}).contiguous());
  });
  seed(ReaderKind::Png, png);
  // stb's JPEG writer is linked into the io layer with its PNG writer.
  const torch::Tensor rgb =
      small_cube(torch::kUInt8).narrow(2, 0, 1).expand({-1, -1, 3}).contiguous();
  std::string jpeg;
  stbi_write_jpg_to_func(
      [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
      },
      &jpeg, int(rgb.size(1)), int(rgb.size(0)), 3, rgb.data_ptr(), 90);
  seed(ReaderKind::Jpeg, jpeg);
}

void ply_seeds(const fs::path& dir) {
  io::GaussianPly g;
  const int64_t G = 2, N = 2;
  g.means = torch::rand({G, 3});
  g.log_scales = torch::rand({G, 3});
  g.quats = torch::rand({G, 4});
  g.logit_opacities = torch::rand({G, 1});
  g.sh_dc = torch::rand({G, N});
  g.sh_rest = torch::rand({G, N, 3});
  g.wavelengths_nm = {500, 600};
  seed(ReaderKind::GaussianPly,
       written(dir / "g.ply", [&](const fs::path& p) { io::write_gaussian_ply(p, g); }));
  io::PointCloud points;
  points.xyz = torch::rand({3, 3});
  points.rgb = torch::randint(0, 255, {3, 3}).to(torch::kUInt8);
  points.spectra = torch::rand({3, 2});
  seed(ReaderKind::PointPly,
       written(dir / "p.ply", [&](const fs::path& p) { io::write_point_ply(p, points); }));
  seed(ReaderKind::PointPly,
       "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
       "property float y\nproperty float z\nend_header\n0 0 0\n1 2 3\n");
}

void colmap_seeds(const fs::path& dir) {
  io::ColmapModel model;
  model.cameras[1] = {1, "OPENCV", 8, 6, {5, 5, 4, 3, 0.01, 0.0, 0.0, 0.0}};
  io::ColmapImage image;
  image.image_id = 1;
  image.camera_id = 1;
  image.name = "a.png";
  image.xys = {{1, 2}};
  image.point3d_ids = {7};
  model.images.push_back(image);
  io::ColmapPoint point;
  point.point3d_id = 7;
  point.track = {{1, 0}};
  model.points.push_back(point);
  io::write_colmap_binary(dir / "bin", model);
  io::write_colmap_text(dir / "txt", model);
  seed(ReaderKind::ColmapCamerasBin, io::read_file(dir / "bin" / "cameras.bin"));
  seed(ReaderKind::ColmapImagesBin, io::read_file(dir / "bin" / "images.bin"));
  seed(ReaderKind::ColmapPointsBin, io::read_file(dir / "bin" / "points3D.bin"));
  seed(ReaderKind::ColmapCamerasTxt, io::read_file(dir / "txt" / "cameras.txt"));
  seed(ReaderKind::ColmapImagesTxt, io::read_file(dir / "txt" / "images.txt"));
  seed(ReaderKind::ColmapPointsTxt, io::read_file(dir / "txt" / "points3D.txt"));
}

void json_seeds(const fs::path& dir) {
  ddhgs::core::Camera camera;
  camera.intrinsics.width = 8;
  camera.intrinsics.height = 6;
  camera.intrinsics.fx = camera.intrinsics.fy = 5;
  camera.intrinsics.cx = 4;
  camera.intrinsics.cy = 3;
  seed(ReaderKind::CameraJson,
       written(dir / "cam.json", [&](const fs::path& p) { io::write_camera_json(p, camera); }));
  io::TransformsFile transforms;
  io::TransformsFrame frame;
  frame.file_path = "images/a.png";
  frame.hyperspectral_file_path = "hyperspectral/a.npy";
  frame.intrinsics = camera.intrinsics;
  transforms.frames = {frame};
  transforms.wavelengths_nm = {500, 600};
  transforms.test_files = {"images/a.png"};
  seed(ReaderKind::Transforms, written(dir / "transforms.json", [&](const fs::path& p) {
         io::write_transforms(p, transforms);
       }));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds DIR\n");
    return 2;
  }
  g_out = argv[1];
  fs::create_directories(g_out);
  const fs::path scratch = g_out / ".scratch";
  fs::create_directories(scratch);
  torch::manual_seed(0);
  cube_seeds(scratch);
  ply_seeds(scratch);
  colmap_seeds(scratch);
  json_seeds(scratch);
  fs::remove_all(scratch);
  std::printf("fuzz_seeds: %d seeds in %s\n", g_count, g_out.c_str());
  return 0;
}
