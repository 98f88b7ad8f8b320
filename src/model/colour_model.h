// The colour model (../shared/DESIGN.md): how a Gaussian's SH coefficients
// become band values. One value type with two forms; render, train, eval,
// export and the report ask it and never branch on which form it has.
//
//   per band (basis undefined): one SH set per band, C = N channels, each
//     colour max(SH + 0.5, 0). The rasterizer blends the bands themselves
//     over the background (the paper's model).
//   latent (basis [N, K], mean [N]): SH over K latent channels, C = K, each
//     channel the plain SH value (no offset, no clamp). The rasterizer blends
//     K channels over a zero background, and decode() maps a pixel to bands:
//       bands = basis . latent + alpha mean + (1 - alpha) background.
//     The map is linear, so this is exact: with weights w_i and final
//     transmittance T = 1 - alpha, sum_i w_i (B z_i + m) + T bg
//     = B sum_i w_i z_i + (1 - T) m + T bg.
//
// An output map [M, N] (bands at other wavelengths, or what another sensor's
// response functions see; render/band_map.h) applies after decoding in both
// forms, so a model renders M channels instead of N.
#pragma once
#include "core/tensor.h"

#include "core/spectral_pca.h"

namespace ddhgs::model {

struct ColourModel {
  torch::Tensor basis;   // [N, K] float32; undefined: per band
  torch::Tensor mean;    // [N] float32 (latent only)
  torch::Tensor output;  // [M, N] float32 applied after decoding; undefined: the N bands

  bool latent() const { return basis.defined(); }
  int64_t rank() const { return latent() ? basis.size(1) : 0; }  // K; 0 per band
  // Blended channels for a model of N bands: K, or N per band.
  int64_t channels(int64_t bands) const { return latent() ? rank() : bands; }
  // The factor on the SH learning rates: latent_scale for a latent model
  // (optim.latent_sh_lr_scale), 1 per band.
  double sh_rate_scale(double latent_scale) const { return latent() ? latent_scale : 1.0; }
  // Whether SH values are used as they are (render::eval_sh's `linear`).
  bool linear_sh() const { return latent(); }

  // The background the rasterizer blends over: background [N] per band, a
  // zero [K] latent (decode adds the background).
  torch::Tensor blend_background(const torch::Tensor& background) const;
  // The rendered bands [H, W, M] from the blended channels [H, W, C], the
  // alpha [H, W] and the background [N]. Differentiable in every input and
  // in basis and mean.
  torch::Tensor decode(const torch::Tensor& blended, const torch::Tensor& alpha,
                       const torch::Tensor& background) const;
  // The affine map from SH values (sum_k c_k Y_k, per channel) to bands,
  // before the per-band clamp: bands = A . values + offset, A [M, C] and
  // offset [M] float64 for a model of N bands (per band: I and 0.5). For
  // maps of the coefficients themselves (exports, the report's 3D view).
  std::pair<torch::Tensor, torch::Tensor> affine(int64_t bands) const;
  // Band values [G, M] of SH values [G, C] at full opacity (a Gaussian's
  // colour: its DC coefficients times Y_0^0), clamped at 0 per band as
  // rendering does; float64.
  torch::Tensor spectra(const torch::Tensor& sh_values) const;
  // Channel values [G, C] whose spectra() are closest to spectra [G, N] in
  // least squares (exact per band and within the basis's span); ignores
  // output. For starting Gaussians from known colours.
  torch::Tensor channels_for(const torch::Tensor& spectra) const;
  // SH DC coefficients [G, C] whose colour from every side is closest to
  // spectra [G, N] (per band: (v - 0.5) / Y_0^0).
  torch::Tensor sh_dc_for(const torch::Tensor& spectra) const;

  // The wavelength encoder's output per band: (degree+1)^2 SH offsets per
  // band, or K + 1 latent (basis row offsets, then the mean's).
  int64_t encoder_width(int sh_coeffs) const { return latent() ? rank() + 1 : sh_coeffs; }
  // Encoder output [N, encoder_width] as SH offsets (per band), else undefined.
  torch::Tensor sh_offsets(const torch::Tensor& encoder_output) const;
  // The model with encoder output [N, K + 1] added to basis and mean
  // (latent); per band, or when undefined, the model itself.
  ColourModel with_encoder(const torch::Tensor& encoder_output) const;
  // The model rendering map . bands ([M, N], composed with an earlier map).
  ColourModel mapped(const torch::Tensor& map) const;
  // Detached float32 copies (for a model held beside trained parameters).
  ColourModel detached() const;
};

// A latent model of rank k (1 <= k <= N) from principal components: the
// first k components and the mean, float32. The basis columns have length
// sqrt(N), not 1, so a latent value moves a spectrum along a component about
// as far per band as a per-band coefficient moves its band: with Adam's
// steps of about one learning rate, a latent model then learns as fast as
// a per-band one at the same rates.
ColourModel latent_from_pca(const core::SpectralPca& pca, int64_t k);

}  // namespace ddhgs::model
