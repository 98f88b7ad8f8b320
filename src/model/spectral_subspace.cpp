#include "model/spectral_subspace.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/spectral_pca.h"

namespace ddhgs::model {

namespace {

// Below this the spectra do not vary: the scale stays finite and the
// coefficients sit at 0.5.
constexpr double kMinSigma = 1e-6;

}  // namespace

torch::Tensor SpectralSubspace::encode(const torch::Tensor& image) const {
  TORCH_CHECK(image.size(-1) == bands(), "SpectralSubspace::encode: ", image.size(-1),
              " bands, the subspace has ", bands());
  const torch::Tensor x = image.to(torch::kFloat32) - mean;
  return torch::matmul(x, basis) / scale + 0.5;
}

torch::Tensor SpectralSubspace::apply(const torch::Tensor& image, const torch::Tensor& before,
                                      const torch::Tensor& after) const {
  TORCH_CHECK(before.sizes() == after.sizes() && before.size(-1) == channels(),
              "SpectralSubspace::apply: coefficients ", before.sizes(), " and ", after.sizes(),
              " must be [..., ", channels(), "]");
  const torch::Tensor change = (after - before.clamp(0.0, 1.0)) * scale;
  return image + torch::matmul(change, basis.t());
}

SpectralSubspace fit_spectral_subspace(const torch::Tensor& spectra, int64_t channels) {
  core::require(channels >= 1, "fit_spectral_subspace: channels must be at least 1");
  const core::SpectralPca pca = core::spectral_pca(spectra);
  const int64_t n = pca.bands(), kept = std::min(channels, n);
  SpectralSubspace s;
  s.mean = pca.mean.to(torch::kFloat32);
  s.basis = torch::zeros({n, channels}, torch::kFloat32);
  s.basis.slice(1, 0, kept).copy_(pca.basis.slice(1, 0, kept));
  // The spread within the kept components: the coefficients' variance.
  const torch::Tensor centred = spectra.to(torch::kFloat64) - pca.mean;
  const torch::Tensor coeffs = torch::matmul(centred, pca.basis.slice(1, 0, kept));
  const double sigma = std::sqrt(coeffs.pow(2).sum(1).mean().item<double>());
  s.scale = SpectralSubspace::kScaleSigmas * std::max(sigma, kMinSigma);
  return s;
}

}  // namespace ddhgs::model
