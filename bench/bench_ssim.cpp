// The fused L1 + SSIM pass (model/ssim_fused.h) against the LibTorch terms it
// replaced (model::ssim and (a - b).abs().mean() with autograd), value and
// gradient w.r.t. the render, at the image sizes and band counts of training.
//
//   build/bench/bench_ssim [--quick]
//   build/bench/bench_ssim --kernel W H N [REPS]   # the fused kernel alone
//
// Per case: median wall milliseconds of forward + backward for both, their
// ratio, and the fused pass's throughput in pixel-bands per second. With
// --kernel, only model/ssim_kernel.h's pass (value and gradient, no autograd,
// no copies) on one W x H x N image, REPS times (default 9): the figure to
// compare two builds of the kernel by, since the LibTorch twin between the
// fused runs evicts the caches. Threads: $DDHGS_THREADS, else every core.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "bench_timing.h"
#include "core/early_setup.h"
#include "core/threads.h"
#include "model/ssim.h"
#include "model/ssim_fused.h"
#include "model/ssim_kernel.h"

namespace {

using namespace ddhgs;

using bench::median_ms;

void run_case(int64_t w, int64_t h, int64_t n, int reps) {
  torch::manual_seed(n);
  const auto target = torch::rand({h, w, n});
  const auto render = (target + 0.1 * torch::randn({h, w, n})).clamp(0, 1);
  auto fused = [&] {
    auto x = render.clone().requires_grad_(true);
    auto v = model::l1_and_ssim(x, target);
    (0.8 * v.l1 + 0.2 * (1 - v.ssim)).backward();
  };
  auto libtorch = [&] {
    auto x = render.clone().requires_grad_(true);
    (0.8 * (x - target).abs().mean() + 0.2 * (1 - model::ssim(x, target))).backward();
  };
  const double fused_ms = median_ms(reps, fused);
  const double libtorch_ms = median_ms(std::max(1, reps / 2), libtorch);
  std::printf("| %lldx%lld | %lld | %.1f | %.1f | %.1fx | %.0f |\n", (long long)w, (long long)h,
              (long long)n, fused_ms, libtorch_ms, libtorch_ms / fused_ms,
              double(w * h * n) / (fused_ms * 1e-3) / 1e6);
  std::fflush(stdout);
}

void run_kernel(int64_t w, int64_t h, int64_t n, int reps) {
  torch::manual_seed(n);
  const auto target = torch::rand({h, w, n});
  const auto render = (target + 0.1 * torch::randn({h, w, n})).clamp(0, 1).contiguous();
  auto grad = torch::empty({h, w, n});
  const model::ssim_kernel::Images images{render.data_ptr<float>(), target.data_ptr<float>(), h, w,
                                          n};
  const double ms =
      median_ms(reps, [&] { model::ssim_kernel::run(images, grad.data_ptr<float>()); });
  std::printf("kernel %lldx%lldx%lld: %.1f ms (median of %d), %.0f Mpixel-bands/s\n", (long long)w,
              (long long)h, (long long)n, ms, reps, double(w * h * n) / (ms * 1e-3) / 1e6);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 5 && !std::strcmp(argv[1], "--kernel")) {
    core::configure_threads(0);
    run_kernel(std::atoll(argv[2]), std::atoll(argv[3]), std::atoll(argv[4]),
               argc > 5 ? std::atoi(argv[5]) : 9);
    return 0;
  }
  const bool quick = argc > 1 && !std::strcmp(argv[1], "--quick");
  const int threads = core::configure_threads(0);
  std::printf("threads %d; forward + backward of 0.8 L1 + 0.2 (1 - SSIM), median ms\n\n", threads);
  std::printf("| image | N | fused ms | LibTorch ms | speed-up | fused Mpixel-bands/s |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (int64_t n : {3, 40, 128, 141}) run_case(160, 128, n, quick ? 3 : 9);
  for (int64_t n : {3, 141}) run_case(640, 512, n, quick ? 1 : 3);
  return 0;
}
