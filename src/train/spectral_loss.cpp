#include "train/spectral_loss.h"

#include "core/error.h"

namespace ddhgs::train {

torch::Tensor spectral_loss(const torch::Tensor& pred, const torch::Tensor& gt,
                            const SpectralLossOptions& options) {
  core::require(pred.sizes() == gt.sizes(),
                "spectral loss: prediction and ground truth shapes differ");
  core::require(pred.dim() >= 1 && pred.size(-1) > 0, "spectral loss: no bands");
  core::require(options.temperature > 0, "spectral loss: temperature must be positive");
  const int64_t bands = pred.size(-1);
  auto log_p = torch::log_softmax(pred.reshape({-1, bands}) / options.temperature, 1);
  auto log_q = torch::log_softmax(gt.reshape({-1, bands}) / options.temperature, 1);
  auto p = log_p.exp();  // predicted distribution
  auto q = log_q.exp();  // ground-truth distribution
  auto kl = (q * (log_q - log_p)).sum(1);
  // Softmax outputs are strictly positive, so the norms never vanish.
  auto cos = (p * q).sum(1) / (p.norm(2, 1) * q.norm(2, 1));
  return (options.alpha * kl + options.beta * (1 - cos)).mean();
}

}  // namespace ddhgs::train
