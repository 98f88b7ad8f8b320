#include "core/spectral_pca.h"

#include <torch/linalg.h>
#include <algorithm>

#include "core/error.h"

namespace ddhgs::core {

namespace {

// Covariance about the mean of float64 samples x [M, N]: [N, N].
torch::Tensor covariance(const torch::Tensor& x) {
  const torch::Tensor centred = x - x.mean(0);
  return centred.t().matmul(centred) / double(x.size(0));
}

}  // namespace

double SpectralPca::kept(int64_t k) const {
  double sum = 0;
  for (int64_t i = 0; i < std::min<int64_t>(k, bands()); ++i) sum += energy[size_t(i)];
  return std::min(sum, 1.0);
}

int64_t SpectralPca::rank_for(double share) const {
  double sum = 0;
  for (int64_t i = 0; i < bands(); ++i) {
    if (sum >= share) return i;
    sum += energy[size_t(i)];
  }
  return sum > 0 ? bands() : 0;
}

int64_t SpectralPca::signal_rank() const {
  const int64_t cap = rank_for(0.999);
  if (bands() < kMinBandsForFloor) return cap;
  std::vector<double> sorted = energy;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double floor = sorted[sorted.size() / 2];
  int64_t k = 0;
  while (k < cap && energy[size_t(k)] > kNoiseFactor * floor) ++k;
  return k;
}

SpectralPca spectral_pca(const torch::Tensor& spectra) {
  require(spectra.dim() == 2 && spectra.size(0) >= 1 && spectra.size(1) >= 1,
          "spectral_pca: expected spectra [M, N] with M, N >= 1");
  const torch::Tensor x = spectra.to(torch::kFloat64);
  SpectralPca pca;
  pca.mean = x.mean(0);
  auto [values, vectors] = torch::linalg::eigh(covariance(x), "L");  // ascending
  values = values.flip(0).clamp_min(0);
  pca.basis = vectors.flip(1).contiguous();
  // A deterministic sign: each component's largest entry is positive.
  const torch::Tensor largest = pca.basis.abs().argmax(0);
  const torch::Tensor sign =
      pca.basis.gather(0, largest.unsqueeze(0)).squeeze(0).sign().clamp_min(0) * 2 - 1;
  pca.basis = pca.basis * sign;
  const double total = values.sum().item<double>();
  pca.energy.assign(size_t(values.size(0)), 0.0);
  if (total > 0)
    for (int64_t i = 0; i < values.size(0); ++i)
      pca.energy[size_t(i)] = values[i].item<double>() / total;
  return pca;
}

torch::Tensor band_noise_sigma(const torch::Tensor& image) {
  require(image.dim() == 3 && image.size(1) >= 2, "band_noise_sigma: expected an image [H, W, N]");
  const torch::Tensor x = image.to(torch::kFloat64);
  const torch::Tensor right = x.slice(1, 1, x.size(1)).reshape({-1, x.size(2)});
  const torch::Tensor left = x.slice(1, 0, x.size(1) - 1).reshape({-1, x.size(2)});
  const torch::Tensor diff = (right - left).abs();
  const torch::Tensor level = right + left;
  // Two black neighbours (a backdrop masked to 0, noise clipped there) show
  // no noise: on a view that is mostly backdrop they would make the median 0.
  const torch::Tensor live = (right != 0) | (left != 0);
  const double to_sigma = 1 / (0.6745 * std::sqrt(2.0));
  torch::Tensor sigma = torch::zeros({x.size(2)}, torch::kFloat64);
  for (int64_t n = 0; n < x.size(2); ++n) {
    const torch::Tensor mask = live.select(1, n);
    const torch::Tensor d = diff.select(1, n).masked_select(mask);
    const int64_t m = d.numel();
    if (m == 0) continue;
    // Shot noise grows with the signal: the median pair of a view that is
    // mostly dim backdrop would give the backdrop's level, several times
    // below the lit object's. The pairs sorted by level into kNoiseLevels
    // equal shares, the median in each, and their root mean square: the
    // noise the view's pixels carry on average (white noise: the median).
    const int64_t shares = m >= 16 * kNoiseLevels ? kNoiseLevels : 1;
    const torch::Tensor sorted =
        d.index_select(0, level.select(1, n).masked_select(mask).argsort());
    double sum = 0;
    for (int64_t i = 0; i < shares; ++i) {
      const torch::Tensor share = sorted.slice(0, i * m / shares, (i + 1) * m / shares);
      const double s = std::get<0>(share.median(0)).item<double>() * to_sigma;
      sum += s * s;
    }
    sigma[n] = std::sqrt(sum / double(shares));
  }
  return sigma;
}

int64_t whitened_signal_rank(const torch::Tensor& spectra, const torch::Tensor& noise_sigma) {
  require(spectra.dim() == 2 && noise_sigma.dim() == 1 && noise_sigma.size(0) == spectra.size(1),
          "whitened_signal_rank: expected spectra [M, N] and noise_sigma [N]");
  const torch::Tensor sigma = noise_sigma.to(torch::kFloat64);
  const double top = sigma.max().item<double>();
  if (!(top > 0)) return spectral_pca(spectra).rank_for(0.999);  // no noise to whiten by
  const torch::Tensor x = spectra.to(torch::kFloat64) / sigma.clamp_min(1e-6 * top);
  const torch::Tensor values = torch::linalg::eigvalsh(covariance(x), "L");
  return (values > kWhitenedThreshold).sum().item<int64_t>();
}

}  // namespace ddhgs::core
