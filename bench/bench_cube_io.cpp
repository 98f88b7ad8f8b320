// Reading one BaySpec-sized view (640 x 512, 141 bands) in every cube format,
// and converting it to float: the per-view cost of lazy dataset loading.
// Run: build/bench/bench_cube_io  (reports bytes/s of stored samples)
#include <benchmark/benchmark.h>

#include <filesystem>
#include <vector>

#include "io/cube/cube.h"
#include "lzw_tiff.h"

namespace {
namespace fs = std::filesystem;
using namespace ddhgs::io;

const fs::path& cube_dir() {
  static fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / "ddhgs-bench-cube-io";
    fs::create_directories(d);
    torch::manual_seed(0);
    torch::Tensor u8 = torch::randint(0, 256, {512, 640, 141}).to(torch::kUInt8);
    write_npy(d / "u8.npy", u8);
    write_npy(d / "bhw.npy", u8.permute({2, 0, 1}).contiguous());
    write_npy(d / "f32.npy", u8.to(torch::kFloat) / 255);
    for (auto [name, interleave] :
         {std::pair{"bsq", EnviInterleave::BSQ}, std::pair{"bil", EnviInterleave::BIL},
          std::pair{"bip", EnviInterleave::BIP}})
      write_envi(d / (std::string(name) + ".hdr"), u8, {}, interleave);
    write_tiff(d / "contig.tif", u8, TiffLayout::Contiguous);
    write_tiff(d / "pages.tif", u8, TiffLayout::Pages);
    const torch::Tensor x = torch::linspace(0, 1, 640).view({1, 640, 1});
    const torch::Tensor y = torch::linspace(0, 1, 512).view({512, 1, 1});
    const torch::Tensor band = torch::linspace(0, 1, 141).view({1, 1, 141});
    const torch::Tensor smooth =
        20000 + 15000 * torch::sin(3 * x + 2 * y + 4 * band) + 200 * torch::randn({512, 640, 141});
    ddhgs::bench::write_lzw_tiff(d / "lzw.tif", smooth);
    return d;
  }();
  return dir;
}

void read(benchmark::State& state, const std::string& name) {
  fs::path path = cube_dir() / name;
  size_t bytes = 0;
  for (auto _ : state) {
    Cube cube = read_cube(path);
    bytes = cube.bytes();
    benchmark::DoNotOptimize(cube.data.data_ptr());
  }
  state.SetBytesProcessed(int64_t(state.iterations() * bytes));
}

void to_float(benchmark::State& state) {
  Cube cube = read_cube(cube_dir() / "u8.npy");
  for (auto _ : state) benchmark::DoNotOptimize(cube_to_float(cube).data_ptr());
  state.SetBytesProcessed(int64_t(state.iterations() * cube.bytes()));
}

void probe(benchmark::State& state, const std::string& name) {
  fs::path path = cube_dir() / name;
  for (auto _ : state) benchmark::DoNotOptimize(probe_cube(path).bands);
}

BENCHMARK_CAPTURE(read, npy_u8, "u8.npy")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, npy_u8_bands_first, "bhw.npy")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, npy_f32, "f32.npy")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, envi_bsq, "bsq.hdr")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, envi_bil, "bil.hdr")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, envi_bip, "bip.hdr")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, tiff_contiguous, "contig.tif")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, tiff_page_per_band, "pages.tif")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(read, tiff_lzw_smooth_u16, "lzw.tif")->Unit(benchmark::kMillisecond);
BENCHMARK(to_float)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(probe, npy, "u8.npy")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(probe, envi, "bsq.hdr")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(probe, tiff_page_per_band, "pages.tif")->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
