// When things happen during training, in iteration numbers. Presets give the
// schedule as fractions of `iterations` (model.sh_degree_every_fraction,
// optim.means_lr_decay_fraction, lr_decay_from_fraction,
// densify.from_fraction, until_fraction, opacity_reset_every_fraction,
// loss.bands_per_step_until_fraction), so one
// preset means the same run shape at 2,000 and at 30,000 iterations;
// densify.every stays in iterations because it is the window over which
// view-space gradients are averaged, which depends on how many views it spans,
// not on the run's length.
#pragma once
#include <cstdint>

namespace ddhgs::train {

struct Schedule {
  int64_t iterations = 0;
  int64_t sh_degree_every = 0;       // raise the active SH degree every this many iterations
  int64_t means_lr_decay_steps = 0;  // position lr reaches means_lr_final here
  int64_t lr_decay_from = 0;         // the other rates start to fall after this one
  int64_t densify_from = 0;          // densify after this iteration ...
  int64_t densify_until = 0;         // ... and before this one
  int64_t densify_every = 0;
  int64_t opacity_reset_every = 0;  // 0: never
  // loss.bands_per_step draws bands up to and including this iteration.
  int64_t bands_drawn_until = 0;
  // loss.view_fraction crops the views up to and including this iteration.
  int64_t views_cropped_until = 0;
  // A rig run (camera_refinement.rig) trains on the reference camera's views
  // alone up to and including this iteration; 0: from the start on all.
  int64_t reference_views_until = 0;
  // ... and after it, up to and including this iteration, aligns the band
  // cameras (camera_refinement.rig_align_fraction): their views train their
  // corrections and the colours, not the Gaussians' shape; 0: no such phase.
  int64_t rig_align_until = 0;

  bool densifies(int64_t iteration) const { return iteration < densify_until; }
  bool draws_bands(int64_t iteration) const { return iteration <= bands_drawn_until; }
  bool crops_views(int64_t iteration) const { return iteration <= views_cropped_until; }
  bool reference_views_only(int64_t iteration) const { return iteration <= reference_views_until; }
  bool aligns_rig(int64_t iteration) const {
    return iteration > reference_views_until && iteration <= rig_align_until;
  }
};

struct RunConfig;

// How many Gaussian iterations a run of `config` trains: `iterations`, or,
// on a band-per-view scene (a rig's flight: one band image per view), at most
// optim.iterations_per_band_view per training view (0: no such limit). Such a
// flight supervises one band image per iteration, and its held-out views stop
// improving after about a hundred passes over them (docs/benchmarks.md, "A
// 1280x960 strip with the defaults"), long before 30,000 iterations at
// 1280x960 do (hours on two cores).
int64_t run_iterations(const RunConfig& config, bool band_per_view, int64_t training_views);

// The schedule of a run's config: round(fraction x iterations), and at
// least 1 for the intervals whose fraction is above zero.
Schedule schedule_of(const RunConfig& config);

// The slot (0 to slots - 1) step `iteration` (1-based) takes: a fresh
// permutation of the slots every epoch of `slots` steps, drawn from `seed`
// and the epoch (train/seed.h mix_seed), so each slot comes once an epoch.
int64_t epoch_slot(int64_t iteration, int64_t slots, uint64_t seed);

}  // namespace ddhgs::train
