// Wavelength encoder (DD-HGS): per-band SH offsets from the band's wavelength.
//
//   lambda in [0, 1] (normalised over the sensor's range)
//   gamma(lambda) = [lambda?, sin(2^k pi lambda), cos(2^k pi lambda)]_{k<L}
//   delta_SH[n, :] = scale * MLP(gamma(lambda_n))        -> [N, (degree+1)^2]
//
// The offsets are added to every Gaussian's SH coefficients of that band
// inside render::eval_sh (no [G, N, 16] copy). Geometry is never modulated.
#pragma once
#include <torch/nn/module.h>
#include <torch/nn/modules/container/modulelist.h>

#include <vector>

#include "core/tensor.h"

namespace ddhgs::model {

struct WavelengthEncoderOptions {
  int frequencies = 10;        // L
  bool include_input = true;   // concatenate the raw normalised wavelength
  int hidden = 64;             // width of hidden layers
  int layers = 4;              // linear layers in total (>= 1)
  double output_scale = 0.01;  // the authors' code scaled the output by 0.01
  int sh_coeffs = 16;          // (degree + 1)^2 at degree 3
};

// Wavelengths (nm) -> [N] float in [0, 1]; one band maps to 0.5.
torch::Tensor normalise_wavelengths(const std::vector<double>& wavelengths_nm);

// x: [N] -> [N, 2L (+1)].
torch::Tensor positional_encoding(const torch::Tensor& x, int frequencies, bool include_input);

class WavelengthEncoderImpl : public torch::nn::Module {
 public:
  explicit WavelengthEncoderImpl(const WavelengthEncoderOptions& options = {});
  // lambda01: [N] normalised wavelengths -> offsets [N, sh_coeffs].
  torch::Tensor forward(const torch::Tensor& lambda01);
  const WavelengthEncoderOptions& options() const { return options_; }

 private:
  WavelengthEncoderOptions options_;
  torch::nn::ModuleList linears_;
};
TORCH_MODULE(WavelengthEncoder);

}  // namespace ddhgs::model
