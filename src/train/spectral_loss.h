// Spectral loss (DD-HGS): per pixel, D = softmax over bands (of x / temperature);
//   L = alpha * KL(D_gt || D_pred) + beta * (1 - cos(D_gt, D_pred))
// averaged over pixels. The paper sums over pixels; averaging keeps the weight
// w3 independent of image size (a sum would multiply it by H x W).
//
// Softmax is invariant to adding a constant to every band, so this loss sees
// only the spectrum's shape, never its overall brightness: L1 and SSIM carry
// the absolute level. Values in [0, 1] give nearly flat softmax distributions
// at temperature 1 (the paper's choice); a temperature below 1 sharpens them.
#pragma once
#include "core/tensor.h"

namespace ddhgs::train {

struct SpectralLossOptions {
  double alpha = 0.5;        // KL weight
  double beta = 0.5;         // cosine weight
  double temperature = 1.0;  // softmax temperature
};

// pred, gt: [..., N] (bands last, e.g. [H, W, N]); returns a scalar.
// Stable: log-softmax for KL; finite for all-zero or all-equal spectra.
torch::Tensor spectral_loss(const torch::Tensor& pred, const torch::Tensor& gt,
                            const SpectralLossOptions& options = {});

}  // namespace ddhgs::train
