// The linear decode of a latent colour model (model/colour_model.h) as one
// fused, multi-threaded kernel: blended latent channels and alpha to bands,
//   out[p, j] = sum_k z[p, k] B[j, k] + alpha[p] (m[j] - bg[j]) + bg[j].
// The same map in LibTorch ops costs two [P, M] temporaries per call and
// runs on one thread; at 640x512 and 141 bands each is 185 MB.
#pragma once
#include "core/tensor.h"

namespace ddhgs::render {

// Differentiable in every input (autograd Function). The output and the
// latent gradient are pooled (core/buffer_pool.h). The reductions over
// pixels (the gradients of basis, mean and background) are summed in fixed
// chunks, in order: the same bits for any thread count.
torch::Tensor decode_latent(const torch::Tensor& latent,       // [P, K] float32
                            const torch::Tensor& alpha,        // [P]
                            const torch::Tensor& basis,        // [M, K]
                            const torch::Tensor& mean,         // [M]
                            const torch::Tensor& background);  // [M]

}  // namespace ddhgs::render
