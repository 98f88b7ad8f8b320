// Seconds per N-3DGS training iteration (Trainer::advance, the step `ddhgs
// train` runs) and its split by stage, at the band counts users bring.
//
//   build/bench/bench_train_step                      # the default cases below
//   build/bench/bench_train_step --only W H G N       # one case (e.g. for perf)
//   build/bench/bench_train_step --scene DIR [--downscale D] --only 0 0 G 0
//   options: --iterations K (timed, default 5), --views V (default 6)
//
// Per case it writes a synthetic scene (`ddhgs synth --preset bayspec` with
// the case's size and band count, supersample 1) to a temporary folder,
// starts the trainer from G random Gaussians with densification off and the
// SH degree raised every iteration (degree 3 after the 3 warm-up
// iterations), then times K iterations: wall, user and system CPU time and
// minor page faults per iteration (getrusage), peak RSS, and each stage's
// share (core/stage_timer.h; stages exclude the stages nested in them).
// Threads: $DDHGS_THREADS, else every core.
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/early_setup.h"
#include "core/stage_timer.h"
#include "core/threads.h"
#include "synth/generate.h"
#include "train/config.h"
#include "train/run_folder.h"
#include "train/trainer.h"

namespace {

using namespace ddhgs;
namespace fs = std::filesystem;

struct Case {
  int width, height;  // 0: the scene's own size (--scene)
  int64_t gaussians;
  int bands;  // 0: the scene's own bands (--scene)
};

struct Options {
  std::vector<Case> cases = {{640, 512, 100000, 141},
                             {160, 128, 10000, 141},
                             {160, 128, 10000, 128},
                             {160, 128, 10000, 40},
                             {160, 128, 10000, 3}};
  int iterations = 5;
  int warmup = 3;
  int views = 6;
  fs::path scene;  // use this scene instead of a synthetic one
  int downscale = 1;
};

struct Usage {
  double wall, user, system;
  int64_t faults;
  static Usage now() {
    rusage u;
    getrusage(RUSAGE_SELF, &u);
    return {
        std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(),
        double(u.ru_utime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec),
        double(u.ru_stime.tv_sec) + 1e-6 * double(u.ru_stime.tv_usec), int64_t(u.ru_minflt)};
  }
};

double peak_rss_mib() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

fs::path write_scene(const Case& c, int views, const fs::path& dir) {
  synth::SynthConfig config = synth::preset_config("bayspec");
  config.width = c.width, config.height = c.height, config.bands = c.bands;
  config.views = views;
  config.supersample = 1;
  const fs::path out = dir / "scene";
  synth::write_synthetic_scene(config, out, false);
  return out;
}

nlohmann::json train_config(const fs::path& scene, const Options& o, int64_t gaussians) {
  nlohmann::json config = train::load_preset("default");
  config["data"]["path"] = fs::absolute(scene).string();
  config["data"]["downscale"] = o.downscale;
  config["init"]["random"] = true;
  config["init"]["random_points"] = gaussians;
  // A fixed Gaussian count: statistics are gathered, nothing is added, no
  // opacity reset.
  config["densify"]["from_fraction"] = 1.0;
  config["densify"]["opacity_reset_every_fraction"] = 0.0;
  // Degree 3 from the fourth iteration (an interval rounds up to 1).
  config["model"]["sh_degree_every_fraction"] = 1e-9;
  config["output"]["checkpoint_every"] = 0;
  return config;
}

void print_stages(const Usage& total, int iterations) {
  std::printf("  %-22s %9s %9s %9s %9s %8s\n", "stage", "wall ms", "CPU ms", "sys ms", "faults",
              "CPU %");
  const double cpu_total = total.user + total.system;
  for (const core::StageTotals& s : core::stage_totals()) {
    const double cpu = s.user_s + s.system_s;
    std::printf("  %-22s %9.1f %9.1f %9.1f %9lld %7.1f%%\n", s.name.c_str(),
                1e3 * s.wall_s / iterations, 1e3 * cpu / iterations, 1e3 * s.system_s / iterations,
                (long long)(s.minor_faults / iterations),
                cpu_total > 0 ? 100.0 * cpu / cpu_total : 0.0);
  }
}

// A temporary folder of this process, removed with everything in it.
struct TempDir {
  fs::path path =
      fs::temp_directory_path() / ("ddhgs_bench_train_step_" + std::to_string(::getpid()));
  TempDir() { fs::create_directories(path); }
  ~TempDir() { fs::remove_all(path); }
};

void run_case(const Case& c, const Options& o) {
  const TempDir temp;
  const fs::path& dir = temp.path;
  const auto synth_start = std::chrono::steady_clock::now();
  const fs::path scene = o.scene.empty() ? write_scene(c, o.views, dir) : o.scene;
  const double synth_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - synth_start).count();
  {
    auto trainer = train::Trainer::start(train_config(scene, o, c.gaussians), {dir / "run"}, false);
    const auto& views = trainer->scene().views;
    const auto& in = views.at(size_t(trainer->scene().train.front())).camera.intrinsics;
    for (int i = 0; i < o.warmup; ++i) trainer->advance();
    core::reset_stage_totals();
    core::enable_stage_timing(true);
    const Usage before = Usage::now();
    for (int i = 0; i < o.iterations; ++i) trainer->advance();
    const Usage after = Usage::now();
    core::enable_stage_timing(false);
    const Usage d{after.wall - before.wall, after.user - before.user, after.system - before.system,
                  after.faults - before.faults};
    const int k = o.iterations;
    const double cpu = d.user + d.system;
    std::printf(
        "%dx%d, %lld bands, %lld Gaussians, threads %d, %d iterations (after %d warm-up), "
        "scene %.0f s\n",
        in.width, in.height, (long long)trainer->scene().bands(),
        (long long)trainer->state().gaussians.size(), core::thread_count(), k, o.warmup, synth_s);
    std::printf(
        "  per iteration: wall %.3f s, CPU %.3f s (user %.3f + system %.3f, system %.1f %%), "
        "minor faults %lld; peak RSS %.0f MiB\n",
        d.wall / k, cpu / k, d.user / k, d.system / k, cpu > 0 ? 100.0 * d.system / cpu : 0.0,
        (long long)(d.faults / k), peak_rss_mib());
    print_stages(d, k);
    std::fflush(stdout);
  }
}

[[noreturn]] void usage_error(const char* message) {
  std::fprintf(stderr, "bench_train_step: %s\n", message);
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  auto number = [&](int& i) {
    if (i + 1 >= argc) usage_error("an option is missing its value");
    return std::atoll(argv[++i]);
  };
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--only")) {
      if (i + 4 >= argc) usage_error("--only needs W H G N");
      Case c{int(std::atoi(argv[i + 1])), int(std::atoi(argv[i + 2])), std::atoll(argv[i + 3]),
             int(std::atoi(argv[i + 4]))};
      o.cases = {c};
      i += 4;
    } else if (!std::strcmp(argv[i], "--iterations")) {
      o.iterations = int(number(i));
    } else if (!std::strcmp(argv[i], "--views")) {
      o.views = int(number(i));
    } else if (!std::strcmp(argv[i], "--downscale")) {
      o.downscale = int(number(i));
    } else if (!std::strcmp(argv[i], "--scene")) {
      if (i + 1 >= argc) usage_error("--scene needs a folder");
      o.scene = argv[++i];
    } else {
      usage_error((std::string("unknown option ") + argv[i]).c_str());
    }
  }
  if (o.iterations < 1 || o.views < 1 || o.downscale < 1)
    usage_error("--iterations, --views and --downscale must be positive");
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  core::configure_threads(0);
  try {
    for (const Case& c : o.cases) run_case(c, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_train_step: %s\n", e.what());
    return 1;
  }
  return 0;
}
