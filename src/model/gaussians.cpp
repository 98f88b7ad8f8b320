#include "model/gaussians.h"

#include <cmath>

#include "core/error.h"

namespace ddhgs::model {

namespace {

int degree_from_rest(int64_t k) {
  int degree = int(std::lround(std::sqrt(double(k + 1)))) - 1;
  if ((degree + 1) * (degree + 1) - 1 != k || degree < 0 || degree > 3)
    throw core::Error("Gaussians: " + std::to_string(k) +
                      " SH rest coefficients per band is not 0, 3, 8 or 15");
  return degree;
}

torch::Tensor detached_copy(const torch::Tensor& t) {
  return t.detach().to(torch::kFloat32).contiguous().clone();
}

}  // namespace

int Gaussians::max_sh_degree() const {
  return sh_rest.defined() && sh_rest.dim() == 3 ? degree_from_rest(sh_rest.size(2)) : 0;
}

std::vector<torch::Tensor*> Gaussians::tensors() {
  return {&means, &log_scales, &quats, &logit_opacities, &sh_dc, &sh_rest};
}

std::vector<torch::Tensor> Gaussians::values() const {
  return {means, log_scales, quats, logit_opacities, sh_dc, sh_rest};
}

const std::vector<std::string>& Gaussians::tensor_names() {
  static const std::vector<std::string> names{"means",           "log_scales", "quats",
                                              "logit_opacities", "sh_dc",      "sh_rest"};
  return names;
}

io::GaussianPly to_ply(const Gaussians& gaussians, const std::vector<double>& wavelengths_nm,
                       const torch::Tensor& encoder_output) {
  io::GaussianPly ply;
  ply.means = detached_copy(gaussians.means);
  ply.log_scales = detached_copy(gaussians.log_scales);
  ply.quats = detached_copy(gaussians.quats);
  ply.logit_opacities = detached_copy(gaussians.logit_opacities);
  ply.sh_dc = detached_copy(gaussians.sh_dc);
  ply.sh_rest = gaussians.sh_rest.defined()
                    ? detached_copy(gaussians.sh_rest)
                    : torch::zeros({gaussians.size(), gaussians.channels(), 0});
  ply.wavelengths_nm = wavelengths_nm;
  const ColourModel colour = gaussians.colour.with_encoder(encoder_output).detached();
  ply.basis = colour.basis;
  ply.mean = colour.mean;
  const torch::Tensor band_offsets = gaussians.colour.sh_offsets(encoder_output);
  if (band_offsets.defined()) {
    const int64_t k = ply.sh_rest.size(2);
    core::require(band_offsets.dim() == 2 && band_offsets.size(0) == gaussians.bands() &&
                      band_offsets.size(1) == k + 1,
                  "to_ply: band offsets must be [N, K+1] for the model's N bands and degree");
    auto offsets = band_offsets.detach().to(torch::kFloat32);
    ply.sh_dc += offsets.select(1, 0).unsqueeze(0);
    if (k > 0) ply.sh_rest += offsets.slice(1, 1).unsqueeze(0);
  }
  return ply;
}

Gaussians from_ply(const io::GaussianPly& ply) {
  Gaussians g;
  g.means = detached_copy(ply.means);
  g.log_scales = detached_copy(ply.log_scales);
  g.quats = detached_copy(ply.quats);
  g.logit_opacities = detached_copy(ply.logit_opacities);
  g.sh_dc = detached_copy(ply.sh_dc);
  g.sh_rest = ply.sh_rest.defined() ? detached_copy(ply.sh_rest)
                                    : torch::zeros({g.size(), g.channels(), 0});
  if (ply.basis.defined()) {
    g.colour.basis = detached_copy(ply.basis);
    g.colour.mean = detached_copy(ply.mean);
  }
  g.active_sh_degree = g.max_sh_degree();
  return g;
}

int64_t training_bytes_per_gaussian(int64_t channels, int sh_degree) {
  const int64_t floats = 3 + 3 + 4 + 1 + channels * (sh_degree + 1) * (sh_degree + 1);
  return floats * int64_t(sizeof(float)) * 4;
}

}  // namespace ddhgs::model
