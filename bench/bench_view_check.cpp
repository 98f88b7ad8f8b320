// The check `train` runs before its first iteration: every
// compressed view decoded once. Writes a scene of LZW-compressed 16-bit TIFF
// views (smooth spectra with noise, as a capture) and times
// train::check_scene_before_training on one thread and on all of them.
// Run: build/bench/bench_view_check [VIEWS=16] [WIDTH=640] [HEIGHT=512] [BANDS=141]
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "core/camera.h"
#include "core/threads.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "lzw_tiff.h"
#include "train/run_checks.h"

namespace {
namespace fs = std::filesystem;
using namespace ddhgs;

fs::path write_scene(int views, int width, int height, int bands) {
  // A folder of this process's own: nothing else is ever removed.
  const fs::path root =
      fs::temp_directory_path() / ("ddhgs-bench-view-check-" + std::to_string(::getpid()));
  if (!fs::create_directories(root / "cubes")) throw std::runtime_error(root.string() + " exists");
  io::TransformsFile file;
  for (int b = 0; b < bands; ++b) file.wavelengths_nm.push_back(400 + 5.0 * b);
  torch::manual_seed(0);
  const torch::Tensor x = torch::linspace(0, 1, width).view({1, width, 1});
  const torch::Tensor y = torch::linspace(0, 1, height).view({height, 1, 1});
  const torch::Tensor band = torch::linspace(0, 1, bands).view({1, 1, bands});
  for (int i = 0; i < views; ++i) {
    io::TransformsFrame f;
    f.hyperspectral_file_path = "cubes/v" + std::to_string(i) + ".tif";
    f.intrinsics.fx = f.intrinsics.fy = width;
    f.intrinsics.cx = width / 2.0;
    f.intrinsics.cy = height / 2.0;
    f.intrinsics.width = width;
    f.intrinsics.height = height;
    const double a = 6.283 * i / views;
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(
        core::look_at({3 * std::cos(a), 3 * std::sin(a), 1}, {0, 0, 0}, {0, 0, 1}));
    bench::write_lzw_tiff(root / f.hyperspectral_file_path,
                          20000 + 15000 * torch::sin(3 * x + 2 * y + 4 * band + 0.1 * i) +
                              200 * torch::randn({height, width, bands}));
    file.frames.push_back(f);
  }
  io::write_transforms(root / "transforms.json", file);
  return root;
}

double check_seconds(const fs::path& root) {
  io::LoadOptions options;
  options.cache_mb = 0;  // every view decoded by the check itself
  auto scene = io::load_scene(root, options);
  const auto start = std::chrono::steady_clock::now();
  train::check_scene_before_training(*scene);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

int main(int argc, char** argv) {
  const int views = argc > 1 ? std::atoi(argv[1]) : 16;
  const int width = argc > 2 ? std::atoi(argv[2]) : 640;
  const int height = argc > 3 ? std::atoi(argv[3]) : 512;
  const int bands = argc > 4 ? std::atoi(argv[4]) : 141;
  const fs::path root = write_scene(views, width, height, bands);
  const int all = core::configure_threads(0);
  double one = 0, many = 0;
  for (int round = 0; round < 2; ++round) {  // interleaved
    core::configure_threads(1);
    one += check_seconds(root) / 2;
    core::configure_threads(all);
    many += check_seconds(root) / 2;
  }
  std::printf(
      "%d LZW TIFF views of %dx%d, %d bands: check %.2f s on 1 thread (%.3f s per view), "
      "%.2f s on %d threads; %.2fx\n",
      views, width, height, bands, one, one / views, many, all, one / many);
  fs::remove_all(root);
  return 0;
}
