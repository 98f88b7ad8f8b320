// Cost of the diffusion denoiser: one training step of the U-Net on a crop,
// and DDIM inference on a whole small view, at the default width and half it.
#include <benchmark/benchmark.h>

#include "core/early_setup.h"
#include "core/threads.h"
#include "model/diffusion.h"

using namespace ddhgs;

namespace {

// Default depth (3 levels, 1 block each, no attention) at a given width.
model::UNet unet_of_width(int64_t bands, int64_t base_channels) {
  model::UNetOptions options;
  options.bands = bands;
  options.base_channels = base_channels;
  return model::UNet(options);
}

// Forward and backward of the diffusion loss on one crop_px x crop_px crop.
// Arguments: bands, crop (pixels), base channels.
void BM_UNetTrainStep(benchmark::State& state) {
  core::configure_threads();
  const int64_t bands = state.range(0), crop_px = state.range(1);
  torch::manual_seed(0);
  model::Denoiser denoiser{unet_of_width(bands, state.range(2)), model::NoiseSchedule()};
  auto gt = torch::rand({crop_px, crop_px, bands});
  auto render = torch::rand({crop_px, crop_px, bands}).requires_grad_(true);
  auto generator = at::make_generator<at::CPUGeneratorImpl>(1);
  for (auto _ : state) {
    denoiser.unet->zero_grad();
    model::view_diffusion_loss(denoiser, gt, render, crop_px, generator).backward();
  }
  state.counters["steps/s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_UNetTrainStep)
    ->Args({40, 64, 32})
    ->Args({141, 64, 32})
    ->Args({40, 64, 16})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Deterministic DDIM on a 128 x 96 view. Arguments: bands, K, base channels.
void BM_DdimDenoise(benchmark::State& state) {
  core::configure_threads();
  const int64_t bands = state.range(0), steps = state.range(1);
  torch::manual_seed(0);
  const model::Denoiser denoiser{unet_of_width(bands, state.range(2)), model::NoiseSchedule()};
  auto render = torch::rand({96, 128, bands});
  model::SamplerOptions options;
  options.steps = steps;
  for (auto _ : state) benchmark::DoNotOptimize(model::denoise_view(denoiser, render, options));
  state.counters["frames/s"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DdimDenoise)
    ->Args({40, 10, 32})
    ->Args({141, 10, 32})
    ->Args({40, 10, 16})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
