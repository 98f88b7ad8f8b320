// A finished training run opened for `ddhgs eval` and `ddhgs render`: its
// resolved config, its dataset (loaded as it was for training) and its final
// Gaussians, with the checks that they belong together.
#pragma once
#include <torch/torch.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <string>

#include "io/dataset.h"
#include "model/gaussians.h"

namespace ddhgs::app {

struct TrainedRun {
  std::filesystem::path root;
  nlohmann::json config;
  std::unique_ptr<io::Scene> scene;
  model::Gaussians gaussians;
  torch::Tensor background;  // [N]
};

// data_override: a dataset folder to use instead of the config's data.path
// (for a run folder copied to another machine). Throws core::Error naming the
// file when the folder is not a run, its config is of another format_version,
// gaussians.ply is missing or malformed, the dataset is missing, or the model
// and dataset disagree in bands or wavelengths.
TrainedRun open_trained_run(const std::filesystem::path& run_dir,
                            const std::string& data_override = "");

}  // namespace ddhgs::app
