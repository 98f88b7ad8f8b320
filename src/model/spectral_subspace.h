// The fixed-width spectral space a denoiser prior works in, whatever a
// scene's band count. A scene's spectra lie close to a few principal
// components (core/spectral_pca.h); the prior sees each pixel as its first K
// coefficients, scaled into [0, 1], and its correction goes back into the
// bands along the same K directions. What lies outside them (mostly noise,
// and the detail of minor components) passes through unchanged, so a prior
// trained on scenes of 3 to 141 bands denoises a scene of any count.
//
//   u = 0.5 + ((x - mean) . basis) / scale            [.., N] -> [.., K]
//   x' = x + scale (u' - clamp(u, 0, 1)) . basis^T     the correction
//
// The basis columns are the scene's leading components, signed as
// core::spectral_pca signs them (each one's largest entry positive); with
// fewer than K bands the missing columns are zero and their coefficients
// stay 0.5. scale = kScaleSigmas x the spectra's standard
// deviation within the K components, so nearly every pixel lands inside
// [0, 1]; a pixel beyond gets its correction from the clamped coefficient.
#pragma once
#include "core/tensor.h"

namespace ddhgs::model {

struct SpectralSubspace {
  torch::Tensor mean;   // [N] float32
  torch::Tensor basis;  // [N, K] float32, orthonormal columns or zero ones
  double scale = 1;     // > 0

  int64_t bands() const { return mean.size(0); }
  int64_t channels() const { return basis.size(1); }

  // [..., N] -> [..., K], in [0, 1] for pixels within kScaleSigmas / 2
  // standard deviations (unclamped).
  torch::Tensor encode(const torch::Tensor& image) const;
  // The image with the change from `before` to `after` (both [..., K], as
  // encode returns them) applied in its bands; `before` is clamped to [0, 1]
  // first, as the denoiser's output is.
  torch::Tensor apply(const torch::Tensor& image, const torch::Tensor& before,
                      const torch::Tensor& after) const;

  static constexpr double kScaleSigmas = 8;
};

// The subspace of `spectra` ([M, N], M >= 1, any floating type): the mean and
// the first min(K, N) principal components, K = channels >= 1.
SpectralSubspace fit_spectral_subspace(const torch::Tensor& spectra, int64_t channels);

}  // namespace ddhgs::model
