#include "train/losses.h"

#include <cmath>

#include "core/stage_timer.h"
#include "model/ssim.h"
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

std::vector<LossTerm> baseline_losses(double l1_weight, double dssim_weight) {
  return {{"l1", l1_weight,
           [](const LossInputs& in) {
             core::StageScope stage("l1 forward");
             return train::l1_loss(in.render, in.target);
           }},
          {"dssim", dssim_weight, [](const LossInputs& in) {
             core::StageScope stage("ssim forward");
             return train::dssim_loss(in.render, in.target);
           }}};
}

double psnr(const torch::Tensor& render, const torch::Tensor& target) {
  const double mse = (render.detach() - target).pow(2).mean().item<double>();
  return 10.0 * std::log10(1.0 / std::max(mse, 1e-12));
}

LossTerm spectral_term(const nlohmann::json& loss_config) {
  SpectralLossOptions options;
  options.alpha = loss_config.at("spectral_alpha").get<double>();
  options.beta = loss_config.at("spectral_beta").get<double>();
  options.temperature = loss_config.at("spectral_temperature").get<double>();
  return {"spectral", loss_config.at("spectral").get<double>(),
          [options](const LossInputs& in) { return spectral_loss(in.render, in.target, options); }};
}

}  // namespace ddhgs::train
