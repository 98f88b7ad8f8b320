// Principal components of spectra: how many dimensions a scene's spectra
// really span. Plant and material spectra lie close to a low-dimensional
// subspace; what lies beyond it is mostly sensor noise. `ddhgs info` reports
// the rank that keeps 99.9 % of the variance, and a subspace colour model
// starts its band basis from these components (issue 30).
#pragma once
#include <torch/torch.h>

#include <vector>

namespace ddhgs::core {

struct SpectralPca {
  torch::Tensor mean;          // [N] float64, the mean spectrum
  torch::Tensor basis;         // [N, N] float64, orthonormal columns by decreasing variance
  std::vector<double> energy;  // [N] share of the variance per component; sums to 1 (all 0: none)

  int64_t bands() const { return int64_t(energy.size()); }
  // Share of the variance the first k components hold.
  double kept(int64_t k) const;
  // Smallest k whose components hold at least `share` of the variance (0
  // when the spectra do not vary at all).
  int64_t rank_for(double share) const;
  // Leading components that stand above the noise floor. Sensor noise
  // spreads evenly over every component, so with many bands the median
  // component's share estimates the floor; counts the leading components
  // holding more than kNoiseFactor times it, at most rank_for(0.999). With
  // fewer than kMinBandsForFloor bands there is no floor to see: rank_for(0.999).
  // (On the synthetic presets' noisy views 99.9 % needs 115 of 141
  // components, most of them noise; this gives 4, the clean cubes' own rank.)
  int64_t signal_rank() const;
  static constexpr double kNoiseFactor = 4;
  static constexpr int64_t kMinBandsForFloor = 8;
};

// spectra: [M, N] (M samples of N bands), any floating type, M >= 1.
// Computed in float64 from the N x N covariance about the mean.
SpectralPca spectral_pca(const torch::Tensor& spectra);

}  // namespace ddhgs::core
