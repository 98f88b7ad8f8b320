// Seconds per N-3DGS training iteration (Trainer::advance, the step `ddhgs
// train` runs) and its split by stage, at the band counts users bring.
//
//   build/bench/bench_train_step                      # the default cases below
//   build/bench/bench_train_step --only W H G N       # one case (e.g. for perf)
//   build/bench/bench_train_step --scene DIR [--downscale D] --only 0 0 G 0
//   options: --iterations K (timed, default 5), --views V (default 6),
//            --ranks R[,R...] (model.spectral_rank, default 0: per band; each
//            rank trains on the same scene, one after the other),
//            --bands-per-step S[,S...] (loss.bands_per_step, default 0: all;
//            each value with each rank), --view-fraction F (loss.view_fraction,
//            default 1: whole views; the rest of a run's schedule as default.json),
//            --blend-paths P[,P...] (lane, row; default lane: the blender's path
//            for images of at most 8 channels, render/blend.h; each path with
//            each rank and bands value, on the same scene: an A/B in one run)
//
// Per case it writes a synthetic scene (`ddhgs synth --preset bayspec` with
// the case's size and band count, supersample 1) to a temporary folder,
// starts the trainer from G random Gaussians with densification off and the
// SH degree raised every iteration (degree 3 after the 3 warm-up
// iterations), then times K iterations: wall, user and system CPU time and
// minor page faults per iteration (getrusage), peak RSS, and each stage's
// share (core/stage_timer.h; stages exclude the stages nested in them), and
// the final save: checkpoint and PLY, as `ddhgs train` writes them at its end.
// Peak RSS is the process's: run one rank alone to measure its memory.
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
#include "io/ply/ply.h"
#include "render/blend.h"
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
  std::vector<int> ranks = {0};
  std::vector<int> bands_per_step = {0};
  double view_fraction = 1;
  std::vector<bool> lane_paths = {true};
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

nlohmann::json train_config(const fs::path& scene, const Options& o, int64_t gaussians, int rank,
                            int bands_per_step) {
  nlohmann::json config = train::load_preset("default");
  config["model"]["spectral_rank"] = rank;
  config["loss"]["bands_per_step"] = bands_per_step;
  config["loss"]["view_fraction"] = o.view_fraction;
  config["loss"]["view_fraction_from_pixels"] = 0;  // every size: the fraction asked for
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

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// One rank and loss.bands_per_step on the scene, trained in run_dir (a new
// folder each time: the final save stays in it).
void run_rank(const Case& c, const Options& o, const fs::path& scene, const fs::path& run_dir,
              double synth_s, int rank, int bands_per_step, bool lane_path) {
  render::set_lane_path(lane_path);
  auto trainer = train::Trainer::start(train_config(scene, o, c.gaussians, rank, bands_per_step),
                                       {run_dir}, false);
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
  const model::Gaussians& g = trainer->state().gaussians;
  std::printf(
      "%dx%d, %lld bands, %s, loss on %s bands and %g of the pixels, %lld Gaussians, threads %d, "
      "%d iterations (after %d warm-up), scene %.0f s%s\n",
      in.width, in.height, (long long)trainer->scene().bands(),
      g.colour.latent() ? ("rank " + std::to_string(g.colour.rank())).c_str() : "per band",
      bands_per_step > 0 ? std::to_string(bands_per_step).c_str() : "all", o.view_fraction,
      (long long)g.size(), core::thread_count(), k, o.warmup, synth_s,
      o.lane_paths.size() > 1 ? (lane_path ? ", lane path" : ", row path") : "");
  std::printf(
      "  per iteration: wall %.3f s, CPU %.3f s (user %.3f + system %.3f, system %.1f %%), "
      "minor faults %lld; peak RSS %.0f MiB\n",
      d.wall / k, cpu / k, d.user / k, d.system / k, cpu > 0 ? 100.0 * d.system / cpu : 0.0,
      (long long)(d.faults / k), peak_rss_mib());
  print_stages(d, k);
  // The final save, as the trainer writes it (the encoder is off here).
  const auto save_start = std::chrono::steady_clock::now();
  train::save_checkpoint(run_dir / "final.pt", trainer->state());
  const double checkpoint_s = seconds_since(save_start);
  const auto ply_start = std::chrono::steady_clock::now();
  io::write_gaussian_ply(run_dir / "final.ply", model::to_ply(g, trainer->scene().wavelengths_nm));
  const double ply_s = seconds_since(ply_start);
  std::printf(
      "  %lld bytes per Gaussian in training; final save %.2f s: checkpoint %.2f s (%.0f MB), "
      "PLY %.2f s (%.0f MB)\n",
      (long long)model::training_bytes_per_gaussian(g.channels(), g.max_sh_degree()),
      checkpoint_s + ply_s, checkpoint_s, double(fs::file_size(run_dir / "final.pt")) / 1e6, ply_s,
      double(fs::file_size(run_dir / "final.ply")) / 1e6);
  std::fflush(stdout);
}

void run_case(const Case& c, const Options& o) {
  const TempDir temp;
  const fs::path& dir = temp.path;
  const auto synth_start = std::chrono::steady_clock::now();
  const fs::path scene = o.scene.empty() ? write_scene(c, o.views, dir) : o.scene;
  const double synth_s = seconds_since(synth_start);
  int runs = 0;
  for (int rank : o.ranks)
    for (int bands_per_step : o.bands_per_step)
      for (bool lane_path : o.lane_paths)
        run_rank(c, o, scene, dir / ("run_" + std::to_string(++runs)), synth_s, rank,
                 bands_per_step, lane_path);
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
  auto list = [&](int& i, const char* missing) {
    if (i + 1 >= argc) usage_error(missing);
    std::vector<int> values;
    const std::string text = argv[++i];
    for (size_t at = 0; at <= text.size();) {
      const size_t comma = std::min(text.find(',', at), text.size());
      values.push_back(std::atoi(text.substr(at, comma - at).c_str()));
      at = comma + 1;
    }
    return values;
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
    } else if (!std::strcmp(argv[i], "--ranks")) {
      o.ranks = list(i, "--ranks needs a list");
    } else if (!std::strcmp(argv[i], "--bands-per-step")) {
      o.bands_per_step = list(i, "--bands-per-step needs a list");
    } else if (!std::strcmp(argv[i], "--view-fraction")) {
      if (i + 1 >= argc) usage_error("--view-fraction needs a value");
      o.view_fraction = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--blend-paths")) {
      if (i + 1 >= argc) usage_error("--blend-paths needs a list");
      o.lane_paths.clear();
      const std::string text = argv[++i];
      for (size_t at = 0; at <= text.size();) {
        const size_t comma = std::min(text.find(',', at), text.size());
        const std::string path = text.substr(at, comma - at);
        if (path != "lane" && path != "row") usage_error("--blend-paths takes lane and row");
        o.lane_paths.push_back(path == "lane");
        at = comma + 1;
      }
    } else if (!std::strcmp(argv[i], "--scene")) {
      if (i + 1 >= argc) usage_error("--scene needs a folder");
      o.scene = argv[++i];
    } else {
      usage_error((std::string("unknown option ") + argv[i]).c_str());
    }
  }
  if (o.iterations < 1 || o.views < 1 || o.downscale < 1)
    usage_error("--iterations, --views and --downscale must be positive");
  if (!(o.view_fraction > 0 && o.view_fraction <= 1))
    usage_error("--view-fraction must be in (0, 1]");
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
