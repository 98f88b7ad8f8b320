#include "render/decode.h"

#include <vector>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/stage_timer.h"

namespace ddhgs::render {
namespace {

// Pixels per reduction chunk: the partial sums depend on it, not on threads.
constexpr int64_t kChunk = 2048;

// Rows the kernels read: the basis transposed ([K, M], one contiguous row
// per channel), then m - bg and bg.
struct Rows {
  torch::Tensor table;  // [K + 2, M] float32 contiguous
  int64_t K = 0, M = 0;
  const float* row(int64_t r) const { return table.data_ptr<float>() + r * M; }
};

Rows rows_of(const torch::Tensor& basis, const torch::Tensor& mean,
             const torch::Tensor& background) {
  Rows r;
  r.K = basis.size(1), r.M = basis.size(0);
  r.table = torch::cat({basis.t(), (mean - background).unsqueeze(0), background.unsqueeze(0)}, 0)
                .to(torch::kFloat32)
                .contiguous();
  return r;
}

// sum_j a[j] b[j] in 8 interleaved partial sums, added in a fixed order:
// the compiler keeps the 8 in one vector register (a plain running sum may
// not be reordered, so it would stay scalar).
inline float dot(const float* a, const float* b, int64_t n) {
  constexpr int kLanes = 8;
  float lanes[kLanes] = {};
  int64_t j = 0;
  for (; j + kLanes <= n; j += kLanes)
    for (int l = 0; l < kLanes; ++l) lanes[l] += a[j + l] * b[j + l];
  float sum = 0;
  for (; j < n; ++j) sum += a[j] * b[j];
  for (int l = 0; l < kLanes; ++l) sum += lanes[l];
  return sum;
}

void forward_kernel(const float* z, const float* alpha, const Rows& r, int64_t P, float* out) {
  const int64_t K = r.K, M = r.M;
  const float* lift = r.row(K);
  const float* bg = r.row(K + 1);
  core::parallel_for(0, P, 256, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      float* o = out + p * M;
      const float a = alpha[p];
      for (int64_t j = 0; j < M; ++j) o[j] = bg[j] + a * lift[j];
      for (int64_t k = 0; k < K; ++k) {
        const float zk = z[p * K + k];
        const float* b = r.row(k);
        for (int64_t j = 0; j < M; ++j) o[j] += zk * b[j];
      }
    }
  });
}

class DecodeFunction : public torch::autograd::Function<DecodeFunction> {
 public:
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& latent,
                               const torch::Tensor& alpha, const torch::Tensor& basis,
                               const torch::Tensor& mean, const torch::Tensor& background) {
    core::StageScope stage("decode forward");
    ctx->save_for_backward({latent, alpha, basis, mean, background});
    const Rows r = rows_of(basis, mean, background);
    const int64_t P = latent.size(0);
    auto out = core::pooled_empty({P, r.M});
    forward_kernel(latent.data_ptr<float>(), alpha.data_ptr<float>(), r, P, out.data_ptr<float>());
    return out;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grad_outputs) {
    core::StageScope stage("decode backward");
    const auto saved = ctx->get_saved_variables();
    const auto &latent = saved[0], &alpha = saved[1], &basis = saved[2], &mean = saved[3],
               &background = saved[4];
    const torch::Tensor grad = grad_outputs[0].to(torch::kFloat32).contiguous();  // [P, M]
    const Rows r = rows_of(basis, mean, background);
    const int64_t P = latent.size(0), K = r.K, M = r.M;
    const int64_t chunks = (P + kChunk - 1) / kChunk;
    auto d_latent = core::pooled_empty({P, K});
    auto d_alpha = torch::empty({P});
    // Per chunk: sum_p g[p, j] z[p, k] (K rows), sum_p g alpha, sum_p g.
    auto partials = torch::zeros({chunks, K + 2, M});
    const float* g = grad.data_ptr<float>();
    const float* z = latent.data_ptr<float>();
    const float* a = alpha.data_ptr<float>();
    float* dz = d_latent.data_ptr<float>();
    float* da = d_alpha.data_ptr<float>();
    float* part = partials.data_ptr<float>();
    core::parallel_for(0, chunks, 1, [&](int64_t chunk_begin, int64_t chunk_end) {
      for (int64_t chunk = chunk_begin; chunk < chunk_end; ++chunk) {
        float* acc = part + chunk * (K + 2) * M;
        const int64_t p_end = std::min(P, (chunk + 1) * kChunk);
        for (int64_t p = chunk * kChunk; p < p_end; ++p) {
          const float* gp = g + p * M;
          for (int64_t k = 0; k <= K; ++k) {  // k == K: the alpha row (m - bg)
            (k < K ? dz[p * K + k] : da[p]) = dot(gp, r.row(k), M);
          }
          for (int64_t k = 0; k < K; ++k) {
            const float zk = z[p * K + k];
            float* row = acc + k * M;
            for (int64_t j = 0; j < M; ++j) row[j] += zk * gp[j];
          }
          float* row_alpha = acc + K * M;
          float* row_all = acc + (K + 1) * M;
          const float ap = a[p];
          for (int64_t j = 0; j < M; ++j) {
            row_alpha[j] += ap * gp[j];
            row_all[j] += gp[j];
          }
        }
      }
    });
    // Summed in double, chunk by chunk in order.
    const torch::Tensor sums = partials.to(torch::kFloat64).sum(0);  // [K + 2, M]
    const auto dtype = basis.scalar_type();
    const torch::Tensor d_basis = sums.slice(0, 0, K).t().to(dtype).contiguous();
    // out = ... + alpha m + (1 - alpha) bg.
    const torch::Tensor d_mean = sums[K].to(dtype);
    const torch::Tensor d_background = (sums[K + 1] - sums[K]).to(dtype);
    return {d_latent, d_alpha, d_basis, d_mean, d_background};
  }
};

}  // namespace

torch::Tensor decode_latent(const torch::Tensor& latent, const torch::Tensor& alpha,
                            const torch::Tensor& basis, const torch::Tensor& mean,
                            const torch::Tensor& background) {
  core::require(latent.dim() == 2 && basis.dim() == 2 && basis.size(1) == latent.size(1) &&
                    alpha.numel() == latent.size(0) && mean.numel() == basis.size(0) &&
                    background.numel() == basis.size(0),
                "decode_latent: expected latent [P, K], alpha [P], basis [M, K], mean and "
                "background [M]");
  return DecodeFunction::apply(latent.to(torch::kFloat32).contiguous(),
                               alpha.reshape({-1}).to(torch::kFloat32).contiguous(), basis,
                               mean.reshape({-1}), background.reshape({-1}));
}

}  // namespace ddhgs::render
