// Initial Gaussians for a scene: one per sparse point (colours from the
// points' spectra, else from the training views they project into, else
// grey), or random points inside the cameras' view volume.
#pragma once
#include "core/tensor.h"

#include <cstdint>
#include <vector>

#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::train {

struct InitOptions {
  bool random = false;  // ignore the scene's points
  int64_t random_points = 100000;
  // Random points added beside a dataset's own points, per pixel of the first
  // training view: sparse structure from motion covers the textured object,
  // not a backdrop or floor that the views also show (Basil's turntable:
  // docs/benchmarks.md). Per pixel, so a small image is not buried in them.
  double extra_random_per_pixel = 0;
  double opacity = 0.1;
  int neighbours = 3;    // for the initial scale
  int colour_views = 8;  // training views sampled to colour points without spectra
  int sh_degree = 3;     // size of sh_rest
  uint64_t seed = 0;
};

// The largest angle, degrees, between a view's viewing direction and the
// views' mean direction: small for one-sided captures (a nadir flight strip,
// a facade), large for views around an object (a turntable).
double view_direction_spread_deg(const io::Scene& scene, const std::vector<int>& views);
// Below this spread the extra random points are left out: in the slab that
// parallel views share they become floaters in front of the views (a nadir
// strip of 8 captures: 26.4 dB with them, 31.7 dB without; docs/benchmarks.md).
constexpr double kOneSidedSpreadDeg = 30;

// Random points when random is set or the scene has none; otherwise the
// scene's points plus extra_random_per_pixel x (pixels of a view) random
// ones (grey), except for a one-sided capture (kOneSidedSpreadDeg). Their coefficients are the
// colour model's (it becomes theirs).
model::Gaussians initialise_gaussians(const io::Scene& scene, const InitOptions& options,
                                      const model::ColourModel& colour = {});

// The colour model model.spectral_rank asks for: per band for 0; else a
// latent one of that rank (-1: the scene's whitened signal rank,
// core::whitened_signal_rank, when the scene has at least
// subspace_from_bands bands, else per band) from the PCA of up to 8
// training views' pixels (io::sample_spectra). Throws naming the scene when
// the rank is above its band count.
model::ColourModel initial_colour_model(const io::Scene& scene, int spectral_rank,
                                        int subspace_from_bands = 0);

// The colour model of a checkpoint of rank `rank` (model::ColourModel::rank;
// 0 per band) for the scene's bands, to load its basis and mean into: zeros
// of the checkpoint's shapes. Logs what it is and where it comes from.
model::ColourModel resumed_colour_model(const io::Scene& scene, int64_t rank);

// 3DGS's scene extent (io/scene/scene.h).
using io::scene_extent;

// Uniform points along random pixel rays of the given views, at depths within
// the camera's distance d to the point the cameras look at (least-squares
// closest point to their optical axes) plus or minus min(d / 2, r), r the
// radius the views see at that distance: [count, 3].
torch::Tensor sample_view_volume(const io::Scene& scene, const std::vector<int>& views,
                                 int64_t count, at::Generator& generator);

// Per-point values from the first sampled view that sees each point (pixel the
// point projects to, in front of the camera): [P, N], and a [P, N] bool "seen"
// mask. In a band-per-view scene each band comes from the first view that
// holds it and sees the point.
std::pair<torch::Tensor, torch::Tensor> colours_from_views(const io::Scene& scene,
                                                           const std::vector<int>& views,
                                                           const torch::Tensor& xyz);  // [P, 3]

}  // namespace ddhgs::train
