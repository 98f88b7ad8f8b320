// Fast per-band SH evaluation (forward and exact backward) as an autograd
// Function. Parallel over Gaussians; per Gaussian the basis is computed once
// and reused for every band.
#include "render/sh.h"

#include <type_traits>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/stage_timer.h"
#include "render/rasterize.h"

namespace ddhgs::render {
namespace {

// Fixed-size Gaussian chunks make the band_offsets gradient reduction
// independent of the thread count: per-chunk partial sums are added in order.
constexpr int64_t kShChunk = 1024;

struct ShShapes {
  int64_t G = 0, N = 0;
  int64_t rest_stride = 0;    // stored rest coefficients per band (>= K - 1)
  int64_t offset_stride = 0;  // stored offsets per band (>= K), 0 without offsets
  bool linear = false;        // latent channels: no +0.5 and no clamp at 0
};

// Pointers into contiguous inputs of one dtype.
template <typename T>
struct ShInputs {
  const T* dc;       // [G, N]
  const T* rest;     // [G, N, rest_stride] or null
  const T* means;    // [G, 3]
  const T* center;   // [3]
  const T* offsets;  // [N, offset_stride] or null
};

// Unit direction from the camera centre to the Gaussian and the distance; a
// Gaussian exactly at the centre gets direction 0 (only the DC term then).
template <typename T>
inline T view_direction(const T* mean, const T* center, T dir[3]) {
  const T d[3] = {mean[0] - center[0], mean[1] - center[1], mean[2] - center[2]};
  const T length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const T inv = length > T(0) ? T(1) / length : T(0);
  for (int a = 0; a < 3; ++a) dir[a] = d[a] * inv;
  return length;
}

// sum_k c[n, k] Y[k] + 0.5 (+ 0 when linear) for one Gaussian and band,
// offsets included.
template <int K, typename T>
inline T band_value(const ShInputs<T>& in, const ShShapes& s, int64_t g, int64_t n, const T* Y) {
  T v = in.dc[g * s.N + n] * Y[0] + (s.linear ? T(0) : T(0.5));
  if constexpr (K > 1) {
    const T* rest = in.rest + (g * s.N + n) * s.rest_stride;
    for (int k = 1; k < K; ++k) v += rest[k - 1] * Y[k];
  }
  if (in.offsets) {
    const T* offset = in.offsets + n * s.offset_stride;
    for (int k = 0; k < K; ++k) v += offset[k] * Y[k];
  }
  return v;
}

template <int Degree, typename T>
void forward_kernel(const ShInputs<T>& in, const ShShapes& s, T* out) {
  constexpr int K = sh_coeff_count(Degree);
  core::parallel_for(0, s.G, 64, [&](int64_t begin, int64_t end) {
    for (int64_t g = begin; g < end; ++g) {
      T dir[3], Y[16];
      view_direction(in.means + 3 * g, in.center, dir);
      sh_basis<Degree>(dir[0], dir[1], dir[2], Y);
      if (s.linear)
        for (int64_t n = 0; n < s.N; ++n) out[g * s.N + n] = band_value<K>(in, s, g, n, Y);
      else
        for (int64_t n = 0; n < s.N; ++n)
          out[g * s.N + n] = std::max(band_value<K>(in, s, g, n, Y), T(0));
    }
  });
}

// Gradient outputs; a null pointer means that input needs no gradient.
template <typename T>
struct ShGrads {
  T* dc = nullptr;       // [G, N]
  T* rest = nullptr;     // [G, N, rest_stride], every entry written
  T* means = nullptr;    // [G, 3]
  T* offsets = nullptr;  // [chunks, N, K] per-chunk partial sums, zero-initialised
  // Instead of rest: receives the rest gradient in blocks of kSinkRows
  // Gaussians (float32 only), after their other gradients are computed.
  const ShRestSink* rest_sink = nullptr;
};

// Gaussians per block handed to a rest sink: the block's gradient, about
// 270 KB at 141 bands, is still in cache when the sink reads it.
constexpr int64_t kSinkRows = 32;

template <typename T>
std::vector<T>& sink_block() {
  thread_local std::vector<T> block;
  return block;
}

template <int Degree, typename T>
void backward_gaussian(const ShInputs<T>& in, const ShShapes& s, const T* grad_out,
                       const ShGrads<T>& gr, int64_t g, T* rest_grad, T* offsets_partial) {
  constexpr int K = sh_coeff_count(Degree);
  T dir[3], Y[16], dY[16][3];
  const T length = view_direction(in.means + 3 * g, in.center, dir);
  sh_basis<Degree>(dir[0], dir[1], dir[2], Y, dY);
  // dL/dY[k] summed over bands, for the direction gradient.
  T dL_dY[16] = {};
  for (int64_t n = 0; n < s.N; ++n) {
    // Matches clamp_min's convention: the gradient passes at exactly 0.
    const bool clamped = !s.linear && band_value<K>(in, s, g, n, Y) < T(0);
    const T gv = clamped ? T(0) : grad_out[g * s.N + n];
    if (gr.dc) gr.dc[g * s.N + n] = gv * Y[0];
    if (rest_grad) {
      // Every entry is written (the buffer is reused, not zeroed):
      // coefficients above the degree get zero.
      T* row = rest_grad + n * s.rest_stride;
      int64_t k = 1;
      if (gv != T(0))
        for (; k < K; ++k) row[k - 1] = gv * Y[k];
      std::fill(row + k - 1, row + s.rest_stride, T(0));
    }
    if (gv == T(0)) continue;
    if (offsets_partial) {
      T* partial = offsets_partial + n * K;
      for (int k = 0; k < K; ++k) partial[k] += gv * Y[k];
    }
    if (gr.means && K > 1) {
      const T* rest = in.rest + (g * s.N + n) * s.rest_stride;
      const T* offset = in.offsets ? in.offsets + n * s.offset_stride : nullptr;
      for (int k = 1; k < K; ++k) dL_dY[k] += gv * (rest[k - 1] + (offset ? offset[k] : T(0)));
    }
  }
  if (!gr.means) return;
  T dL_ddir[3] = {0, 0, 0};
  for (int k = 1; k < K; ++k)
    for (int a = 0; a < 3; ++a) dL_ddir[a] += dL_dY[k] * dY[k][a];
  // d(d/|d|)/dd = (I - dir dir^T) / |d|.
  const T along = dL_ddir[0] * dir[0] + dL_ddir[1] * dir[1] + dL_ddir[2] * dir[2];
  const T inv = length > T(0) ? T(1) / length : T(0);
  for (int a = 0; a < 3; ++a) gr.means[3 * g + a] = (dL_ddir[a] - along * dir[a]) * inv;
}

template <int Degree, typename T>
void backward_kernel(const ShInputs<T>& in, const ShShapes& s, const T* grad_out,
                     const ShGrads<T>& gr) {
  const int64_t chunks = (s.G + kShChunk - 1) / kShChunk;
  const int64_t row = s.N * s.rest_stride;  // rest gradient floats per Gaussian
  core::parallel_for(0, chunks, 1, [&](int64_t chunk_begin, int64_t chunk_end) {
    std::vector<T>& block = sink_block<T>();
    if (gr.rest_sink) block.resize(size_t(kSinkRows * row));
    for (int64_t chunk = chunk_begin; chunk < chunk_end; ++chunk) {
      T* offsets_partial = gr.offsets ? gr.offsets + chunk * s.N * sh_coeff_count(Degree) : nullptr;
      const int64_t g_end = std::min(s.G, (chunk + 1) * kShChunk);
      for (int64_t first = chunk * kShChunk; first < g_end; first += kSinkRows) {
        const int64_t last = std::min(g_end, first + kSinkRows);
        for (int64_t g = first; g < last; ++g) {
          T* rest_grad = gr.rest_sink ? block.data() + (g - first) * row
                         : gr.rest    ? gr.rest + g * row
                                      : nullptr;
          backward_gaussian<Degree>(in, s, grad_out, gr, g, rest_grad, offsets_partial);
        }
        if constexpr (std::is_same_v<T, float>)
          if (gr.rest_sink) (*gr.rest_sink)(first, last - first, block.data());
      }
    }
  });
}

template <typename F>
void dispatch_degree(int degree, F&& f) {
  switch (degree) {
    case 0:
      return f(std::integral_constant<int, 0>{});
    case 1:
      return f(std::integral_constant<int, 1>{});
    case 2:
      return f(std::integral_constant<int, 2>{});
    default:
      return f(std::integral_constant<int, 3>{});
  }
}

template <typename T>
ShInputs<T> inputs_of(const torch::Tensor& dc, const torch::Tensor& rest,
                      const torch::Tensor& means, const torch::Tensor& center,
                      const torch::Tensor& offsets) {
  return {dc.data_ptr<T>(), rest.numel() ? rest.data_ptr<T>() : nullptr, means.data_ptr<T>(),
          center.data_ptr<T>(), offsets.numel() ? offsets.data_ptr<T>() : nullptr};
}

ShShapes shapes_of(const torch::Tensor& dc, const torch::Tensor& rest, const torch::Tensor& offsets,
                   bool linear) {
  return {dc.size(0), dc.size(1), rest.size(2), offsets.numel() ? offsets.size(1) : 0, linear};
}

// Carries a rest sink from the forward to the backward in saved_data.
struct SinkHolder : torch::CustomClassHolder {
  explicit SinkHolder(ShRestSink s) : sink(std::move(s)) {}
  ShRestSink sink;
};

class EvalShFunction : public torch::autograd::Function<EvalShFunction> {
 public:
  // Inputs are contiguous, of one floating dtype; rest is [G, N, R] (R may be
  // 0) and offsets [N, KO] (empty when absent).
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& dc,
                               const torch::Tensor& rest, const torch::Tensor& means,
                               const torch::Tensor& center, const torch::Tensor& offsets,
                               int degree, const ShRestSink& rest_sink, bool linear) {
    core::StageScope stage("sh forward");
    ctx->save_for_backward({dc, rest, means, center, offsets});
    ctx->saved_data["degree"] = degree;
    ctx->saved_data["linear"] = linear;
    if (rest_sink)
      ctx->saved_data["rest_sink"] =
          c10::IValue::make_capsule(c10::make_intrusive<SinkHolder>(rest_sink));
    // Pooled: the colours and the SH gradients are allocated every iteration.
    auto out = core::pooled_empty(dc.sizes(), dc.scalar_type());
    const ShShapes shapes = shapes_of(dc, rest, offsets, linear);
    AT_DISPATCH_FLOATING_TYPES(dc.scalar_type(), "eval_sh_forward", [&] {
      const auto in = inputs_of<scalar_t>(dc, rest, means, center, offsets);
      dispatch_degree(degree, [&](auto deg) {
        forward_kernel<decltype(deg)::value>(in, shapes, out.data_ptr<scalar_t>());
      });
    });
    return out;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grad_outputs) {
    core::StageScope stage("sh backward");
    const auto saved = ctx->get_saved_variables();
    const auto &dc = saved[0], &rest = saved[1], &means = saved[2], &center = saved[3],
               &offsets = saved[4];
    const int degree = int(ctx->saved_data["degree"].toInt());
    const int64_t K = sh_coeff_count(degree);
    const auto grad_out = grad_outputs[0].contiguous();
    const ShShapes shapes = shapes_of(dc, rest, offsets, ctx->saved_data["linear"].toBool());
    const bool want_means = ctx->needs_input_grad(2) || ctx->needs_input_grad(3);
    const bool want_offsets = ctx->needs_input_grad(4) && offsets.numel() > 0;
    torch::Tensor d_dc = ctx->needs_input_grad(0) ? core::pooled_empty(dc.sizes(), dc.scalar_type())
                                                  : torch::Tensor();
    c10::intrusive_ptr<SinkHolder> sink;
    if (ctx->needs_input_grad(1) && ctx->saved_data.count("rest_sink"))
      sink =
          c10::static_intrusive_pointer_cast<SinkHolder>(ctx->saved_data["rest_sink"].toCapsule());
    torch::Tensor d_rest = ctx->needs_input_grad(1) && !sink
                               ? core::pooled_empty(rest.sizes(), rest.scalar_type())
                               : torch::Tensor();
    torch::Tensor d_means = want_means ? torch::empty_like(means) : torch::Tensor();
    const int64_t chunks = (shapes.G + kShChunk - 1) / kShChunk;
    torch::Tensor partials =
        want_offsets ? torch::zeros({chunks, shapes.N, K}, dc.options()) : torch::Tensor();
    AT_DISPATCH_FLOATING_TYPES(dc.scalar_type(), "eval_sh_backward", [&] {
      const auto in = inputs_of<scalar_t>(dc, rest, means, center, offsets);
      ShGrads<scalar_t> grads;
      if (d_dc.defined()) grads.dc = d_dc.data_ptr<scalar_t>();
      if (d_rest.defined() && d_rest.numel()) grads.rest = d_rest.data_ptr<scalar_t>();
      if (d_means.defined()) grads.means = d_means.data_ptr<scalar_t>();
      if (partials.defined()) grads.offsets = partials.data_ptr<scalar_t>();
      if (sink && rest.numel()) grads.rest_sink = &sink->sink;
      dispatch_degree(degree, [&](auto deg) {
        backward_kernel<decltype(deg)::value>(in, shapes, grad_out.data_ptr<scalar_t>(), grads);
      });
    });
    torch::Tensor d_offsets;
    if (want_offsets) {
      d_offsets = torch::zeros_like(offsets);
      // Summed in double, chunk by chunk in order: same bits for any thread count.
      d_offsets.slice(1, 0, K).copy_(partials.to(torch::kFloat64).sum(0));
    }
    torch::Tensor d_center;
    if (ctx->needs_input_grad(3)) d_center = -d_means.sum(0);
    if (!ctx->needs_input_grad(2)) d_means = torch::Tensor();
    return {d_dc,      d_rest,          d_means,         d_center,
            d_offsets, torch::Tensor(), torch::Tensor(), torch::Tensor()};
  }
};

void check_shapes(const torch::Tensor& sh_dc, const torch::Tensor& sh_rest,
                  const torch::Tensor& means, const torch::Tensor& camera_center, int degree,
                  const torch::Tensor& band_offsets) {
  using core::require;
  require(degree >= 0 && degree <= kMaxShDegree,
          "eval_sh: SH degree must be 0-3, got " + std::to_string(degree));
  require(sh_dc.defined() && sh_dc.dim() == 2 && sh_dc.size(1) >= 1,
          "eval_sh: sh_dc must be [G, N] with N >= 1");
  const int64_t G = sh_dc.size(0), N = sh_dc.size(1), K = sh_coeff_count(degree);
  const auto dtype = sh_dc.scalar_type();
  require(dtype == torch::kFloat32 || dtype == torch::kFloat64,
          "eval_sh: coefficients must be float32 or float64");
  auto same_kind = [&](const torch::Tensor& t) {
    return t.scalar_type() == dtype && t.device().is_cpu();
  };
  require(sh_dc.device().is_cpu(), "eval_sh: tensors must be on the CPU");
  require(means.defined() && means.dim() == 2 && means.size(0) == G && means.size(1) == 3 &&
              same_kind(means),
          "eval_sh: means must be [G, 3] with G = " + std::to_string(G) + " and sh_dc's dtype");
  require(camera_center.defined() && camera_center.numel() == 3 && same_kind(camera_center),
          "eval_sh: camera_center must have 3 elements of sh_dc's dtype");
  require(K == 1 || sh_rest.defined(),
          "eval_sh: degree " + std::to_string(degree) + " needs sh_rest");
  if (sh_rest.defined()) {
    require(sh_rest.dim() == 3 && sh_rest.size(0) == G && sh_rest.size(1) == N &&
                sh_rest.size(2) >= K - 1 && same_kind(sh_rest),
            "eval_sh: sh_rest must be [G, N, >= " + std::to_string(K - 1) + "] for degree " +
                std::to_string(degree) + " with G = " + std::to_string(G) +
                ", N = " + std::to_string(N));
  }
  if (band_offsets.defined()) {
    require(band_offsets.dim() == 2 && band_offsets.size(0) == N && band_offsets.size(1) >= K &&
                same_kind(band_offsets),
            "eval_sh: band_offsets must be [N, >= " + std::to_string(K) +
                "] with N = " + std::to_string(N));
  }
}

}  // namespace

torch::Tensor eval_sh(const torch::Tensor& sh_dc, const torch::Tensor& sh_rest,
                      const torch::Tensor& means, const torch::Tensor& camera_center, int degree,
                      const torch::Tensor& band_offsets, const ShRestSink& rest_sink, bool linear) {
  check_shapes(sh_dc, sh_rest, means, camera_center, degree, band_offsets);
  core::require(!rest_sink || (sh_rest.defined() && sh_rest.scalar_type() == torch::kFloat32 &&
                               sh_rest.is_contiguous()),
                "eval_sh: a rest sink needs a contiguous float32 sh_rest");
  const int64_t G = sh_dc.size(0), N = sh_dc.size(1);
  // Absent inputs become empty tensors so the autograd Function always sees
  // the same five tensor arguments.
  auto rest = sh_rest.defined() ? sh_rest.contiguous() : torch::zeros({G, N, 0}, sh_dc.options());
  auto offsets =
      band_offsets.defined() ? band_offsets.contiguous() : torch::zeros({N, 0}, sh_dc.options());
  return EvalShFunction::apply(sh_dc.contiguous(), rest, means.contiguous(),
                               camera_center.reshape({3}).contiguous(), offsets, degree, rest_sink,
                               linear);
}

}  // namespace ddhgs::render
