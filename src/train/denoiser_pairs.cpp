#include "train/denoiser_pairs.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "train/novel_views.h"
#include "train/seed.h"
#include "train/stop_signal.h"

namespace ddhgs::train {

std::map<int, torch::Tensor> pair_renders(StageHost& host, const DiffusionTermOptions& o) {
  const io::Scene& scene = host.scene();
  const RunConfig& config = host.config();
  const std::vector<std::vector<int>> groups = o.pairs == FinetunePairs::Folds
                                                   ? interleaved_folds(scene.train, int(o.folds))
                                                   : std::vector<std::vector<int>>{scene.train};
  RunConfig aux = config;
  const int64_t steps =
      std::max<int64_t>(1, std::llround(o.fold_iterations * double(config.iterations)));
  // An earlier checkpoint keeps the run's schedule and seed and stops early.
  if (o.pairs != FinetunePairs::Checkpoint) aux.iterations = steps;
  aux.diffusion.weight = 0;  // an auxiliary model has no denoiser of its own
  std::map<int, torch::Tensor> renders;
  const auto start = std::chrono::steady_clock::now();
  for (size_t f = 0; f < groups.size(); ++f) {
    if (o.pairs != FinetunePairs::Checkpoint) aux.seed = mix_seed(config.seed, kFoldStream + f);
    const std::vector<int> held_out =
        o.pairs == FinetunePairs::Folds ? groups[f] : std::vector<int>{};
    const double perturb_px = o.pairs == FinetunePairs::Perturbed ? o.perturb_px : 0.0;
    std::unique_ptr<AuxiliaryModel> model = host.auxiliary(aux, held_out, perturb_px);
    const int64_t n = std::min(steps, aux.iterations);
    const std::string label =
        o.pairs == FinetunePairs::Folds
            ? "fold " + std::to_string(f + 1) + "/" + std::to_string(groups.size())
            : to_string(o.pairs);
    core::ProgressBar bar(label, n);
    for (int64_t i = 0; i < n; ++i) {
      if (stop_requested())
        throw core::Error(host.run_paths().root, "interrupted while training the auxiliary models");
      model->advance();
      bar.update(i + 1);
    }
    bar.finish();
    // At the views' own poses (the main scene's cameras: a perturbed model's
    // are turned).
    for (int v : groups[f]) renders[v] = model->render(scene.views[size_t(v)].camera);
  }
  std::string who;
  if (o.pairs == FinetunePairs::Folds)
    who = std::to_string(groups.size()) + " auxiliary models that never saw them (" +
          std::to_string(steps) + " iterations each";
  else if (o.pairs == FinetunePairs::Checkpoint)
    who = "the Gaussians as they were at iteration " + std::to_string(steps) + " (recomputed";
  else {
    char px[32];
    std::snprintf(px, sizeof px, "%g", o.perturb_px);
    who = "a model trained on them with each camera turned by " + std::string(px) + " px (" +
          std::to_string(steps) + " iterations";
  }
  core::log_info(
      "denoiser pairs: " + std::to_string(renders.size()) + " training views rendered by " + who +
      ", " +
      core::format_duration(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()) +
      ")");
  return renders;
}

}  // namespace ddhgs::train
