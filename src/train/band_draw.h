// The bands a Gaussian iteration measures its loss on (loss.bands_per_step).
// A latent colour model decodes every band from the same K channels, so a
// few bands per iteration still train every Gaussian, the whole basis row by
// row over the iterations, and every band-mean term (L1, D-SSIM) in
// expectation: the decode, the loss and its backward then cost count / N of
// the full image's.
#pragma once
#include "core/tensor.h"

#include <cstdint>

namespace ddhgs::train {

// count of the bands 0 .. bands - 1, increasing: one from each of count
// strata of (nearly) equal size, [floor(j N / count), floor((j + 1) N /
// count)), uniform within it, drawn from seed alone (mix_seed(seed, j)).
// count >= bands gives every band. int64 [count]. core::selection_map of
// them is the map for model::ColourModel::mapped, with which the latent
// decode computes only them; io::Scene::image(view, window) reads only them.
torch::Tensor draw_bands(int64_t bands, int64_t count, uint64_t seed);

}  // namespace ddhgs::train
