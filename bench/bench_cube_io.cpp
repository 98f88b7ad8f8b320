// Reading one BaySpec-sized view (640 x 512, 141 bands) in every cube format,
// and converting it to float: the per-view cost of lazy dataset loading.
// Run: build/bench/bench_cube_io  (reports bytes/s of stored samples)
#include <benchmark/benchmark.h>

#include <filesystem>

#include "io/cube/cube.h"

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
BENCHMARK(to_float)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(probe, npy, "u8.npy")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(probe, envi, "bsq.hdr")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(probe, tiff_page_per_band, "pages.tif")->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
