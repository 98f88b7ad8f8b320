// Undistorting one view (io::Undistortion: one bilinear remap for all bands,
// in the stored sample type) against the other per-view costs: reading the
// file and converting the cached view to float, which Scene::image does on
// every access. Decides where undistortion belongs: once per decode (the
// cache keeps undistorted views) or on every access.
// Run: build/bench/bench_undistort  (one thread; CPU time per view)
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <filesystem>

#include "io/cube/cube.h"
#include "io/undistort/undistort.h"

namespace {
namespace fs = std::filesystem;
using namespace ddhgs;

// Surface Optics size (696 x 520, 128 bands) with a Hyper-NeRF-like lens.
core::Intrinsics surface_optics_lens() {
  core::Intrinsics k;
  k.width = 696;
  k.height = 520;
  k.fx = k.fy = 4870;
  k.cx = 348;
  k.cy = 260;
  k.k1 = -0.3;
  k.k2 = 0.1;
  k.p1 = 1e-4;
  k.p2 = -2e-4;
  return k;
}

torch::Tensor view_u8() {
  static torch::Tensor v = [] {
    torch::manual_seed(0);
    return torch::randint(0, 256, {520, 696, 128}).to(torch::kUInt8);
  }();
  return v;
}

void undistort(benchmark::State& state, io::SampleType type) {
  io::Undistortion u(surface_optics_lens());
  torch::Tensor data = type == io::SampleType::U8 ? view_u8() : view_u8().to(torch::kFloat) / 255;
  u.apply(data, type, "bench");  // builds the remap table
  for (auto _ : state) benchmark::DoNotOptimize(u.apply(data, type, "bench").data_ptr());
  state.SetBytesProcessed(int64_t(state.iterations() * data.nbytes()));
}

void build_table(benchmark::State& state) {
  torch::Tensor one_band = torch::zeros({520, 696, 1}, torch::kUInt8);
  for (auto _ : state) {
    io::Undistortion u(surface_optics_lens());  // the pinhole camera (bisection)
    benchmark::DoNotOptimize(u.apply(one_band, io::SampleType::U8, "bench").data_ptr());
  }
}

void read_npy(benchmark::State& state) {
  fs::path path = fs::temp_directory_path() / "ddhgs-bench-undistort-u8.npy";
  io::write_npy(path, view_u8());
  for (auto _ : state) benchmark::DoNotOptimize(io::read_cube(path).data.data_ptr());
  fs::remove(path);
}

void to_float(benchmark::State& state) {
  io::Cube cube{view_u8(), io::SampleType::U8, {}, {}, {}};
  for (auto _ : state) benchmark::DoNotOptimize(io::cube_to_float(cube).data_ptr());
}

BENCHMARK_CAPTURE(undistort, u8, io::SampleType::U8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(undistort, f32, io::SampleType::F32)->Unit(benchmark::kMillisecond);
BENCHMARK(build_table)->Unit(benchmark::kMillisecond);
BENCHMARK(read_npy)->Unit(benchmark::kMillisecond);
BENCHMARK(to_float)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  at::set_num_threads(1);  // CPU time of one thread: comparable across machines' loads
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
