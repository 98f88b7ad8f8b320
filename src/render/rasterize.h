// N-channel Gaussian rasterizer (CPU): autograd-aware entry points.
//
// Conventions (see core/camera.h and supplementary notes): OpenCV camera axes,
// pixel centres at +0.5, EWA projection with 0.3 dilation, 16x16 tiles sorted
// by depth, alpha = min(0.99, o * exp(-power)), alpha < 1/255 skipped, a pixel
// stops once transmittance < 1e-4.
#pragma once
#include "core/tensor.h"

#include <functional>

#include "core/camera.h"

namespace ddhgs::render {

struct RenderCamera {
  float fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  int width = 0, height = 0;
  float world_to_camera[16];  // row-major, OpenCV axes
  float near_plane = 0.01f;   // scene units
  // core::Intrinsics' frame: the whole view this image is a part of
  // (frame_width 0: the image itself), for the Jacobian clamp.
  int frame_x = 0, frame_y = 0, frame_width = 0, frame_height = 0;
  static RenderCamera from(const core::Camera& camera);
};

struct RenderOutput {
  torch::Tensor image;    // [H, W, N] float32
  torch::Tensor alpha;    // [H, W]
  torch::Tensor depth;    // [H, W] alpha-weighted camera z
  torch::Tensor radii;    // [G] int32, 0 for culled Gaussians
  torch::Tensor means2d;  // [G, 2] pixels
};

// Renders Gaussians with precomputed colours. Differentiable (through
// torch::autograd) in means, log_scales, quats, logit_opacities and colors.
// means2d_grad_sink: optional [G, 2] zeros tensor with requires_grad; after
// backward its .grad() holds dL/d(means2d), which densification needs.
RenderOutput rasterize(const torch::Tensor& means,            // [G, 3]
                       const torch::Tensor& log_scales,       // [G, 3]
                       const torch::Tensor& quats,            // [G, 4] (w, x, y, z), unnormalised
                       const torch::Tensor& logit_opacities,  // [G, 1]
                       const torch::Tensor& colors,           // [G, N]
                       const RenderCamera& camera,
                       const torch::Tensor& background,  // [N]
                       const torch::Tensor& means2d_grad_sink = {});

// Per-band spherical harmonics of degree 0-3:
//   colour[g, n] = max(sum_k c[g, n, k] Y_k(dir_g) + 0.5, 0)
// with c[g, n, 0] = sh_dc[g, n], c[g, n, k] = sh_rest[g, n, k-1] for k >= 1,
// plus band_offsets[n, k] when given (the wavelength encoder's per-band
// offsets, added without materialising a [G, N, K] copy), and
// dir_g = normalize(means[g] - camera_center). Coefficients above `degree`
// are ignored. Differentiable in sh_dc, sh_rest, band_offsets and means.
//
// rest_sink (training): the backward hands dL/d(sh_rest) to it in blocks of
// Gaussians instead of returning a [G, N, K-1] gradient (sh_rest.grad() stays
// undefined), so an optimizer can update those rows while they are in cache
// and no gradient of the model's largest tensor is stored. It is called once
// per block, possibly from several threads at once, after the block's other
// gradients (which read sh_rest) are computed; it may modify those rows of
// sh_rest. Needs a contiguous float32 sh_rest.
//
// linear (a latent colour model's channels, model/colour_model.h): the value
// is sum_k c[g, n, k] Y_k(dir_g), without the +0.5 and without the clamp.
using ShRestSink = std::function<void(int64_t first, int64_t count,
                                      const float* grad)>;  // grad: [count, N, K-1]
torch::Tensor eval_sh(const torch::Tensor& sh_dc,           // [G, N]
                      const torch::Tensor& sh_rest,         // [G, N, K-1] or undefined
                      const torch::Tensor& means,           // [G, 3]
                      const torch::Tensor& camera_center,   // [3]
                      int degree, const torch::Tensor& band_offsets = {},  // [N, K] or undefined
                      const ShRestSink& rest_sink = {}, bool linear = false);

}  // namespace ddhgs::render
