// What shapes a run's model: its colour model and rank, its bands, its SH
// degree and the networks and parameters trained beside the Gaussians
// (wavelength encoder, background, camera corrections, denoiser). A resumed
// run loads a checkpoint's tensors into the modules its config builds, so
// the two must agree on every one of these; otherwise the run would train
// one model while its config.json and its log describe another.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>

#include "io/scene/scene.h"
#include "train/checkpoint.h"
#include "train/run_config.h"

namespace ddhgs::train {

// What a checkpoint records beside its tensors (meta "model"): the config's
// settings that shape the model without fixing a tensor's shape on their own
// (the subspace rule, the encoder's and the denoiser's networks), and the
// wavelengths of the bands the run trained on.
nlohmann::json model_record(const RunConfig& config, const io::Scene& scene);

// Throws core::Error, one line naming the setting, its value in config_file,
// the checkpoint's and both files, unless config builds, for scene, the
// model the checkpoint holds.
void check_resumable(const SavedModel& saved, const RunConfig& config, const io::Scene& scene,
                     const std::filesystem::path& checkpoint,
                     const std::filesystem::path& config_file);

}  // namespace ddhgs::train
