// `ddhgs ablate DATA --out DIR`: the DD-HGS ablation (paper Table 3) on one
// scene, so users can reproduce it on their own data (app/ablation.h).
#include <iostream>

#include "app/ablation.h"
#include "app/registry.h"
#include "core/log.h"

namespace ddhgs::app {
namespace cmd_ablate {

struct AblateArgs {
  std::string data, out;
  std::vector<std::string> rows = {"3dgs", "sl",       "we",    "we+sl",    "diffusion",
                                   "full", "subspace", "folds", "distilled"};
  AblationOptions options;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<AblateArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "ablate",
      "Train and evaluate the DD-HGS ablation rows (3DGS, +SL, +WE, +WE+SL, +Diffusion, full, "
      "a spectral-subspace colour model, a denoiser trained on novel-view pairs, and that "
      "denoiser distilled into the Gaussians) "
      "with the same preset, seed and iterations; writes DIR/<row>/ runs, DIR/ablation.md and "
      "DIR/ablation.json");
  cmd->add_option("data", args->data, "Dataset folder")->required();
  cmd->add_option("--out", args->out, "Folder for the rows' runs and the table")->required();
  cmd->add_option("--preset", args->options.preset, "Preset name in configs/ or a .json path")
      ->capture_default_str();
  cmd->add_option("--rows", args->rows, "Rows to run, in order")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--set", args->options.assignments,
                  "Override one key for every row: key.path=value (repeatable; the rows' "
                  "switches loss.spectral, wavelength_encoder.enabled, loss.diffusion win)");
  cmd->add_option("--spectral-weight", args->options.spectral_weight,
                  "loss.spectral of the rows with the spectral loss (paper w3)")
      ->check(within(1e-12, 1e6))
      ->capture_default_str();
  cmd->add_option("--diffusion-weight", args->options.diffusion_weight,
                  "loss.diffusion of the rows with the denoiser (paper w4)")
      ->check(within(1e-12, 1e6))
      ->capture_default_str();
  cmd->add_option("--denoise-steps", args->options.denoise_steps,
                  "DDIM step counts K evaluated for the rows with the denoiser")
      ->delimiter(',')
      ->check(within(1, 100000))
      ->capture_default_str();
  cmd->add_option("--start-strength", args->options.start_strength,
                  "Sampler start strength for the denoiser rows (default: the preset's "
                  "diffusion.start_strength); changing it re-evaluates without retraining")
      ->check(within(1e-9, 1));
  cmd->add_option("--samples", args->options.samples,
                  "Denoised samples averaged per view (default: the preset's "
                  "diffusion.sampler_samples); re-evaluates without retraining")
      ->check(within(1, 1000));
  cmd->add_option("--fps-repeats", args->options.fps_repeats, "Timed render passes for FPS")
      ->check(within(0, 10000))
      ->capture_default_str();
  cmd->add_flag("--force", args->options.force,
                "Retrain rows whose folder holds a run of another configuration");
  return [args] {
    AblationOptions options = args->options;
    options.data = args->data;
    options.out = args->out;
    options.rows = select_rows(args->rows, "--rows");
    nlohmann::json ablation = run_ablation(options);
    if (ablation.is_null()) {
      core::log_info("interrupted; the same ddhgs ablate command continues where it stopped");
      return 130;
    }
    std::cout << ablation_markdown(ablation) << "wrote " << (options.out / "ablation.md").string()
              << " and " << (options.out / "ablation.json").string() << "\n";
    return 0;
  };
}

Registrar registrar("ablate", 55, setup);

}  // namespace cmd_ablate
}  // namespace ddhgs::app
