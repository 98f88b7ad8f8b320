#include "model/colour_model.h"

#include <cmath>

#include "core/error.h"
#include "render/decode.h"
#include "render/sh.h"

namespace ddhgs::model {

torch::Tensor ColourModel::blend_background(const torch::Tensor& background) const {
  if (!latent()) return background;
  return torch::zeros({rank()}, background.options());
}

torch::Tensor ColourModel::decode(const torch::Tensor& blended, const torch::Tensor& alpha,
                                  const torch::Tensor& background) const {
  if (!latent()) return output.defined() ? torch::matmul(blended, output.t()) : blended;
  core::require(blended.dim() == 3 && blended.size(2) == rank() && alpha.dim() == 2,
                "colour model: decode needs [H, W, K] channels and an [H, W] alpha");
  const int64_t H = blended.size(0), W = blended.size(1);
  torch::Tensor B = basis, m = mean, bg = background;
  if (output.defined()) B = output.matmul(B), m = output.matmul(m), bg = output.matmul(bg);
  if (blended.scalar_type() == torch::kFloat32)
    return render::decode_latent(blended.reshape({H * W, rank()}), alpha, B, m, bg)
        .reshape({H, W, B.size(0)});
  // Other dtypes (tests' double paths): one product [z | alpha | 1] . [B^T ; m - bg ; bg].
  auto rows = torch::cat({blended.reshape({H * W, rank()}), alpha.reshape({H * W, 1}),
                          torch::ones({H * W, 1}, blended.options())},
                         1);
  auto map = torch::cat({B.t(), (m - bg).unsqueeze(0), bg.unsqueeze(0)}, 0).to(rows.dtype());
  return rows.matmul(map).reshape({H, W, B.size(0)});
}

std::pair<torch::Tensor, torch::Tensor> ColourModel::affine(int64_t bands) const {
  const auto f64 = torch::kFloat64;
  torch::Tensor A = latent() ? basis.detach().to(f64) : torch::eye(bands, f64);
  torch::Tensor offset = latent() ? mean.detach().to(f64) : torch::full({bands}, 0.5, f64);
  if (output.defined()) {
    const auto M = output.detach().to(f64);
    A = M.matmul(A);
    offset = M.matmul(offset);
  }
  return {A, offset};
}

torch::Tensor ColourModel::spectra(const torch::Tensor& sh_values) const {
  const auto values = sh_values.detach().to(torch::kFloat64);
  if (!latent()) {
    const auto bands = (values + 0.5).clamp_min(0);
    return output.defined() ? bands.matmul(output.detach().to(torch::kFloat64).t()) : bands;
  }
  const auto [A, offset] = affine(values.size(1));
  return values.matmul(A.t()) + offset;
}

torch::Tensor ColourModel::channels_for(const torch::Tensor& spectra) const {
  if (!latent()) return spectra;
  const auto B = basis.detach().to(torch::kFloat64);
  const auto centred = spectra.to(torch::kFloat64) - mean.detach().to(torch::kFloat64);
  // Least squares through the pseudo-inverse: exact for an orthonormal basis.
  return centred.matmul(torch::pinverse(B).t()).to(spectra.scalar_type());
}

torch::Tensor ColourModel::sh_dc_for(const torch::Tensor& spectra) const {
  const double c0 = render::sh_constants::C0;
  if (!latent()) return ((spectra - 0.5) / c0).contiguous();
  return (channels_for(spectra) / c0).contiguous();
}

torch::Tensor ColourModel::sh_offsets(const torch::Tensor& encoder_output) const {
  return latent() ? torch::Tensor() : encoder_output;
}

ColourModel ColourModel::with_encoder(const torch::Tensor& encoder_output) const {
  if (!latent() || !encoder_output.defined()) return *this;
  core::require(encoder_output.dim() == 2 && encoder_output.size(0) == basis.size(0) &&
                    encoder_output.size(1) == rank() + 1,
                "colour model: the wavelength encoder must give [N, K + 1] for a latent model");
  ColourModel m = *this;
  m.basis = basis + encoder_output.slice(1, 0, rank());
  m.mean = mean + encoder_output.select(1, rank());
  return m;
}

ColourModel ColourModel::mapped(const torch::Tensor& map) const {
  core::require(map.dim() == 2, "colour model: a band map must be [M, N]");
  ColourModel m = *this;
  const auto f = map.to(torch::kFloat32);
  m.output = output.defined() ? f.matmul(output) : f;
  return m;
}

ColourModel ColourModel::detached() const {
  ColourModel m;
  auto copy = [](const torch::Tensor& t) {
    return t.defined() ? t.detach().to(torch::kFloat32).contiguous().clone() : t;
  };
  m.basis = copy(basis);
  m.mean = copy(mean);
  m.output = copy(output);
  return m;
}

ColourModel latent_from_pca(const core::SpectralPca& pca, int64_t k) {
  core::require(k >= 1 && k <= pca.bands(), "colour model: rank " + std::to_string(k) + " for " +
                                                std::to_string(pca.bands()) +
                                                " bands (must be 1 to the band count)");
  ColourModel m;
  const double length = std::sqrt(double(pca.bands()));
  m.basis = (pca.basis.slice(1, 0, k) * length).to(torch::kFloat32).contiguous();
  m.mean = pca.mean.to(torch::kFloat32).contiguous();
  return m;
}

}  // namespace ddhgs::model
