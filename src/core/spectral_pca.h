// Principal components of spectra: how many dimensions a scene's spectra
// really span. Plant and material spectra lie close to a low-dimensional
// subspace; what lies beyond it is mostly sensor noise. `ddhgs info` reports
// the rank that keeps 99.9 % of the variance, and a subspace colour model
// starts its band basis from these components (model.spectral_rank).
#pragma once
#include "core/tensor.h"

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

// Per-band noise level of an image [H, W, N] (W >= 2): the median absolute
// difference of horizontally adjacent pixels over 0.6745 sqrt(2), the
// standard deviation of white noise, robust to the image's edges. Noise
// that grows with the signal (shot noise) is measured at every level: the
// pairs sorted by their level into kNoiseLevels equal shares, the median in
// each, and the root mean square of those. Pairs of two
// samples exactly 0 (a black backdrop) are left out. [N] float64.
torch::Tensor band_noise_sigma(const torch::Tensor& image);
constexpr int64_t kNoiseLevels = 8;

// The signal's rank however uneven the noise is across bands: the spectra
// with each band divided by its noise level (noise then has variance 1 in
// every direction, as in a minimum-noise-fraction transform), counting the
// components whose variance exceeds kWhitenedThreshold. spectra [M, N],
// noise_sigma [N] (bands without noise count as 1e-6 of the largest).
int64_t whitened_signal_rank(const torch::Tensor& spectra, const torch::Tensor& noise_sigma);
constexpr double kWhitenedThreshold = 2;

}  // namespace ddhgs::core
