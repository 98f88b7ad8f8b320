// A finished training run opened for `ddhgs eval` and `ddhgs render`: its
// resolved config, its dataset (loaded as it was for training) and its final
// Gaussians, with the checks that they belong together.
#pragma once
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "core/tensor.h"
#include "io/ply/ply.h"
#include "io/scene/scene.h"
#include "model/diffusion.h"
#include "model/gaussians.h"
#include "train/run_config.h"

namespace ddhgs::app {

struct TrainedRun {
  std::filesystem::path root;
  train::RunConfig config;  // RUN/config.json
  std::unique_ptr<io::Scene> scene;
  model::Gaussians gaussians;
  torch::Tensor background;  // [N]
  // RUN/denoiser.pt when the run trained the diffusion term, with the
  // sampler defaults of its config (diffusion.sampler_steps, start_strength, eta).
  std::optional<model::Denoiser> denoiser;
  model::SamplerOptions sampler;
};

// --start-strength, --eta and --samples, shared by `ddhgs eval` and `ddhgs render`.
struct SamplerFlags {
  double start_strength = 0, eta = 0;
  int64_t samples = 1;
  CLI::Option* start_strength_option = nullptr;
  CLI::Option* eta_option = nullptr;
  CLI::Option* samples_option = nullptr;
};
void add_sampler_flags(CLI::App* cmd, SamplerFlags& flags);
// The run's sampler defaults (TrainedRun::sampler) with the flags that were given.
model::SamplerOptions sampler_options(const TrainedRun& run, const SamplerFlags& flags);

// A run's model without its dataset, for commands that need no views
// (`ddhgs export`): the resolved config, gaussians.ply and the background
// the run rendered with (learned or configured). core::Error naming the file
// when the folder is not a run or a file is missing or malformed.
struct RunModel {
  std::filesystem::path root;
  train::RunConfig config;
  io::GaussianPly ply;
  torch::Tensor background;  // [N]
};
RunModel open_run_model(const std::filesystem::path& run_dir);

// data_override: a dataset folder to use instead of the config's data.path
// (for a run folder copied to another machine). Throws core::Error naming the
// file when the folder is not a run, its config is of another format_version,
// gaussians.ply is missing or malformed, the dataset is missing, or the model
// and dataset disagree in bands or wavelengths, or denoiser.pt is unreadable
// or made for another band count.
TrainedRun open_trained_run(const std::filesystem::path& run_dir,
                            const std::string& data_override = "");

}  // namespace ddhgs::app
