// Per-band SH evaluation (render::eval_sh) against the dense LibTorch
// reference on fixed, seeded random inputs, both in float32 with autograd.
//
//   build/bench/bench_sh [--quick]
//
// Per case: forward and forward+backward milliseconds (median of several
// runs) for the fast path and the reference, the speed-up, and the fast
// path's coefficient throughput (G x N x K coefficients read per second in
// forward+backward). Backward produces gradients for every input, including
// the wavelength encoder's band offsets and the means.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <vector>

#include "bench_timing.h"
#include "core/early_setup.h"
#include "core/threads.h"
#include "render/rasterize.h"
#include "render/sh.h"
#include "render/sh_reference.h"

namespace {

using namespace ddhgs;

struct Inputs {
  torch::Tensor dc, rest, means, center, offsets;
};

Inputs make_inputs(int64_t G, int64_t N) {
  torch::manual_seed(G + N);
  auto leaf = [](torch::Tensor t) { return t.requires_grad_(true); };
  return {leaf(torch::randn({G, N})), leaf(torch::randn({G, N, 15}) * 0.2),
          leaf(torch::randn({G, 3})), torch::tensor({0.f, 0.f, -5.f}),
          leaf(torch::randn({N, 16}) * 0.01)};
}

using bench::median_ms;

// Callables, not function pointers: eval_sh has a trailing defaulted argument.
const auto fast_sh = [](const auto&... args) { return render::eval_sh(args...); };
const auto reference_sh = [](const auto&... args) { return render::eval_sh_reference(args...); };

void run_case(int64_t G, int64_t N, int degree, int reps) {
  Inputs in = make_inputs(G, N);
  auto forward = [&](const auto& fn) {
    torch::NoGradGuard no_grad;
    return fn(in.dc, in.rest, in.means, in.center, degree, in.offsets);
  };
  auto forward_backward = [&](const auto& fn) {
    auto out = fn(in.dc, in.rest, in.means, in.center, degree, in.offsets);
    auto grads = torch::autograd::grad({out.sum()}, {in.dc, in.rest, in.means, in.offsets}, {},
                                       false, false, true);
    return grads[0];
  };
  const double fast_fwd = median_ms(reps, [&] { forward(fast_sh); });
  const double fast_both = median_ms(reps, [&] { forward_backward(fast_sh); });
  const double ref_fwd = median_ms(reps, [&] { forward(reference_sh); });
  const double ref_both = median_ms(reps, [&] { forward_backward(reference_sh); });
  const double coefficients = double(G) * double(N) * render::sh_coeff_count(degree);
  std::printf("%7lld %4lld %3d | %9.2f %9.2f | %9.2f %9.2f | %6.1fx %6.1fx | %8.2f\n", (long long)G,
              (long long)N, degree, fast_fwd, fast_both, ref_fwd, ref_both, ref_fwd / fast_fwd,
              ref_both / fast_both, 2 * coefficients / (fast_both * 1e-3) / 1e9);
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const int threads = core::configure_threads();
  std::printf("eval_sh, float32, %d threads; times in ms (median of %d)\n", threads, quick ? 3 : 7);
  std::printf("%7s %4s %3s | %9s %9s | %9s %9s | %7s %7s | %8s\n", "G", "N", "deg", "fast fwd",
              "fast f+b", "ref fwd", "ref f+b", "fwd x", "f+b x", "Gcoef/s");
  const std::vector<int64_t> gaussians =
      quick ? std::vector<int64_t>{10000} : std::vector<int64_t>{10000, 100000};
  for (int64_t G : gaussians)
    for (int64_t N : {3, 32, 128})
      for (int degree : {0, 3}) run_case(G, N, degree, quick ? 3 : 7);
  return 0;
}
