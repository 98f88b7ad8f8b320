#include "train/schedule.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "train/run_config.h"
#include "train/seed.h"

namespace ddhgs::train {

namespace {

int64_t of_run(double fraction, int64_t iterations) {
  return std::llround(fraction * double(iterations));
}

// An interval: never shorter than one iteration unless switched off.
int64_t interval(double fraction, int64_t iterations) {
  return fraction > 0 ? std::max<int64_t>(1, of_run(fraction, iterations)) : 0;
}

}  // namespace

int64_t run_iterations(const RunConfig& config, bool band_per_view, int64_t training_views) {
  const int64_t per_view = config.optim.iterations_per_band_view;
  if (!band_per_view || per_view <= 0 || training_views <= 0) return config.iterations;
  return std::min(config.iterations, per_view * training_views);
}

Schedule schedule_of(const RunConfig& config) {
  Schedule s;
  s.iterations = config.iterations;
  const DensifyConfig& densify = config.densify;
  s.sh_degree_every = interval(config.model.sh_degree_every_fraction, s.iterations);
  s.means_lr_decay_steps = interval(config.optim.means_lr_decay_fraction, s.iterations);
  s.lr_decay_from = of_run(config.optim.lr_decay_from_fraction, s.iterations);
  s.densify_from = of_run(densify.from_fraction, s.iterations);
  s.densify_until = of_run(densify.until_fraction, s.iterations);
  s.densify_every = densify.every;
  s.opacity_reset_every = interval(densify.opacity_reset_every_fraction, s.iterations);
  s.bands_drawn_until = of_run(config.loss.bands_per_step_until_fraction, s.iterations);
  s.views_cropped_until = of_run(config.loss.view_fraction_until_fraction, s.iterations);
  const CameraRefinementConfig& cameras = config.camera_refinement;
  s.reference_views_until = cameras.rig ? of_run(cameras.rig_warmup_fraction, s.iterations) : 0;
  if (cameras.rig && cameras.rig_align_fraction > 0)
    s.rig_align_until = std::min(
        s.iterations, s.reference_views_until + interval(cameras.rig_align_fraction, s.iterations));
  return s;
}

int64_t epoch_slot(int64_t iteration, int64_t slots, uint64_t seed) {
  const int64_t epoch = (iteration - 1) / slots, position = (iteration - 1) % slots;
  auto generator =
      at::make_generator<at::CPUGeneratorImpl>(mix_seed(seed, uint64_t(2 * epoch + 1)));
  return torch::randperm(slots, generator, torch::kInt64)[position].item<int64_t>();
}

}  // namespace ddhgs::train
