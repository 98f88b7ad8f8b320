// Training losses: a weighted list of named terms, so later components (the
// spectral loss, the diffusion term) join by appending a term.
#pragma once
#include "core/tensor.h"

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "train/spectral_loss.h"

namespace ddhgs::train {

struct LossInputs {
  const torch::Tensor& render;  // [H, W, N] differentiable
  const torch::Tensor& target;  // [H, W, N]
  int view;                     // index into Scene::views
  int64_t iteration;            // 1-based
  // Seed for a term's own randomness (crops, noise), a function of the run's
  // seed and the iteration only, so a resumed run draws what a straight one would.
  uint64_t seed = 0;
  // Values several terms share, filled by the first term that needs them
  // during one evaluate_losses call (the L1 and SSIM of one fused pass).
  mutable std::map<std::string, torch::Tensor> shared = {};
};

struct LossTerm {
  std::string name;  // key in metrics.jsonl
  double weight;
  std::function<torch::Tensor(const LossInputs&)> compute;  // unweighted, 0-d
};

struct LossValues {
  torch::Tensor total;                                // 0-d, differentiable
  std::vector<std::pair<std::string, double>> terms;  // unweighted values
};

// Sums weight * term over the terms whose weight is not zero.
LossValues evaluate_losses(const std::vector<LossTerm>& terms, const LossInputs& inputs);

// Mean absolute error over every pixel and band (LibTorch ops; the reference
// twin of the fused pass the baseline terms use).
torch::Tensor l1_loss(const torch::Tensor& render, const torch::Tensor& target);
// 1 - SSIM (model/ssim.h) over all bands (LibTorch ops, likewise).
torch::Tensor dssim_loss(const torch::Tensor& render, const torch::Tensor& target);
// The 3DGS baseline terms: "l1" and "dssim" with the given weights. With a
// non-zero dssim weight both come from one fused pass (model/ssim_fused.h),
// which needs a target that does not require a gradient.
std::vector<LossTerm> baseline_losses(double l1_weight, double dssim_weight);

// The DD-HGS spectral term "spectral" (train/spectral_loss.h) with its weight
// (loss.spectral) and options.
LossTerm spectral_term(double weight, const SpectralLossOptions& options);

// 10 log10(1 / MSE) over all elements, data range 1 (dB). Reads the two
// tensors in place when they are contiguous float32 (no temporaries).
double psnr(const torch::Tensor& render, const torch::Tensor& target);

}  // namespace ddhgs::train
