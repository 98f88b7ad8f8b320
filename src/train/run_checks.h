// Checks that make a run fail at its start rather than after hours of
// training: every view and clean file the run will read is probed before the
// first iteration, and a run that diverges (a NaN or Inf loss or parameter)
// stops at once instead of writing a model full of NaN.
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>

#include "io/scene/scene.h"
#include "train/checkpoint.h"

namespace ddhgs::train {

// core::Error naming the first file that would fail to load: every view's and
// clean file's header (band count, size, truncation), and every held-out view
// read in full, as the end of training will read it. Logs that test metrics
// will be missing when the scene holds no held-out views.
void check_scene_before_training(const io::Scene& scene);

// core::Error naming the run folder when a number in an iteration's record
// (loss, PSNR, ...) is NaN or Inf: training has diverged.
void require_finite_record(const nlohmann::json& record, const std::filesystem::path& run);

// core::Error naming the run folder when a Gaussian or module parameter holds
// NaN or Inf; called before every checkpoint, so none holds them.
void require_finite_parameters(const TrainState& state, const std::filesystem::path& run);

}  // namespace ddhgs::train
