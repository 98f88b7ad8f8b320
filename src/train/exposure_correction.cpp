#include "train/exposure_correction.h"

#include <algorithm>
#include <cstdio>
#include <vector>

#include "core/error.h"

namespace ddhgs::train {

ExposureCorrectionImpl::ExposureCorrectionImpl(const torch::Tensor& trained) {
  core::require(trained.dim() == 2 && trained.any().item<bool>(),
                "exposure correction: no trained view bands");
  log_gain = register_parameter("log_gain", torch::zeros(trained.sizes()));
  trained_ = trained.to(torch::kFloat32);
}

torch::Tensor ExposureCorrectionImpl::apply(int view, const torch::Tensor& render,
                                            const torch::Tensor& bands) const {
  torch::Tensor row = log_gain[view];  // [N]
  if (bands.defined()) row = row.index_select(0, bands);
  return render * row.exp();  // broadcast over [H, W, B]
}

torch::Tensor ExposureCorrectionImpl::prior(int view) const {
  const torch::Tensor held = trained_[view].to(log_gain.scalar_type());
  return (log_gain[view].pow(2) * held).sum() / held.sum().clamp_min(1);
}

void ExposureCorrectionImpl::recentre() {
  torch::NoGradGuard no_grad;
  const torch::Tensor held = trained_.to(log_gain.scalar_type());
  const torch::Tensor mean = (log_gain * held).sum(0) / held.sum(0).clamp_min(1);  // [N]
  log_gain.sub_(held * mean);
}

torch::Tensor ExposureCorrectionImpl::gains() const {
  return log_gain.detach().exp();
}

torch::Tensor trained_entries(const io::Scene& scene) {
  torch::Tensor trained = torch::zeros({int64_t(scene.views.size()), scene.bands()}, torch::kBool);
  for (int v : scene.train) {
    const torch::Tensor bands = scene.view_bands(v);
    if (bands.defined())
      trained[v].index_fill_(0, bands, true);
    else
      trained[v].fill_(true);
  }
  return trained;
}

nlohmann::json exposure_summary(const ExposureCorrectionImpl& exposure, const io::Scene& scene) {
  const torch::Tensor gains = exposure.gains().to(torch::kFloat64);
  nlohmann::json per_view = nlohmann::json::object();
  double low = 0, high = 0;
  bool first = true;
  for (int v : scene.train) {
    const torch::Tensor bands = scene.view_bands(v);
    const torch::Tensor row = bands.defined() ? gains[v].index_select(0, bands) : gains[v];
    std::vector<double> values(row.data_ptr<double>(), row.data_ptr<double>() + row.numel());
    for (double g : values) {
      low = first ? g : std::min(low, g);
      high = first ? g : std::max(high, g);
      first = false;
    }
    per_view[scene.views[size_t(v)].name] = values;
  }
  return {{"exposure_gain_min", low}, {"exposure_gain_max", high}, {"exposure_gains", per_view}};
}

std::string describe_exposure(const nlohmann::json& summary) {
  size_t entries = 0;
  for (const auto& [name, values] : summary.at("exposure_gains").items()) entries += values.size();
  char text[256];
  std::snprintf(text, sizeof text,
                "exposure correction: gains %.3f-%.3f over %zu training view bands (training "
                "only: renders and exports are not corrected)",
                summary.at("exposure_gain_min").get<double>(),
                summary.at("exposure_gain_max").get<double>(), entries);
  return text;
}

}  // namespace ddhgs::train
