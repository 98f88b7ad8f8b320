// Slow, dense, double-precision twin of rasterize() in plain LibTorch ops:
// every Gaussian against every pixel, a global depth sort and cumulative
// transmittance. Used only by tests, which compare values and autograd
// gradients of the two on random scenes.
#pragma once
#include "core/tensor.h"

#include "render/rasterize.h"

namespace ddhgs::render {

// Same contract as rasterize(); outputs are float64 (radii int32) and
// differentiable through ordinary autograd in every floating input.
RenderOutput rasterize_reference(const torch::Tensor& means,            // [G, 3]
                                 const torch::Tensor& log_scales,       // [G, 3]
                                 const torch::Tensor& quats,            // [G, 4]
                                 const torch::Tensor& logit_opacities,  // [G, 1]
                                 const torch::Tensor& colors,           // [G, N]
                                 const RenderCamera& camera,
                                 const torch::Tensor& background);  // [N]

}  // namespace ddhgs::render
