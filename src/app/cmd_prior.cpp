// `ddhgs prior CORPUS --out PRIOR.pt`: trains a denoiser prior on a corpus
// of synthetic scenes (app/prior_corpus.h, train/denoiser_prior.h),
// resumably: PRIOR.pt holds the weights after every check, PRIOR.pt.state.pt
// the optimiser, PRIOR.pt.curve.csv the learning curve; a rerun with the same
// --out goes on from the last check. A run then uses the prior with
// `--set diffusion.prior=PRIOR.pt`.
#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>

#include "app/prior_corpus.h"
#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"
#include "train/config.h"
#include "train/run_config.h"
#include "train/stop_signal.h"

namespace ddhgs::app {
namespace cmd_prior {

namespace fs = std::filesystem;

struct PriorArgs {
  std::string corpus, out;
  train::PriorTrainingOptions training;
  int64_t channels = train::kPriorChannels;
  int64_t base_channels = 32;
  int64_t check_every = 500;
  bool force = false;
  std::string objective = "restoration";
};

// The command with the settings that decide the weights (the corpus and the
// output as given), for the prior's record.
std::string command_line(const PriorArgs& args) {
  const train::PriorTrainingOptions& t = args.training;
  std::ostringstream line;
  line << "ddhgs prior " << args.corpus << " --out " << args.out << " --objective "
       << args.objective << " --steps " << t.steps << " --batch " << t.batch << " --crop " << t.crop
       << " --lr " << core::format_g(t.lr) << " --channels " << args.channels << " --base-channels "
       << args.base_channels << " --seed " << t.seed;
  return line.str();
}

// The denoiser to start from: the default preset's network, schedule and
// parameterisation, in `channels` channels, its weights from `seed`.
model::Denoiser fresh_denoiser(const PriorArgs& args, train::PriorTrainingOptions& training) {
  const train::RunConfig defaults =
      train::parse_run_config(train::load_preset("default"), "configs/default.json");
  const train::DiffusionTermOptions& d = defaults.diffusion;
  model::UNetOptions unet = d.unet;
  unet.bands = args.channels;
  unet.base_channels = args.base_channels;
  torch::manual_seed(training.seed);
  model::Denoiser denoiser;
  denoiser.unet = model::UNet(unet);
  denoiser.schedule = model::NoiseSchedule(d.schedule_steps, d.schedule, d.beta_start, d.beta_end);
  denoiser.prediction = d.prediction;
  training.min_snr_gamma = d.min_snr_gamma;
  training.sampler = d.sampler;
  return denoiser;
}

// Appends one line to PRIOR.pt.curve.csv (with its header when new).
void append_curve(const fs::path& path, const std::string& line) {
  const bool fresh = !fs::exists(path);
  std::ofstream out(path, std::ios::app);
  if (fresh) out << "step,seconds,loss,identity_loss,check_raw_db,check_denoised_db\n";
  out << line << "\n";
  core::require(bool(out), path, "cannot be written");
}

// The training seconds a resumed prior had spent up to `step`: the seconds
// of the curve's last row at or before it (0 without one), so the curve's
// seconds count the whole training across reruns.
double curve_seconds_at(const fs::path& path, int64_t step) {
  std::ifstream in(path);
  std::string line;
  double seconds = 0;
  while (std::getline(in, line)) {
    int64_t row_step = 0;
    double row_seconds = 0;
    char comma = 0;
    std::istringstream row(line);
    if (row >> row_step >> comma >> row_seconds && comma == ',' && row_step <= step)
      seconds = row_seconds;
  }
  return seconds;
}

fs::path curve_path(const fs::path& prior) {
  fs::path p = prior;
  p += ".curve.csv";
  return p;
}

int run(const PriorArgs& args) {
  const fs::path out = args.out, state = train::prior_state_path(out), curve = curve_path(out);
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  if (args.force)
    for (const fs::path& p : {out, state, curve}) fs::remove(p);
  core::require(!fs::exists(out) || fs::exists(state), out,
                "exists and holds a finished prior (no training state beside it); --force "
                "starts over");
  train::PriorTrainingOptions training = args.training;
  model::Denoiser denoiser = fresh_denoiser(args, training);
  PriorCorpus corpus = load_prior_corpus(args.corpus, args.channels);
  core::log_info("prior: " + std::to_string(corpus.pairs.size()) + " pairs from " +
                 corpus.description["entries"].dump() + " finished entries (" +
                 corpus.description["unfinished_entries"].dump() + " unfinished), " +
                 std::to_string(corpus.checks.size()) + " views kept for checks");
  train::PriorTraining trainer(denoiser, training, std::move(corpus.pairs));
  if (trainer.load_state(state))
    core::log_info("prior: resuming " + out.string() + " at step " +
                   std::to_string(trainer.step()));
  if (trainer.step() >= training.steps) {
    core::log_info("prior: " + out.string() + " has already trained " +
                   std::to_string(trainer.step()) + " steps (--steps " +
                   std::to_string(training.steps) + ")");
    return 0;
  }
  nlohmann::json info = {{"command", command_line(args)},
                         {"corpus", corpus.description},
                         {"objective", train::to_string(training.objective)},
                         {"batch", training.batch},
                         {"crop", training.crop},
                         {"lr", training.lr},
                         {"seed", training.seed}};
  train::StopSignalGuard stop_guard;
  core::ProgressBar bar("prior", training.steps);
  const auto start = std::chrono::steady_clock::now();
  const double seconds_before = curve_seconds_at(curve, trainer.step());
  double loss_sum = 0, identity_sum = 0;
  int64_t since = 0;
  auto checkpoint = [&] {
    std::string check = ",";
    if (!corpus.checks.empty()) {
      const auto [raw, denoised] = trainer.check(corpus.checks);
      check = core::format_g(raw) + "," + core::format_g(denoised);
      core::log_info("prior: step " + std::to_string(trainer.step()) + ": check views " +
                     core::format_g(denoised) + " dB denoised against " + core::format_g(raw) +
                     " dB raw");
    }
    const double seconds =
        seconds_before +
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    append_curve(curve, std::to_string(trainer.step()) + "," + core::format_g(seconds) + "," +
                            core::format_g(since ? loss_sum / double(since) : 0) + "," +
                            core::format_g(since ? identity_sum / double(since) : 0) + "," + check);
    info["steps"] = trainer.step();
    train::write_prior(out, trainer.denoiser(), info);
    trainer.save_state(state);
    loss_sum = identity_sum = 0;
    since = 0;
  };
  while (trainer.step() < training.steps && !train::stop_requested()) {
    const auto [loss, identity] = trainer.train_step();
    loss_sum += loss;
    identity_sum += identity;
    ++since;
    bar.update(trainer.step(), "loss " + core::format_g(loss_sum / double(since)) + " (identity " +
                                   core::format_g(identity_sum / double(since)) + ")");
    if (trainer.step() % args.check_every == 0 || trainer.step() == training.steps) checkpoint();
  }
  if (since > 0) checkpoint();
  if (trainer.step() >= training.steps) bar.finish();  // a stopped bar stays where it stopped
  core::log_info("prior: " + out.string() + " at step " + std::to_string(trainer.step()) +
                 (trainer.step() < training.steps ? " (stopped; rerun to go on)" : ""));
  return train::stop_requested() ? train::interrupted_exit_code() : 0;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<PriorArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "prior",
      "Train a denoiser prior across a corpus of synthetic scenes (scripts/prior_corpus.sh); "
      "resumable: rerun with the same --out to go on");
  cmd->add_option("corpus", args->corpus, "The corpus folder (holding manifest.json)")->required();
  cmd->add_option("--out", args->out, "The prior file (beside it: .state.pt, .curve.csv)")
      ->required();
  cmd->add_option("--objective", args->objective,
                  "restoration: the render noised up to the sampler's start step, the clean "
                  "view predicted in one step (what the sampler asks at inference); diffusion: "
                  "the paper's loss over every step")
      ->check(CLI::IsMember({"restoration", "diffusion"}))
      ->capture_default_str();
  cmd->add_option("--steps", args->training.steps, "Total optimiser steps")
      ->default_val(20000)
      ->check(within(1, 1e9));
  cmd->add_option("--batch", args->training.batch, "Crops per step")
      ->default_val(8)
      ->check(within(1, 4096));
  cmd->add_option("--crop", args->training.crop, "Crop side, pixels")
      ->default_val(64)
      ->check(within(8, 4096));
  cmd->add_option("--lr", args->training.lr, "Adam learning rate (cosine to 0 over the last tenth)")
      ->default_val(2e-4)
      ->check(within(1e-9, 1));
  cmd->add_option("--channels", args->channels, "Subspace coefficients the prior sees")
      ->default_val(train::kPriorChannels)
      ->check(within(1, 64));
  cmd->add_option("--base-channels", args->base_channels, "U-Net channels at full resolution")
      ->default_val(32)
      ->check(within(4, 512));
  cmd->add_option("--check-every", args->check_every,
                  "Steps between checks (held-out corpus views; the files are written then)")
      ->default_val(500)
      ->check(within(1, 1e9));
  cmd->add_option("--seed", args->training.seed, "Seed of the weights and the draws")
      ->default_val(0);
  cmd->add_flag("--force", args->force, "Start over, replacing the prior and its state");
  return [args] {
    args->training.objective = train::parse_prior_objective(args->objective, "--objective");
    return run(*args);
  };
}

const Registrar registrar("prior", 37, setup);

}  // namespace cmd_prior
}  // namespace ddhgs::app
