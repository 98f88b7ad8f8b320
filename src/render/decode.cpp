#include "render/decode.h"

#include <cstring>
#include <vector>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/float_vec.h"
#include "core/parallel.h"
#include "core/stage_timer.h"

namespace ddhgs::render {
namespace {

// Pixels per reduction chunk: the partial sums depend on it, not on threads.
constexpr int64_t kDecodeChunk = 2048;

// A vector of kLanes bands (GCC vector extension): one AVX-512 register where
// the build has it, one AVX2 register otherwise.
#if defined(__AVX512F__)
constexpr int64_t kLanes = 16;
#else
constexpr int64_t kLanes = 8;
#endif
using Vec = core::FloatVec<kLanes>::type;

inline Vec load(const float* p) {
  return core::load_vec<Vec>(p);
}

inline void store(float* p, const Vec& v) {
  core::store_vec(p, v);
}

// Bands j .. j + kLanes - 1 of a row of M: past the row's end (its last
// vector) zero, without reading beyond it.
inline Vec load_bands(const float* row, int64_t j, int64_t M) {
  if (j + kLanes <= M) return load(row + j);
  Vec v = {};
  std::memcpy(&v, row + j, size_t(M - j) * sizeof(float));
  return v;
}

// The sum of v's lanes, in a fixed order.
inline float lane_sum(const Vec& v) {
  float sum = 0;
  for (int64_t l = 0; l < kLanes; ++l) sum += v[l];
  return sum;
}

// Rows the kernels read: the basis transposed ([K, M], one contiguous row
// per channel), then m - bg and bg, each padded with zeros to a whole
// number of vectors (stride S).
struct Rows {
  torch::Tensor table;          // [K + 2, S] float32 contiguous
  const float* data = nullptr;  // table's
  int64_t K = 0, M = 0, S = 0;
  const float* row(int64_t r) const { return data + r * S; }
};

Rows rows_of(const torch::Tensor& basis, const torch::Tensor& mean,
             const torch::Tensor& background) {
  Rows r;
  r.K = basis.size(1), r.M = basis.size(0);
  r.S = (r.M + kLanes - 1) / kLanes * kLanes;
  r.table = torch::zeros({r.K + 2, r.S}, torch::kFloat32);
  r.table.narrow(1, 0, r.M).copy_(
      torch::cat({basis.t(), (mean - background).unsqueeze(0), background.unsqueeze(0)}, 0));
  r.data = r.table.data_ptr<float>();
  return r;
}

// out[p] = bg + alpha[p] (m - bg) + sum_k z[p, k] B[:, k], a vector of bands
// at a time, each summed in a register.
void forward_kernel(const float* z, const float* alpha, const Rows& r, int64_t P, float* out) {
  const int64_t K = r.K, M = r.M;
  const float* lift = r.row(K);
  const float* bg = r.row(K + 1);
  core::parallel_for(0, P, 256, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      float* o = out + p * M;
      const float a = alpha[p];
      const float* zp = z + p * K;
      for (int64_t j = 0; j < M; j += kLanes) {
        Vec v = load(bg + j) + a * load(lift + j);
        for (int64_t k = 0; k < K; ++k) v += zp[k] * load(r.row(k) + j);
        if (j + kLanes <= M) {
          store(o + j, v);
        } else {
          for (int64_t l = 0; l < M - j; ++l) o[j + l] = v[l];
        }
      }
    }
  });
}

// One chunk of the backward for kK latent channels (a compile-time count, so
// the kK + 1 dot products stay in registers): per pixel, a vector of the
// gradient's bands at a time serves both the products with the basis rows
// and m - bg (dz, dalpha) and the chunk's sums g z, g alpha and g (acc:
// [kK + 2, S]).
template <int64_t kK>
void backward_chunk(const float* g, const float* z, const float* a, const Rows& r, int64_t p0,
                    int64_t p1, float* dz, float* da, float* acc) {
  const int64_t M = r.M, S = r.S;
  for (int64_t p = p0; p < p1; ++p) {
    const float* gp = g + p * M;
    const float* zp = z + p * kK;
    Vec dot[kK + 1] = {};
    for (int64_t j = 0; j < M; j += kLanes) {
      const Vec gv = load_bands(gp, j, M);
      for (int64_t k = 0; k <= kK; ++k) dot[k] += gv * load(r.row(k) + j);
      for (int64_t k = 0; k < kK; ++k) {
        float* row = acc + k * S + j;
        store(row, load(row) + zp[k] * gv);
      }
      float* row_alpha = acc + kK * S + j;
      float* row_all = acc + (kK + 1) * S + j;
      store(row_alpha, load(row_alpha) + a[p] * gv);
      store(row_all, load(row_all) + gv);
    }
    for (int64_t k = 0; k < kK; ++k) dz[p * kK + k] = lane_sum(dot[k]);
    da[p] = lane_sum(dot[kK]);
  }
}

// The same for any number of latent channels, one basis row at a time.
void backward_chunk_any(const float* g, const float* z, const float* a, const Rows& r, int64_t p0,
                        int64_t p1, float* dz, float* da, float* acc) {
  const int64_t K = r.K, M = r.M, S = r.S;
  for (int64_t p = p0; p < p1; ++p) {
    const float* gp = g + p * M;
    for (int64_t k = 0; k <= K; ++k) {  // k == K: the alpha row (m - bg)
      Vec dot = {};
      for (int64_t j = 0; j < M; j += kLanes) dot += load_bands(gp, j, M) * load(r.row(k) + j);
      (k < K ? dz[p * K + k] : da[p]) = lane_sum(dot);
    }
    for (int64_t k = 0; k <= K + 1; ++k) {
      const float w = k < K ? z[p * K + k] : k == K ? a[p] : 1.0f;
      float* row = acc + k * S;
      for (int64_t j = 0; j < M; ++j) row[j] += w * gp[j];
    }
  }
}

// backward_chunk for K latent channels: compiled for kK = 1 .. 8, any other
// count one row at a time.
template <int64_t kK = 1>
void backward_chunk_for(int64_t K, const float* g, const float* z, const float* a, const Rows& r,
                        int64_t p0, int64_t p1, float* dz, float* da, float* acc) {
  if constexpr (kK <= 8) {
    if (K == kK) return backward_chunk<kK>(g, z, a, r, p0, p1, dz, da, acc);
    return backward_chunk_for<kK + 1>(K, g, z, a, r, p0, p1, dz, da, acc);
  } else {
    return backward_chunk_any(g, z, a, r, p0, p1, dz, da, acc);
  }
}

void backward_kernel(const float* g, const float* z, const float* a, const Rows& r, int64_t P,
                     float* dz, float* da, float* partials) {
  const int64_t chunks = (P + kDecodeChunk - 1) / kDecodeChunk;
  const int64_t K = r.K, S = r.S;
  core::parallel_for(0, chunks, 1, [&](int64_t chunk_begin, int64_t chunk_end) {
    for (int64_t chunk = chunk_begin; chunk < chunk_end; ++chunk) {
      const int64_t p0 = chunk * kDecodeChunk, p1 = std::min(P, p0 + kDecodeChunk);
      backward_chunk_for(K, g, z, a, r, p0, p1, dz, da, partials + chunk * (K + 2) * S);
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
    const int64_t chunks = (P + kDecodeChunk - 1) / kDecodeChunk;
    auto d_latent = core::pooled_empty({P, K});
    auto d_alpha = torch::empty({P});
    // Per chunk: sum_p g[p, j] z[p, k] (K rows), sum_p g alpha, sum_p g.
    auto partials = torch::zeros({chunks, K + 2, r.S});
    backward_kernel(grad.data_ptr<float>(), latent.data_ptr<float>(), alpha.data_ptr<float>(), r, P,
                    d_latent.data_ptr<float>(), d_alpha.data_ptr<float>(),
                    partials.data_ptr<float>());
    // Summed in double, chunk by chunk in order.
    const torch::Tensor sums = partials.narrow(2, 0, M).to(torch::kFloat64).sum(0);  // [K + 2, M]
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
