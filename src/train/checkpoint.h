// Checkpoints: everything a run needs to continue bit-for-bit, written
// atomically. A LibTorch archive with a "meta" JSON string (format_version,
// iteration, counters), the Gaussians, the Adam state, densification
// statistics and any extra modules (wavelength encoder, denoiser) by name.
#pragma once
#include <torch/torch.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "model/adam.h"
#include "model/densify.h"
#include "model/gaussians.h"

namespace ddhgs::train {

constexpr int kCheckpointFormatVersion = 1;

struct TrainState {
  int64_t iteration = 0;  // iterations completed
  nlohmann::json meta;    // free-form counters (kept as written)
  model::Gaussians gaussians;
  model::Adam adam;
  model::DensifyStats stats;
  // Extra modules saved under "modules/<name>"; the caller registers them
  // (same names) before loading.
  std::vector<std::pair<std::string, std::shared_ptr<torch::nn::Module>>> modules;
};

void save_checkpoint(const std::filesystem::path& path, const TrainState& state);

// Fills state from the file. The Adam groups are created from the saved
// Gaussians with the saved learning rates; modules must be registered (same
// names) beforehand. Throws core::Error naming the file on a missing or
// malformed file, or one of another format_version.
void load_checkpoint(const std::filesystem::path& path, TrainState& state,
                     const model::AdamOptions& adam_options);

}  // namespace ddhgs::train
