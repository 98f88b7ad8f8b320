// The denoiser's training pairs from auxiliary models (diffusion.pairs folds,
// checkpoint or perturbed; train/novel_views.h says why): each training view
// rendered by a model that did not fit it, beside the view's capture.
#pragma once
#include <map>

#include "core/tensor.h"
#include "train/diffusion_term.h"
#include "train/stage_host.h"

namespace ddhgs::train {

// Each training view of host's scene [H, W, N] rendered by the auxiliary
// model(s) that diffusion.pairs names, by view index: folds, one model per
// fold rendering the fold it left out; checkpoint and perturbed, one model
// rendering every training view. Logs where the renders came from; throws
// when a stop is asked for (train/stop_signal.h) while the models train.
std::map<int, torch::Tensor> pair_renders(StageHost& host, const DiffusionTermOptions& options);

}  // namespace ddhgs::train
