#include "model/wavelength_encoder.h"

#include <torch/nn/modules/linear.h>

#include <cmath>

#include "core/error.h"

namespace ddhgs::model {

torch::Tensor normalise_wavelengths(const std::vector<double>& wavelengths_nm) {
  core::require(!wavelengths_nm.empty(), "wavelength encoder: no bands");
  auto wl = torch::tensor(wavelengths_nm, torch::kFloat64);
  double lo = wl.min().item<double>(), hi = wl.max().item<double>();
  if (hi - lo <= 0) return torch::full({wl.size(0)}, 0.5, torch::kFloat32);
  return ((wl - lo) / (hi - lo)).to(torch::kFloat32);
}

torch::Tensor positional_encoding(const torch::Tensor& x, int frequencies, bool include_input) {
  std::vector<torch::Tensor> parts;
  if (include_input) parts.push_back(x.unsqueeze(1));
  for (int k = 0; k < frequencies; ++k) {
    auto arg = x * (std::ldexp(1.0, k) * M_PI);
    parts.push_back(torch::sin(arg).unsqueeze(1));
    parts.push_back(torch::cos(arg).unsqueeze(1));
  }
  return torch::cat(parts, 1);
}

WavelengthEncoderImpl::WavelengthEncoderImpl(const WavelengthEncoderOptions& options)
    : options_(options) {
  core::require(options.layers >= 1 && options.hidden >= 1 && options.frequencies >= 0 &&
                    options.sh_coeffs >= 1,
                "wavelength encoder: layers, hidden and sh_coeffs must be positive");
  int in = 2 * options.frequencies + (options.include_input ? 1 : 0);
  core::require(in > 0, "wavelength encoder: no input features (frequencies 0, no raw input)");
  linears_ = register_module("linears", torch::nn::ModuleList());
  for (int i = 0; i < options.layers; ++i) {
    bool last = i + 1 == options.layers;
    int out = last ? options.sh_coeffs : options.hidden;
    torch::nn::Linear layer(torch::nn::LinearOptions(in, out));
    if (last) {
      // Zero output at step 0: switching the encoder on leaves a model unchanged.
      torch::NoGradGuard no_grad;
      layer->weight.zero_();
      layer->bias.zero_();
    }
    linears_->push_back(layer);
    in = out;
  }
}

torch::Tensor WavelengthEncoderImpl::forward(const torch::Tensor& lambda01) {
  auto h = positional_encoding(lambda01.to(torch::kFloat32), options_.frequencies,
                               options_.include_input);
  for (size_t i = 0; i < linears_->size(); ++i) {
    h = linears_[i]->as<torch::nn::Linear>()->forward(h);
    if (i + 1 < linears_->size()) h = torch::relu(h);
  }
  return h * options_.output_scale;
}

}  // namespace ddhgs::model
