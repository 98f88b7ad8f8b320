// Cost of the diffusion denoiser at the default width: one training step of
// the U-Net on a crop, and DDIM inference on a whole small view.
#include <benchmark/benchmark.h>

#include "core/threads.h"
#include "model/diffusion.h"

using namespace ddhgs;

namespace {

model::UNet default_unet(int64_t bands) {
  model::UNetOptions options;
  options.bands = bands;
  return model::UNet(options);
}

// Forward and backward of the diffusion loss on one crop_px x crop_px crop.
void BM_UNetTrainStep(benchmark::State& state) {
  core::configure_threads();
  const int64_t bands = state.range(0), crop_px = state.range(1);
  torch::manual_seed(0);
  auto unet = default_unet(bands);
  model::NoiseSchedule schedule;
  auto gt = torch::rand({crop_px, crop_px, bands});
  auto render = torch::rand({crop_px, crop_px, bands}).requires_grad_(true);
  auto generator = at::make_generator<at::CPUGeneratorImpl>(1);
  for (auto _ : state) {
    unet->zero_grad();
    model::view_diffusion_loss(unet, schedule, gt, render, crop_px, generator).backward();
  }
  state.counters["steps/s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_UNetTrainStep)
    ->Args({40, 64})
    ->Args({141, 64})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Deterministic DDIM with K steps on a W x H view.
void BM_DdimDenoise(benchmark::State& state) {
  core::configure_threads();
  const int64_t bands = state.range(0), steps = state.range(1);
  torch::manual_seed(0);
  auto unet = default_unet(bands);
  model::NoiseSchedule schedule;
  auto render = torch::rand({96, 128, bands});
  model::SamplerOptions options;
  options.steps = steps;
  for (auto _ : state)
    benchmark::DoNotOptimize(model::denoise_view(unet, schedule, render, options));
  state.counters["frames/s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DdimDenoise)
    ->Args({40, 10})
    ->Args({141, 10})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
