// `ddhgs eval RUN`: metrics of a trained run on its test views (or another
// split), against the stored views and, for synthetic scenes, clean ground
// truth; render speed. Runs that trained the diffusion denoiser are also
// evaluated after denoising, per sampler setting (eval/denoised_eval.h).
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <optional>

#include "app/registry.h"
#include "app/trained_run.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/denoised_eval.h"
#include "eval/evaluate.h"
#include "eval/held_out_bands.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"
#include "io/scene/backdrop.h"
#include "train/denoiser_prior.h"

namespace ddhgs::app {
namespace cmd_eval {
namespace fs = std::filesystem;

struct EvalArgs {
  std::string run;
  std::string split = "test";
  int fps_repeats = 5;
  std::string data;
  std::string prior;
  // One step from s = 0.1 measured best on our scenes (docs/benchmarks.md).
  std::vector<int64_t> denoise_steps = {1, 10};
  bool ddpm = false, no_denoise = false;
  bool align_poses = false;
  bool held_out_bands = false;
  eval::AlignOptions align;
  SamplerFlags sampler;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "eval",
      "Evaluate a trained run: PSNR, SSIM, SAM, RMSE, per-band PSNR and FPS; writes "
      "RUN/eval/metrics.json and RUN/eval/per_view.csv (metrics_<split>.json and "
      "per_view_<split>.csv for a split other than test)");
  cmd->add_option("run", args->run, "Run folder written by ddhgs train")->required();
  cmd->add_option("--split", args->split, "Views to evaluate")
      ->check(CLI::IsMember({"test", "train", "all"}))
      ->capture_default_str();
  cmd->add_option("--fps-repeats", args->fps_repeats,
                  "Timed passes over the test views for FPS (0: skip timing)")
      ->check(within(0, 10000))
      ->capture_default_str();
  cmd->add_option("--data", args->data, "Dataset folder, if it moved since training");
  cmd->add_option("--denoise-steps", args->denoise_steps,
                  "DDIM step counts K to evaluate the denoiser with (runs with denoiser.pt)")
      ->delimiter(',')
      ->check(within(1, 100000))
      ->capture_default_str();
  cmd->add_flag("--ddpm", args->ddpm,
                "Also evaluate full ancestral DDPM sampling (every step below the start; slow)");
  cmd->add_flag("--align-poses", args->align_poses,
                "Also measure each view from its pose aligned to the view (the model frozen; a "
                "rotation and a shift fitted to the image): the model's error apart from the "
                "poses' (real captures' poses are off by a pixel or so)");
  cmd->add_option("--align-steps", args->align.steps, "Optimiser steps per view for --align-poses")
      ->check(within(1, 1000000))
      ->capture_default_str();
  add_sampler_flags(cmd, args->sampler);
  cmd->add_option("--prior", args->prior,
                  "Denoise with this denoiser prior (ddhgs prior) in the run's spectral subspace, "
                  "fitted to its training views, instead of the run's own denoiser; the denoised "
                  "files are then the prior's");
  cmd->add_flag("--no-denoise", args->no_denoise, "Evaluate the raw render only");
  cmd->add_flag("--held-out-bands", args->held_out_bands,
                "For a run trained on every k-th band (data.band_step k): also render the "
                "bands it skipped and measure them per band against the dataset's own; writes "
                "RUN/eval/held_out_bands.json");
  auto* denoise_steps_option = cmd->get_option("--denoise-steps");
  return [args, denoise_steps_option] {
    TrainedRun run = open_trained_run(args->run, args->data);
    io::FolderLock lock(run.root, "eval");
    if (!args->prior.empty()) {
      train::DiffusionTermOptions options = run.config.diffusion;
      options.prior = args->prior;
      run.denoiser = train::prior_term(options, *run.scene)->denoiser();
      run.sampler = run.config.diffusion.sampler;
    }
    // The sampler settings are checked before the (long) raw evaluation.
    std::vector<eval::DenoiseSetting> settings;
    if (run.denoiser && !args->no_denoise) {
      const int64_t schedule = run.denoiser->schedule.steps;
      std::vector<int64_t> steps;
      for (int64_t k : args->denoise_steps) {
        if (k <= schedule) {
          if (std::find(steps.begin(), steps.end(), k) == steps.end()) steps.push_back(k);
        } else if (denoise_steps_option->count() > 0) {
          throw core::Error("--denoise-steps",
                            "is " + std::to_string(k) + ", but the run's denoiser has a " +
                                std::to_string(schedule) + "-step schedule (diffusion.steps)");
        }
      }
      if (steps.empty()) steps.push_back(schedule);  // defaults all above a short schedule
      settings = eval::denoise_settings(steps, args->ddpm, sampler_options(run, args->sampler));
    }
    std::vector<int> views = eval::split_views(*run.scene, args->split);
    eval::EvalOptions options;
    options.fps_repeats = args->fps_repeats;
    if (args->align_poses) {
      if (run.scene->band_per_view())
        throw core::Error("--align-poses",
                          "aligns a view on all of its bands; the views of this band-per-view "
                          "scene hold one or a few");
      options.align = args->align;
    }
    if (auto backdrop = io::masked_backdrop(*run.scene, run.scene->train)) {
      options.backdrop = *backdrop;
      core::log_info("the views are masked to a uniform backdrop (" +
                     io::describe_colour(*backdrop) +
                     "): the object (the pixels unlike it) is measured on its own too");
    }
    eval::EvalReport report =
        eval::evaluate(*run.scene, run.gaussians, run.background, views, args->split, options);

    std::optional<eval::HeldOutBands> held_out;
    if (args->held_out_bands) {
      io::LoadOptions every_band = run.config.data.load;
      core::require(every_band.band_step > 1, run.root,
                    "was trained on every band (data.band_step 1): no band is held out; train "
                    "with --set data.band_step=2 to hold out every second band");
      every_band.band_step = 1;
      const auto all_bands = io::load_scene(run.scene->root, every_band);
      held_out = eval::evaluate_held_out_bands(*all_bands, run.gaussians, run.scene->wavelengths_nm,
                                               run.background, views);
    }

    std::optional<eval::DenoisedReport> denoised;
    if (!settings.empty()) {
      denoised = eval::evaluate_denoised(*run.scene, run.gaussians, run.background, *run.denoiser,
                                         views, args->split, settings);
    }

    // Every file of this evaluation appears, or none does.
    const fs::path out = run.root / "eval";
    const std::string suffix = args->split == "test" ? "" : "_" + args->split;
    const std::string metrics = "metrics" + suffix + ".json";
    const std::string per_view = "per_view" + suffix + ".csv";
    const std::string denoised_json = "denoised" + suffix + ".json";
    const std::string denoised_csv = "per_view_denoised" + suffix + ".csv";
    io::write_into_folder_atomically(
        {out, io::OutputKind::Eval, true, {run.root, run.scene->root}, ""},
        [&](const fs::path& tmp) {
          eval::write_metrics_json(tmp / metrics, report);
          eval::write_per_view_csv(tmp / per_view, report);
          if (held_out)
            io::write_file_atomically(tmp / ("held_out_bands" + suffix + ".json"),
                                      eval::to_json(*held_out).dump(2) + "\n");
          if (!denoised) return;
          eval::write_denoised_json(tmp / denoised_json, *denoised);
          eval::write_denoised_csv(tmp / denoised_csv, *denoised);
        });
    std::cout << eval::format_report(report) << "wrote " << (out / metrics).string() << " and "
              << (out / per_view).string() << "\n";
    if (held_out) std::cout << eval::format_held_out(*held_out);
    if (denoised)
      std::cout << eval::format_denoised(*denoised) << "wrote " << (out / denoised_json).string()
                << " and " << (out / denoised_csv).string() << "\n";
    return 0;
  };
}

Registrar registrar("eval", 50, setup);

}  // namespace cmd_eval
}  // namespace ddhgs::app
