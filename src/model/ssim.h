// Structural similarity over all bands of an [H, W, N] image.
//
// 11 x 11 Gaussian window (sigma 1.5 pixels, centred), K1 = 0.01, K2 = 0.03,
// data range 1, population (not sample) covariances. Only windows that fit
// inside the image are averaged ("valid" filtering), as scikit-image does, so
// borders are not biased by zero padding.
#pragma once
#include "core/tensor.h"

namespace ddhgs::model {

constexpr int kSsimWindow = 11;     // pixels
constexpr double kSsimSigma = 1.5;  // pixels

// Mean SSIM over pixels and bands (a 0-d tensor), or [N] per band when
// per_band. Differentiable in both inputs. Images must be at least 11 x 11.
torch::Tensor ssim(const torch::Tensor& a,  // [H, W, N] float in [0, 1]
                   const torch::Tensor& b,  // [H, W, N]
                   bool per_band = false);

// The SSIM map before averaging: [N, H - 10, W - 10].
torch::Tensor ssim_map(const torch::Tensor& a,   // [H, W, N]
                       const torch::Tensor& b);  // [H, W, N]

}  // namespace ddhgs::model
