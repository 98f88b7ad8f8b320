// Front-to-back alpha blending of depth-sorted splats per 16x16 tile, N
// channels, and its exact backward. Internal to the render layer.
#pragma once
#include "core/tensor.h"

#include <cstdint>

#include "render/project.h"
#include "render/tiles.h"

namespace ddhgs::render {

struct BlendForward {
  torch::Tensor image;    // [H, W, N]
  torch::Tensor alpha;    // [H, W] 1 - final transmittance
  torch::Tensor depth;    // [H, W] sum of blend weight * camera z
  torch::Tensor final_T;  // [H, W] final transmittance (only when asked for)
  int64_t pairs = 0;      // Gaussian-pixel pairs blended (alpha >= 1/255, not stopped)
};

// The blender's channel loops use 512-bit vectors (16 bands each) where the
// build targets AVX-512 (DDHGS_NATIVE on such a CPU), 256-bit ones otherwise.
// set_wide_kernels(false) selects the 256-bit loops in such a build, so that
// tests check both against the same reference; it has no effect elsewhere.
bool wide_kernels_built();
void set_wide_kernels(bool on);

// Images of at most 8 channels (a latent colour model's, RGB) are blended
// channel-major in the 8 pixel lanes of a group (render/lane_blend.h), where
// the build has AVX2 and FMA; set_lane_path(false) sends them through the
// row path that wider images take, so that tests can check both.
bool lane_path_built();
void set_lane_path(bool on);

// colors: [G, N] contiguous float32, background: [N] contiguous float32.
BlendForward blend_forward(const Projected& projected, const torch::Tensor& colors,
                           const torch::Tensor& background, const TileBins& bins, int width,
                           int height, bool keep_final_T);

struct BlendGrads {
  torch::Tensor means2d;     // [G, 2]
  torch::Tensor conics;      // [G, 3]
  torch::Tensor opacities;   // [G]
  torch::Tensor depths;      // [G]
  torch::Tensor colors;      // [G, N]
  torch::Tensor background;  // [N]
};

// Replays the forward per tile (same decisions bit for bit) and accumulates
// gradients in per-thread buffers that are summed in a fixed order.
// d_alpha and d_depth may be undefined (treated as zeros).
BlendGrads blend_backward(const Projected& projected, const torch::Tensor& colors,
                          const torch::Tensor& background, const TileBins& bins, int width,
                          int height, const BlendForward& forward,
                          const torch::Tensor& d_image,   // [H, W, N]
                          const torch::Tensor& d_alpha,   // [H, W]
                          const torch::Tensor& d_depth);  // [H, W]

}  // namespace ddhgs::render
