// Dense reference for eval_sh in plain LibTorch ops: every coefficient
// materialised as [G, N, K], differentiated by LibTorch's autograd. Slow and
// memory-hungry on purpose; tests compare the fast path against it.
#pragma once
#include "core/tensor.h"

namespace ddhgs::render {

// Basis [G, sh_coeff_count(degree)] at unit directions dirs [G, 3].
torch::Tensor sh_basis_reference(const torch::Tensor& dirs, int degree);

// Same contract as eval_sh (render/rasterize.h); computes in the inputs'
// dtype (tests pass float64). Expects valid shapes: it does no checking.
torch::Tensor eval_sh_reference(const torch::Tensor& sh_dc,          // [G, N]
                                const torch::Tensor& sh_rest,        // [G, N, K-1] or undefined
                                const torch::Tensor& means,          // [G, 3]
                                const torch::Tensor& camera_center,  // [3]
                                int degree,
                                const torch::Tensor& band_offsets = {},  // [N, K] or undefined
                                bool linear = false);

}  // namespace ddhgs::render
