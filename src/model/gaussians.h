// The N-band Gaussian model: its parameters, how it renders, and its PLY form.
#pragma once
#include <torch/torch.h>

#include <vector>

#include "core/camera.h"
#include "io/ply/ply.h"
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
  torch::Tensor sh_dc;            // [G, N]
  torch::Tensor sh_rest;          // [G, N, K], K = (max degree + 1)^2 - 1
  int active_sh_degree = 0;       // raised during training up to max_sh_degree()

  int64_t size() const { return means.defined() ? means.size(0) : 0; }
  int64_t bands() const { return sh_dc.size(1); }
  int max_sh_degree() const;

  // The six parameter tensors in a fixed order (means first), and their names,
  // so optimizers, checkpoints and densification treat them uniformly.
  std::vector<torch::Tensor*> tensors();
  std::vector<torch::Tensor> values() const;  // handles to the same tensors, same order
  static const std::vector<std::string>& tensor_names();
};

// SH value at the camera centre (per-band colours) followed by rasterisation.
// Differentiable in every parameter; see render::rasterize for the sink.
// sh_rest_sink: see render::eval_sh (training hands the SH rest gradient to Adam).
render::RenderOutput render_gaussians(const Gaussians& gaussians, const core::Camera& camera,
                                      const torch::Tensor& background,              // [N]
                                      const torch::Tensor& band_offsets = {},       // [N, K+1]
                                      const torch::Tensor& means2d_grad_sink = {},  // [G, 2]
                                      const render::ShRestSink& sh_rest_sink = {});

// Detached float32 copies; sh_rest keeps all K coefficients of the max degree.
// band_offsets (the wavelength encoder's [N, K+1]) are added to every
// Gaussian's coefficients, so the PLY renders as the model did with them.
io::GaussianPly to_ply(const Gaussians& gaussians, const std::vector<double>& wavelengths_nm,
                       const torch::Tensor& band_offsets = {});
// active_sh_degree becomes the file's degree (a trained model renders at full degree).
Gaussians from_ply(const io::GaussianPly& ply);

// Bytes one Gaussian costs while training with Adam: parameter, gradient and
// two moments, float32: 4 * 4 * (11 + N * (K + 1)).
int64_t training_bytes_per_gaussian(int64_t bands, int sh_degree);

}  // namespace ddhgs::model
