// Checkpoints: everything a run needs to continue bit-for-bit, written
// atomically. A LibTorch archive with a "meta" JSON string (format_version,
// iteration, RunCounters), the Gaussians, the Adam state, densification
// statistics and any extra modules (wavelength encoder, denoiser) by name.
#pragma once
#include <torch/nn/module.h>
#include <torch/serialize/archive.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/tensor.h"
#include "model/adam.h"
#include "model/densify.h"
#include "model/gaussians.h"

namespace ddhgs::train {

constexpr int kCheckpointFormatVersion = 1;

// A network trained beside the Gaussians (wavelength encoder, denoiser). Its
// parameters are groups "<name>/<parameter>" of the run's Adam optimizer at
// lr (stepped only when they received a gradient), and the module is saved
// under "modules/<name>".
struct TrainedModule {
  std::string name;
  std::shared_ptr<torch::nn::Module> module;
  double lr = 0;
};

// Counters that run on across resumes (in the checkpoint's meta record).
struct RunCounters {
  int64_t densify_added = 0, densify_removed = 0;  // Gaussians, over the run
  double seconds = 0;                              // wall time of the run so far
  // Wall time of the Gaussian iterations, once they are done; < 0 before.
  double gaussian_seconds = -1;
};

struct TrainState {
  int64_t iteration = 0;  // iterations completed
  RunCounters counters;
  model::Gaussians gaussians;
  model::Adam adam;
  model::DensifyStats stats;
  // The caller registers them (same names) before loading.
  std::vector<TrainedModule> modules;
  // What shapes the model beyond its tensors (train/model_shape.h), saved in
  // the meta record as "model"; null when unknown.
  nlohmann::json model_record;
};

// A checkpoint's model as its tensors give it, with its meta record "model"
// (null in checkpoints of older ddhgs versions).
struct SavedModel {
  int64_t bands = 0;                 // N
  int64_t rank = 0;                  // latent channels K; 0: one SH set per band
  int sh_degree = 0;                 // of sh_rest
  std::vector<std::string> modules;  // the trained modules' names
  nlohmann::json record;
};

// A checkpoint read into memory, its meta record checked (format_version).
struct CheckpointFile {
  std::filesystem::path path;
  torch::serialize::InputArchive archive;
  nlohmann::json meta;
};

// Registers the module's parameters as Adam groups "<name>/<parameter>".
void add_module_groups(model::Adam& adam, const TrainedModule& module);
// Sets the learning rate of those groups to scale x module.lr.
void scale_module_rate(model::Adam& adam, const TrainedModule& module, double scale);

// A LibTorch archive written atomically, through a sink: LibTorch's own file
// writer ends the process when the disk is full.
void write_archive(const std::filesystem::path& path, torch::serialize::OutputArchive& archive);
// Reads path into archive; core::Error(path, unreadable) when LibTorch
// cannot (a truncated or foreign file).
void read_archive(const std::filesystem::path& path, torch::serialize::InputArchive& archive,
                  const std::string& unreadable);

void save_checkpoint(const std::filesystem::path& path, const TrainState& state);

// Throws core::Error naming the file on a missing or malformed file, or one
// of another format_version.
CheckpointFile open_checkpoint(const std::filesystem::path& path);

// The shapes of the checkpoint's model, read before anything is built from it.
SavedModel saved_model(CheckpointFile& file);

// Fills state from the file. The Adam groups are created from the saved
// Gaussians and the registered modules, with the saved learning rates and
// moments; modules must be registered (same names) beforehand. Throws core::Error naming the file
// on a missing or malformed file, or one of another format_version.
void load_checkpoint(CheckpointFile& file, TrainState& state,
                     const model::AdamOptions& adam_options);
void load_checkpoint(const std::filesystem::path& path, TrainState& state,
                     const model::AdamOptions& adam_options);

}  // namespace ddhgs::train
