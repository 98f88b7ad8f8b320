// Rasterizer throughput on fixed, seeded random scenes, compared with this
// machine's single-precision matrix-multiply peak measured in the same run.
//
//   build/bench/bench_rasterizer [--quick | --only WIDTH HEIGHT G N]
//
// With DDHGS_BENCH_STAGES=1 it also prints CPU milliseconds of the forward's
// stages (projection, binning, blending) next to the whole forward. With
// DDHGS_BENCH_NARROW=1 the blender uses its 256-bit loops even where it was
// built with 512-bit ones (render::set_wide_kernels), to measure the AVX2 path.
//
// Per scene: forward and backward milliseconds (median of several runs, with
// autograd, as training uses them), Gaussian-pixel pairs blended per second,
// blend GFLOP/s and its fraction of the torch::mm peak, and peak RSS. The
// fractions are given per wall second and per CPU second (the latter is the
// honest one when other jobs share the cores).
// Flop counts: forward 2 per band per blended pair (one multiply-add into the
// pixel), backward 4 per band per pair (dL/dweight = colour . dL/dpixel and
// dL/dcolour += weight * dL/dpixel). Scalar work (exp, transmittance) is
// not counted.
#include <sys/resource.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "core/camera.h"
#include "core/early_setup.h"
#include "core/threads.h"
#include "render/blend.h"
#include "render/project.h"
#include "render/rasterize.h"
#include "render/tiles.h"

namespace {

using namespace ddhgs;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// CPU seconds used by all threads of the process: on a shared, oversubscribed
// machine this tracks the work done better than wall time does.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

struct Timing {
  double wall, cpu;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double peak_rss_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux reports KiB
}

// GFLOP/s of a large square float32 torch::mm on all threads, per wall
// second and per CPU second (best of several runs).
Timing mm_peak_gflops() {
  const int64_t n = 2048;
  torch::manual_seed(0);
  const torch::Tensor a = torch::randn({n, n}), b = torch::randn({n, n});
  torch::Tensor c = torch::mm(a, b);  // warm-up
  Timing best{0, 0};
  for (int rep = 0; rep < 5; ++rep) {
    const auto t = Clock::now();
    const double cpu = cpu_seconds();
    c = torch::mm(a, b);
    const double flop = 2.0 * n * n * n / 1e9;
    best.wall = std::max(best.wall, flop / seconds_since(t));
    best.cpu = std::max(best.cpu, flop / (cpu_seconds() - cpu));
  }
  return best;
}

struct Scene {
  torch::Tensor means, log_scales, quats, logit_opacities, colors, background;
  render::RenderCamera camera;
};

// Gaussians uniform in a 2 x 2 x 2 box seen from 4 units away, 0.5-3 % of
// the box wide: a few pixels each at 640 px, like a trained 3DGS scene.
Scene make_scene(int64_t g, int64_t n, int width, int height) {
  torch::manual_seed(1234 + g + n + width);
  Scene s;
  s.means = torch::rand({g, 3}) * 2 - 1;
  s.log_scales = torch::rand({g, 3}) * std::log(6.0) + std::log(0.005);
  s.quats = torch::randn({g, 4});
  s.logit_opacities = torch::randn({g, 1});
  s.colors = torch::rand({g, n});
  s.background = torch::zeros({n});
  core::Camera cam;
  cam.intrinsics = {double(width), double(width), width / 2.0, height / 2.0, width, height};
  cam.world_to_camera = core::look_at({0.5, -0.3, -4.0}, {0, 0, 0}, {0, -1, 0});
  s.camera = render::RenderCamera::from(cam);
  return s;
}

// Blended pairs of one render, through the internal stages (untimed).
int64_t count_pairs(const Scene& s) {
  const render::Projected p =
      render::project_forward(s.means, s.log_scales, s.quats, s.logit_opacities, s.camera);
  render::TileBins bins;
  render::bin_gaussians(p.means2d.data_ptr<float>(), p.conics.data_ptr<float>(),
                        p.opacities.data_ptr<float>(), p.depths.data_ptr<float>(),
                        p.radii.data_ptr<int32_t>(), p.means2d.size(0), s.camera.width,
                        s.camera.height, core::thread_count(), bins);
  return render::blend_forward(p, s.colors, s.background, bins, s.camera.width, s.camera.height,
                               false)
      .pairs;
}

// CPU milliseconds of the forward's stages (median of reps), to see where the
// time outside the blend goes: projection, binning, blending.
void print_stages(const Scene& s, int reps) {
  std::vector<double> project, bin, blend;
  render::TileBins bins;
  for (int rep = 0; rep <= reps; ++rep) {
    double c0 = cpu_seconds();
    const render::Projected p =
        render::project_forward(s.means, s.log_scales, s.quats, s.logit_opacities, s.camera);
    const double c1 = cpu_seconds();
    render::bin_gaussians(p.means2d.data_ptr<float>(), p.conics.data_ptr<float>(),
                          p.opacities.data_ptr<float>(), p.depths.data_ptr<float>(),
                          p.radii.data_ptr<int32_t>(), p.means2d.size(0), s.camera.width,
                          s.camera.height, core::thread_count(), bins);
    const double c2 = cpu_seconds();
    render::blend_forward(p, s.colors, s.background, bins, s.camera.width, s.camera.height, true);
    const double c3 = cpu_seconds();
    if (rep > 0) project.push_back(c1 - c0), bin.push_back(c2 - c1), blend.push_back(c3 - c2);
  }
  std::printf("stages (CPU ms): project %.1f, bin %.1f, blend %.1f\n", median(project) * 1e3,
              median(bin) * 1e3, median(blend) * 1e3);
}

void run_scene(int width, int height, int64_t g, int64_t n, int reps, const Timing& peak) {
  const Scene s = make_scene(g, n, width, height);
  std::vector<torch::Tensor> leaves = {s.means, s.log_scales, s.quats, s.logit_opacities, s.colors};
  for (auto& t : leaves) t.set_requires_grad(true);
  torch::manual_seed(7);
  const torch::Tensor d_image = torch::randn({height, width, n});
  std::vector<double> fwd, bwd, fwd_cpu, bwd_cpu;
  for (int rep = 0; rep <= reps; ++rep) {  // rep 0 warms caches and buffers
    for (auto& t : leaves) t.mutable_grad() = torch::Tensor();
    auto t0 = Clock::now();
    double c0 = cpu_seconds();
    const render::RenderOutput out =
        render::rasterize(s.means, s.log_scales, s.quats, s.logit_opacities, s.colors, s.camera,
                          s.background, torch::zeros({g, 2}, torch::requires_grad()));
    const double f = seconds_since(t0), fc = cpu_seconds() - c0;
    t0 = Clock::now();
    c0 = cpu_seconds();
    out.image.backward(d_image);
    const double b = seconds_since(t0), bc = cpu_seconds() - c0;
    if (rep > 0) fwd.push_back(f), bwd.push_back(b), fwd_cpu.push_back(fc), bwd_cpu.push_back(bc);
  }
  const double f = median(fwd), b = median(bwd), fc = median(fwd_cpu), bc = median(bwd_cpu);
  const double pairs = double(count_pairs(s));
  const double gflop_fwd = 2.0 * n * pairs / 1e9, gflop_all = 6.0 * n * pairs / 1e9;
  std::printf(
      "| %dx%d | %lldk | %lld | %.1f | %.1f | %.2f | %.1f | %.2f | %.1f %% | %.1f %% | %.1f %% | "
      "%.1f "
      "%% | %.0f |\n",
      width, height, (long long)(g / 1000), (long long)n, f * 1e3, b * 1e3, pairs / 1e6,
      pairs / f / 1e6, gflop_fwd / f, 100 * gflop_fwd / f / peak.wall,
      100 * gflop_all / (f + b) / peak.wall, 100 * gflop_fwd / fc / peak.cpu,
      100 * gflop_all / (fc + bc) / peak.cpu, peak_rss_mib());
  if (std::getenv("DDHGS_BENCH_STAGES")) {
    std::printf("forward (CPU ms) %.1f, backward %.1f; ", fc * 1e3, bc * 1e3);
    print_stages(s, reps);
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const int threads = core::configure_threads();
  const char* narrow_env = std::getenv("DDHGS_BENCH_NARROW");
  const bool narrow = narrow_env && std::strcmp(narrow_env, "1") == 0;
  if (narrow) render::set_wide_kernels(false);
  const Timing peak = mm_peak_gflops();
  std::printf(
      "threads %d, blend loops %s, torch::mm fp32 peak %.1f GFLOP/s per wall second, %.1f per "
      "CPU second\n\n",
      threads, render::wide_kernels_built() && !narrow ? "512-bit" : "256-bit", peak.wall,
      peak.cpu);
  std::printf(
      "| image | G | N | fwd ms | bwd ms | pairs (M) | pairs/s (M) | fwd GFLOP/s | fwd %% peak | "
      "fwd+bwd %% peak | fwd %% peak (CPU) | fwd+bwd %% peak (CPU) | peak RSS MiB |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const int reps = quick ? 1 : 5;
  if (argc == 6 && std::strcmp(argv[1], "--only") == 0) {  // one scene, e.g. for a profiler
    run_scene(std::atoi(argv[2]), std::atoi(argv[3]), std::atoll(argv[4]), std::atoll(argv[5]), 3,
              peak);
    return 0;
  }
  for (auto [w, h] : {std::pair{256, 256}, std::pair{640, 512}})
    for (int64_t g : {10000, 100000})
      for (int64_t n : {3, 32, 128, 141}) run_scene(w, h, g, n, reps, peak);
  return 0;
}
