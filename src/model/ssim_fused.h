// L1 and SSIM of a render against its target in one hand-written pass over
// [H, W, N] channels-last images, with the gradient w.r.t. the render.
//
// Same definitions as model/ssim.h (11 x 11 Gaussian window, sigma 1.5,
// "valid" windows only, K1 = 0.01, K2 = 0.03, population covariances) and as
// the mean absolute error; model::ssim and (a - b).abs().mean() are the
// reference twins the tests compare against. LibTorch's version runs ten
// grouped convolutions over 5N channels and keeps some twenty [H, W, N]
// temporaries for autograd; this one blurs band blocks of rows held in small
// ring buffers (separable window, bands innermost and vectorised, row strips
// and band blocks spread over threads) and writes one [H, W, N] gradient.
#pragma once
#include "core/tensor.h"

namespace ddhgs::model {

struct PhotometricValues {
  torch::Tensor l1;    // 0-d: mean |render - target| over pixels and bands
  torch::Tensor ssim;  // 0-d: mean SSIM over valid windows and bands
};

// Differentiable in render only (the target is data): the gradient is
// computed with the values when render requires it, and autograd's backward
// combines the two terms' weights in one pass. Images must be at least
// 11 x 11 pixels; float32 (other dtypes are converted).
PhotometricValues l1_and_ssim(const torch::Tensor& render,   // [H, W, N]
                              const torch::Tensor& target);  // [H, W, N]

}  // namespace ddhgs::model
