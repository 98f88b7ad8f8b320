// EWA projection of 3D Gaussians to screen-space ellipses (3DGS conventions):
// forward and its exact backward. Internal to the render layer.
#pragma once
#include "core/tensor.h"

#include "render/rasterize.h"

namespace ddhgs::render {

// Per-Gaussian screen-space quantities. Culled Gaussians have radius 0.
struct Projected {
  torch::Tensor means2d;    // [G, 2] float32 pixels; zero when behind the near plane
  torch::Tensor conics;     // [G, 3] float32 (A, B, C) of the inverse 2D covariance
  torch::Tensor depths;     // [G] float32 camera z (scene units)
  torch::Tensor opacities;  // [G] float32 sigmoid(logit)
  torch::Tensor radii;      // [G] int32 pixels, 0 for culled Gaussians
};

// Inputs must be contiguous float32 on the CPU (rasterize() guarantees it).
Projected project_forward(const torch::Tensor& means,            // [G, 3]
                          const torch::Tensor& log_scales,       // [G, 3]
                          const torch::Tensor& quats,            // [G, 4]
                          const torch::Tensor& logit_opacities,  // [G, 1]
                          const RenderCamera& camera);

struct ProjectGrads {
  torch::Tensor means;            // [G, 3]
  torch::Tensor log_scales;       // [G, 3]
  torch::Tensor quats;            // [G, 4]
  torch::Tensor logit_opacities;  // [G, 1]
};

// Chain rule from screen-space gradients back to the 3D parameters. Culled
// Gaussians receive only the means2d gradient (when in front of the camera).
ProjectGrads project_backward(const torch::Tensor& means,            // [G, 3]
                              const torch::Tensor& log_scales,       // [G, 3]
                              const torch::Tensor& quats,            // [G, 4]
                              const torch::Tensor& logit_opacities,  // [G, 1]
                              const RenderCamera& camera, const Projected& projected,
                              const torch::Tensor& d_means2d,     // [G, 2]
                              const torch::Tensor& d_conics,      // [G, 3]
                              const torch::Tensor& d_depths,      // [G]
                              const torch::Tensor& d_opacities);  // [G]

// Half-widths of the clamp applied to x/z and y/z before the EWA Jacobian:
// 1.3x the field of view as in 3DGS, generalised to off-centre principal
// points. {neg_x, pos_x, neg_y, pos_y}, dimensionless tangents.
std::array<double, 4> jacobian_clamp_limits(const RenderCamera& camera);

}  // namespace ddhgs::render
