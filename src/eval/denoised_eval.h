// Evaluation of a run's diffusion denoiser (DD-HGS inference): each view is
// rendered, then denoised by the reverse process conditioned on the render,
// once per sampler setting (DDIM with K steps, or DDPM); metrics against the
// stored views and clean ground truth as for the raw render, and the time per
// denoised frame (render + sampling).
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "eval/evaluate.h"
#include "model/diffusion.h"

namespace ddhgs::eval {

struct DenoiseSetting {
  std::string name;  // "ddim10", "ddpm"
  model::SamplerOptions sampler;
};

// One DDIM setting per K in ddim_steps, then DDPM when `ddpm`; all share
// `base`'s eta, start strength and seed.
std::vector<DenoiseSetting> denoise_settings(const std::vector<int64_t>& ddim_steps, bool ddpm,
                                             const model::SamplerOptions& base);

struct DenoisedResult {
  DenoiseSetting setting;
  std::vector<ViewResult> per_view;        // in view order, stored before clean
  ImageMetrics mean;                       // against the stored views
  std::optional<ImageMetrics> mean_clean;  // against clean ground truth
  double denoise_ms = 0;                   // mean sampling time per frame
};

struct DenoisedReport {
  std::string split;
  int views = 0;
  double render_ms = 0;  // mean render time per frame in the same pass
  std::vector<DenoisedResult> results;
  // Frames per second of render + denoise for one setting.
  double fps(const DenoisedResult& r) const {
    return render_ms + r.denoise_ms > 0 ? 1000.0 / (render_ms + r.denoise_ms) : 0;
  }
};

// Renders each view once and denoises it with every setting; one untimed
// warm-up denoise precedes the timed ones.
DenoisedReport evaluate_denoised(const io::Scene& scene, const model::Gaussians& gaussians,
                                 const torch::Tensor& background,  // [N]
                                 model::Denoiser& denoiser, const std::vector<int>& views,
                                 const std::string& split_name,
                                 const std::vector<DenoiseSetting>& settings);

nlohmann::json denoised_json(const DenoisedReport& report);
// Atomic writers: RUN/eval/denoised.json and a per-view CSV with a setting column.
void write_denoised_json(const std::filesystem::path& path, const DenoisedReport& report);
void write_denoised_csv(const std::filesystem::path& path, const DenoisedReport& report);
// A short table, one row per setting and truth.
std::string format_denoised(const DenoisedReport& report);

}  // namespace ddhgs::eval
