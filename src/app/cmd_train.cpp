// `ddhgs train DATA --out RUN`: trains N-band Gaussians on a dataset folder.
// A preset (configs/) gives every hyperparameter; each flag overrides one key.
#include <algorithm>
#include <filesystem>
#include <memory>
#include <vector>

#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "train/config.h"
#include "train/stop_signal.h"
#include "train/trainer.h"

namespace ddhgs::app {
namespace cmd_train {

namespace fs = std::filesystem;

struct TrainArgs {
  std::string data, out, preset = "default", resume, band_range;
  std::vector<std::string> assignments;
  bool force = false, rgb = false, random_init = false, no_spectral_loss = false;
  bool wavelength_encoder = false, no_wavelength_encoder = false;
  int64_t iterations = 0, seed = 0, max_gaussians = 0, checkpoint_every = 0;
  int downscale = 1, bin = 1;
  size_t cache_mb = 0;
};

// Flag -> config key, for the flags given on the command line.
void apply_flags(const TrainArgs& a, CLI::App* cmd, nlohmann::json& config) {
  auto given = [&](const char* name) { return cmd->get_option(name)->count() > 0; };
  auto set = [&](const char* flag, const std::string& key, const std::string& value) {
    if (given(flag)) train::set_key(config, key, value, flag);
  };
  set("--iterations", "iterations", std::to_string(a.iterations));
  set("--seed", "seed", std::to_string(a.seed));
  set("--downscale", "data.downscale", std::to_string(a.downscale));
  set("--max-gaussians", "densify.max_gaussians", std::to_string(a.max_gaussians));
  set("--cache-mb", "data.cache_mb", std::to_string(a.cache_mb));
  set("--bin", "data.bin", std::to_string(a.bin));
  set("--checkpoint-every", "output.checkpoint_every", std::to_string(a.checkpoint_every));
  if (a.rgb) train::set_key(config, "data.rgb", "true", "--rgb");
  if (a.random_init) train::set_key(config, "init.random", "true", "--random-init");
  if (a.no_spectral_loss) train::set_key(config, "loss.spectral", "0", "--no-spectral-loss");
  if (a.wavelength_encoder && a.no_wavelength_encoder)
    throw core::Error("--wavelength-encoder", "conflicts with --no-wavelength-encoder");
  if (a.wavelength_encoder)
    train::set_key(config, "wavelength_encoder.enabled", "true", "--wavelength-encoder");
  if (a.no_wavelength_encoder)
    train::set_key(config, "wavelength_encoder.enabled", "false", "--no-wavelength-encoder");
  if (given("--band-range")) {
    auto colon = a.band_range.find(':');
    if (colon == std::string::npos)
      throw core::Error("--band-range",
                        "expected MIN:MAX in nm, got " + core::quoted_value(a.band_range));
    try {
      size_t lo_end = 0, hi_end = 0;
      const double lo = std::stod(a.band_range.substr(0, colon), &lo_end);
      const double hi = std::stod(a.band_range.substr(colon + 1), &hi_end);
      if (lo_end != colon || hi_end != a.band_range.size() - colon - 1)
        throw std::invalid_argument("");
      config["data"]["band_min_nm"] = lo;
      config["data"]["band_max_nm"] = hi;
    } catch (const std::exception&) {
      throw core::Error("--band-range",
                        "expected MIN:MAX in nm, got " + core::quoted_value(a.band_range));
    }
    const double lo = config["data"]["band_min_nm"], hi = config["data"]["band_max_nm"];
    if (!(lo >= 0 && hi <= 1e9 && lo <= hi))
      throw core::Error("--band-range",
                        "is " + a.band_range + ", expected MIN:MAX with 0 <= MIN <= MAX (nm)");
  }
  for (const auto& assignment : a.assignments) train::apply_assignment(config, assignment);
  // A length the user gives is the length: a band-per-view scene's shorter
  // default (optim.iterations_per_band_view) steps aside.
  const bool iterations_given =
      given("--iterations") ||
      std::any_of(a.assignments.begin(), a.assignments.end(),
                  [](const std::string& s) { return s.rfind("iterations=", 0) == 0; });
  if (iterations_given) config["optim"]["iterations_per_band_view"] = 0;
}

int run_new(const TrainArgs& a, CLI::App* cmd) {
  if (a.out.empty()) throw core::Error("train: --out RUN is required");
  nlohmann::json config = train::load_preset(a.preset);
  apply_flags(a, cmd, config);
  // The dataset comes from the argument or from data.path (--set or the
  // preset), never from both when they disagree.
  const std::string set_path = config["data"]["path"];
  if (a.data.empty() && set_path.empty())
    throw core::Error("train: give a dataset folder (or --resume RUN)");
  std::error_code ec;
  fs::path data = fs::absolute(a.data.empty() ? set_path : a.data, ec);
  if (!a.data.empty() && !set_path.empty() &&
      fs::absolute(set_path, ec).lexically_normal() != data.lexically_normal())
    throw core::Error("train", "key 'data.path' is " + set_path + " (from --set or --preset) but " +
                                   "the dataset argument is " + a.data + "; give the dataset once");
  if (!fs::exists(data)) throw core::Error(data, "no such dataset folder");
  config["data"]["path"] = data.lexically_normal().string();
  train::validate_config(config, "command line");
  auto trainer = train::Trainer::start(config, {a.out}, a.force);
  auto status = trainer->run();
  if (status == train::TrainStatus::Interrupted) return train::interrupted_exit_code();
  core::log_info("done: " + a.out + "/gaussians.ply; evaluate with: ddhgs eval " + a.out);
  return 0;
}

int run_resume(const TrainArgs& a, CLI::App* cmd) {
  for (const char* flag :
       {"--preset", "--seed", "--downscale", "--max-gaussians", "--cache-mb", "--bin",
        "--band-range", "--rgb", "--random-init", "--no-spectral-loss", "--wavelength-encoder",
        "--no-wavelength-encoder", "--set", "--out", "--force", "--checkpoint-every"})
    if (cmd->get_option(flag)->count() > 0)
      throw core::Error(flag, "cannot change a run being resumed (only --iterations)");
  if (!a.data.empty()) throw core::Error("--resume", "give the run folder only, not a dataset");
  if (cmd->get_option("--iterations")->count() > 0 && a.iterations < 1)
    throw core::Error("--iterations", "is " + std::to_string(a.iterations) + ", expected >= 1");
  auto trainer = train::Trainer::resume({a.resume}, a.iterations);
  auto status = trainer->run();
  if (status == train::TrainStatus::Interrupted) return train::interrupted_exit_code();
  core::log_info("done: " + a.resume + "/gaussians.ply");
  return 0;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<TrainArgs>();
  CLI::App* cmd = parent.add_subcommand("train", "Train N-band Gaussians on a dataset folder");
  cmd->footer(
      "The diffusion stage is off by default (loss.diffusion=0). What it costs and gains, "
      "measured on Basil (--rgb --downscale 4, 2000 iterations, 3 seeds; docs/quality.md): the "
      "paper's joint term makes each iteration about 5x slower; the novel-view variant (--set "
      "diffusion.joint=false --set diffusion.pairs=folds --set diffusion.distill_steps=500) "
      "takes 5-6x the time of the Gaussians alone, its denoised renders score 0.2-0.3 dB below its "
      "raw render, and the distilled Gaussians score what they scored before it (-0.02 dB on "
      "average). Its cheaper pair sources (diffusion.pairs=checkpoint or perturbed) take "
      "3.5-4.5x and do no better.");
  cmd->add_option("data", args->data, "Dataset folder (transforms.json or COLMAP layout)");
  cmd->add_option("--out", args->out, "Run folder to create");
  cmd->add_option("--preset", args->preset, "Preset name in configs/ or a .json path")
      ->capture_default_str();
  cmd->add_option("--set", args->assignments, "Override one key: key.path=value (repeatable)");
  cmd->add_option("--iterations", args->iterations, "Training iterations");
  cmd->add_option("--seed", args->seed, "Random seed");
  cmd->add_option("--downscale", args->downscale, "Train on images downscaled by this factor");
  cmd->add_option("--max-gaussians", args->max_gaussians,
                  "Stop densifying at this many (0: no cap)");
  cmd->add_flag("--rgb", args->rgb, "Train on the RGB images as a 3-band scene");
  cmd->add_option("--cache-mb", args->cache_mb,
                  "Memory budget for decoded views, MiB (views that need decoding, downscaling, "
                  "band selection or undistortion; a .npy at the view's own size is read from its "
                  "file at each use, only the rows a step needs)");
  cmd->add_option("--band-range", args->band_range, "Keep bands within MIN:MAX nm");
  cmd->add_option("--bin", args->bin, "Average groups of this many adjacent bands");
  cmd->add_option("--checkpoint-every", args->checkpoint_every,
                  "Checkpoint interval (0: end only)");
  cmd->add_flag("--random-init", args->random_init,
                "Start from random points in the view volume instead of the dataset's points");
  cmd->add_flag("--no-spectral-loss", args->no_spectral_loss,
                "Leave out the spectral loss (sets loss.spectral to 0)");
  cmd->add_flag("--wavelength-encoder", args->wavelength_encoder,
                "Train the wavelength encoder's per-band SH offsets (wavelength_encoder.enabled)");
  cmd->add_flag("--no-wavelength-encoder", args->no_wavelength_encoder,
                "Leave out the wavelength encoder (sets wavelength_encoder.enabled to false)");
  cmd->add_flag("--force", args->force, "Replace an existing run folder (kept until success)");
  cmd->add_option("--resume", args->resume, "Continue the run in this folder");
  return
      [args, cmd]() { return args->resume.empty() ? run_new(*args, cmd) : run_resume(*args, cmd); };
}

const Registrar registrar("train", 30, setup);

}  // namespace cmd_train
}  // namespace ddhgs::app
