// What a run leaves in its folder (train/run_folder.h): checkpoints, and at
// the end the PLY, train_summary.json, the denoiser and the learned
// background.
#include <cmath>
#include <vector>

#include "core/log.h"
#include "core/threads.h"
#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "train/diffusion_stage.h"
#include "train/model_shape.h"
#include "train/run_checks.h"
#include "train/trainer.h"

namespace ddhgs::train {

using nlohmann::json;

void Trainer::save(bool numbered) {
  require_finite_parameters(state_, run_.root);
  state_.model_record = model_record(config_, *scene_);
  save_checkpoint(run_.checkpoint(), state_);
  if (writer_) writer_->saved(state_.iteration);
  if (numbered) {
    io::copy_file_atomically(run_.checkpoint(), run_.checkpoint_at(state_.iteration));
  }
}

void Trainer::write_outputs(double seconds, const json& test_at_end) {
  // The encoder's offsets are added to the exported coefficients, so any
  // renderer of the PLY sees what training saw.
  torch::Tensor offsets;
  {
    torch::NoGradGuard no_grad;
    offsets = band_offsets();
  }
  io::write_gaussian_ply(run_.gaussians(),
                         model::to_ply(state_.gaussians, scene_->wavelengths_nm, offsets));
  const int64_t iterations = config_.iterations;
  const int degree = state_.gaussians.max_sh_degree();
  // Time of the Gaussian iterations alone (the denoiser's fine-tuning after
  // them is reported apart).
  const double gaussian_seconds =
      state_.counters.gaussian_seconds >= 0 ? state_.counters.gaussian_seconds : seconds;
  json summary = {
      {"iterations", iterations},
      {"seconds", seconds},
      {"iterations_per_second", gaussian_seconds > 0 ? double(iterations) / gaussian_seconds : 0.0},
      {"num_gaussians", state_.gaussians.size()},
      {"bands", scene_->bands()},
      {"sh_degree", degree},
      {"colour_channels", state_.gaussians.channels()},
      {"bytes_per_gaussian",
       model::training_bytes_per_gaussian(state_.gaussians.channels(), degree)},
      {"peak_rss_mib", peak_rss_mib()},
      {"threads", core::thread_count()},
      {"thread_source", core::thread_source()},
      {"densify_added", state_.counters.densify_added},
      {"densify_removed", state_.counters.densify_removed}};
  core::log_info("peak memory " +
                 std::to_string(std::llround(summary["peak_rss_mib"].get<double>())) +
                 " MiB resident (train_summary.json: peak_rss_mib)");
  if (block_)
    summary["block"] = {{"name", block_->name},
                        {"flight_train_views", block_->flight_train_views},
                        {"own_train_views", int64_t(scene_->train.size())},
                        {"flight_extent", extent_}};
  if (offsets.defined()) {
    // How far the encoder moved the SH coefficients, to judge its effect.
    summary["wavelength_offsets_abs_max"] = offsets.abs().max().item<double>();
    summary["wavelength_offsets_rms"] = offsets.pow(2).mean().sqrt().item<double>();
  }
  if (diffusion_ && diffusion_->options().finetune_steps > 0) {
    summary["denoiser_finetune_steps"] = diffusion_->options().finetune_steps;
    // Everything after the Gaussian iterations: auxiliary models, fine-tuning
    // and distillation.
    summary["denoiser_finetune_seconds"] = seconds - gaussian_seconds;
  }
  if (stage_) summary.update(stage_->summary());
  if (exposure_) {
    const json gains = exposure_summary(*exposure_, *scene_);
    core::log_info(describe_exposure(gains));
    summary.update(gains);
  }
  summary.update(test_at_end.is_null() ? test_psnr() : test_at_end);
  if (rig_refinement_)
    summary["rig_corrections"] = rig_refinement_->report(*scene_, extent_, run_.rig_corrections());
  if (diffusion_) write_denoiser(denoiser_path(run_), diffusion_->denoiser());
  if (background_module_ || config_.model.background_from_views) {
    // eval, render and report take it from here (config.json stays as the
    // run was configured, so the run can be reproduced from it).
    auto values = background_.detach().contiguous();
    json learned = {{"background", std::vector<float>(values.data_ptr<float>(),
                                                      values.data_ptr<float>() + values.numel())}};
    io::write_file_atomically(run_.learned_background(), learned.dump(2) + "\n");
  }
  // The run's own copy of where its frame lies on the earth, for
  // `render --ortho` and for whoever moves the run without its scene.
  if (scene_->georef) io::write_georeference(run_.georef(), *scene_->georef);
  io::write_file_atomically(run_.summary(), summary.dump(2) + "\n");
}

}  // namespace ddhgs::train
