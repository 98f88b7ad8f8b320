// The fused L1 + SSIM kernel behind model/ssim_fused.h. Internal to the model
// layer; exposed for its tests and benchmark.
#pragma once
#include <cstdint>

namespace ddhgs::model::ssim_kernel {

struct Images {
  const float* render;  // [H, W, N] contiguous
  const float* target;  // [H, W, N] contiguous
  int64_t height = 0, width = 0, bands = 0;
};

struct Sums {
  double l1 = 0;    // sum of |render - target| over every pixel and band
  double ssim = 0;  // sum of SSIM over valid windows and bands
};

// Sums over the whole image. When grad is not null it receives
// d(mean SSIM)/d(render), [H, W, N], every element written. Work is split
// into row strips and band blocks fixed by the image's shape, and partial
// sums are added in a fixed order: results do not depend on the thread count.
Sums run(const Images& images, float* grad);

}  // namespace ddhgs::model::ssim_kernel
