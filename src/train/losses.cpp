#include "train/losses.h"

#include <cmath>

#include "core/parallel.h"
#include "core/stage_timer.h"
#include "model/ssim.h"
#include "model/ssim_fused.h"
#include "train/spectral_loss.h"

namespace ddhgs::train {

LossValues evaluate_losses(const std::vector<LossTerm>& terms, const LossInputs& inputs) {
  LossValues values;
  for (const auto& term : terms) {
    if (term.weight == 0) continue;
    torch::Tensor v = term.compute(inputs);
    values.terms.emplace_back(term.name, v.item<double>());
    values.total = values.total.defined() ? values.total + term.weight * v : term.weight * v;
  }
  if (!values.total.defined()) values.total = inputs.render.sum() * 0;
  return values;
}

torch::Tensor l1_loss(const torch::Tensor& render, const torch::Tensor& target) {
  return (render - target).abs().mean();
}

torch::Tensor dssim_loss(const torch::Tensor& render, const torch::Tensor& target) {
  return 1 - model::ssim(render, target);
}

namespace {

// "l1" or "ssim" of the fused pass over the inputs, run once per evaluation.
torch::Tensor fused(const LossInputs& in, const std::string& which) {
  if (!in.shared.count(which)) {
    const model::PhotometricValues v = model::l1_and_ssim(in.render, in.target);
    in.shared["l1"] = v.l1;
    in.shared["ssim"] = v.ssim;
  }
  return in.shared.at(which);
}

// Sum of squared differences of two contiguous float32 tensors, in double.
// Fixed 64k-element chunks added in order: the same bits for any thread count.
double squared_error_sum(const float* a, const float* b, int64_t n) {
  constexpr int64_t kChunk = 1 << 16;
  std::vector<double> partial(size_t((n + kChunk - 1) / kChunk), 0.0);
  core::parallel_for(0, int64_t(partial.size()), 1, [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c) {
      double sum = 0;
      for (int64_t i = c * kChunk, e = std::min(n, i + kChunk); i < e; ++i) {
        const double d = double(a[i]) - double(b[i]);
        sum += d * d;
      }
      partial[size_t(c)] = sum;
    }
  });
  double total = 0;
  for (double p : partial) total += p;
  return total;
}

}  // namespace

std::vector<LossTerm> baseline_losses(double l1_weight, double dssim_weight) {
  // Without the SSIM term the fused pass would compute it for nothing.
  if (dssim_weight == 0)
    return {{"l1", l1_weight,
             [](const LossInputs& in) {
               core::StageScope stage("l1 forward");
               return train::l1_loss(in.render, in.target);
             }},
            {"dssim", dssim_weight, [](const LossInputs& in) {
               core::StageScope stage("ssim forward");
               return train::dssim_loss(in.render, in.target);
             }}};
  return {{"l1", l1_weight, [](const LossInputs& in) { return fused(in, "l1"); }},
          {"dssim", dssim_weight, [](const LossInputs& in) { return 1 - fused(in, "ssim"); }}};
}

double psnr(const torch::Tensor& render, const torch::Tensor& target) {
  double mse = 0;
  if (render.scalar_type() == torch::kFloat32 && target.scalar_type() == torch::kFloat32 &&
      render.is_contiguous() && target.is_contiguous() && render.sizes() == target.sizes() &&
      render.numel() > 0) {
    mse = squared_error_sum(render.data_ptr<float>(), target.data_ptr<float>(), render.numel()) /
          double(render.numel());
  } else {
    mse = (render.detach() - target).pow(2).mean().item<double>();
  }
  return 10.0 * std::log10(1.0 / std::max(mse, 1e-12));
}

LossTerm spectral_term(double weight, const SpectralLossOptions& options) {
  return {"spectral", weight,
          [options](const LossInputs& in) { return spectral_loss(in.render, in.target, options); }};
}

}  // namespace ddhgs::train
