// The N-band Gaussian model: its parameters, its colour model, how it
// renders, and its PLY form.
#pragma once
#include "core/tensor.h"

#include <vector>

#include "core/camera.h"
#include "io/ply/ply.h"
#include "model/colour_model.h"
#include "render/rasterize.h"

namespace ddhgs::model {

// SH coefficients per band beyond DC at degree 3: (3 + 1)^2 - 1.
constexpr int kShRestMax = 15;
// Y_0^0: the DC coefficient that maps a value v to (v - 0.5) / kShC0.
constexpr double kShC0 = 0.28209479177387814;

struct Gaussians {
  torch::Tensor means;            // [G, 3] scene units
  torch::Tensor log_scales;       // [G, 3] log of the standard deviations
  torch::Tensor quats;            // [G, 4] (w, x, y, z), unnormalised
  torch::Tensor logit_opacities;  // [G, 1]
  torch::Tensor sh_dc;            // [G, C], C = colour.channels(N)
  torch::Tensor sh_rest;          // [G, C, K], K = (max degree + 1)^2 - 1
  int active_sh_degree = 0;       // raised during training up to max_sh_degree()
  // Per band or latent (model/colour_model.h). Shared by every Gaussian: not
  // one of tensors(); training holds its basis and mean as a module.
  ColourModel colour;

  int64_t size() const { return means.defined() ? means.size(0) : 0; }
  int64_t channels() const { return sh_dc.size(1); }                                     // C
  int64_t bands() const { return colour.latent() ? colour.basis.size(0) : channels(); }  // N
  int max_sh_degree() const;

  // The six parameter tensors in a fixed order (means first), and their names,
  // so optimizers, checkpoints and densification treat them uniformly.
  std::vector<torch::Tensor*> tensors();
  std::vector<torch::Tensor> values() const;  // handles to the same tensors, same order
  static const std::vector<std::string>& tensor_names();
};

// SH value at the camera centre (the C channels' values), rasterisation of
// the C channels, then the colour model's decode to bands: image [H, W, M]
// (M = N unless the colour model has an output map). Differentiable in every
// parameter, the colour model's basis and mean included; see render::rasterize
// for the sink. encoder_output: the wavelength encoder's [N, width]
// (ColourModel::encoder_width). sh_rest_sink: see render::eval_sh (training
// hands the SH rest gradient to Adam).
render::RenderOutput render_gaussians(const Gaussians& gaussians, const core::Camera& camera,
                                      const torch::Tensor& background,              // [N]
                                      const torch::Tensor& encoder_output = {},     // [N, width]
                                      const torch::Tensor& means2d_grad_sink = {},  // [G, 2]
                                      const render::ShRestSink& sh_rest_sink = {});

// Detached float32 copies; sh_rest keeps all K coefficients of the max degree.
// The wavelength encoder's output is baked in (added to every Gaussian's
// coefficients per band, or to a latent model's basis and mean), so the PLY
// renders as the model did with it. A latent model's basis and mean go with
// it.
io::GaussianPly to_ply(const Gaussians& gaussians, const std::vector<double>& wavelengths_nm,
                       const torch::Tensor& encoder_output = {});
// active_sh_degree becomes the file's degree (a trained model renders at full degree).
Gaussians from_ply(const io::GaussianPly& ply);

// Bytes one Gaussian costs while training with Adam: parameter, gradient and
// two moments, float32: 4 * 4 * (11 + C * (degree + 1)^2), C the channels
// (N per band, K latent).
int64_t training_bytes_per_gaussian(int64_t channels, int sh_degree);

}  // namespace ddhgs::model
