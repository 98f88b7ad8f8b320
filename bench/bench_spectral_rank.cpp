// How much of a scene's spectra a rank-K subspace keeps, and how much noise
// it drops: the noisy views projected onto the first K principal
// components of their own pixels, measured against the clean cubes, over all
// bands and over the 10 % of bands with the lowest SNR. An upper bound of
// what a subspace colour model can gain from its rank alone (a model also
// has to fit the views in 3D).
// Run: build/bench/bench_spectral_rank SCENE_WITH_CLEAN_CUBES [K ...]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "core/spectral_pca.h"
#include "core/threads.h"
#include "io/scene/scene.h"
#include "io/scene/scene_report.h"

namespace {
using namespace ddhgs;

// Per-band mean squared error of `x` against `clean`, over views: [N].
torch::Tensor band_mse(const std::vector<torch::Tensor>& x,
                       const std::vector<torch::Tensor>& clean) {
  torch::Tensor sum = torch::zeros({x.front().size(-1)}, torch::kFloat64);
  for (size_t i = 0; i < x.size(); ++i)
    sum += (x[i].to(torch::kFloat64) - clean[i].to(torch::kFloat64))
               .pow(2)
               .reshape({-1, sum.size(0)})
               .mean(0);
  return sum / double(x.size());
}

double psnr(const torch::Tensor& mse) {
  return (-10 * torch::log10(mse.clamp_min(1e-20))).mean().item<double>();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_spectral_rank SCENE_WITH_CLEAN_CUBES [K ...]\n");
    return 2;
  }
  core::configure_threads(0);
  io::LoadOptions options;
  auto scene = io::load_scene(argv[1], options);
  std::vector<int64_t> ranks;
  for (int i = 2; i < argc; ++i) ranks.push_back(std::atoll(argv[i]));
  if (ranks.empty()) ranks = {2, 3, 4, 6, 8, 12, 16, 32};
  const io::SpectraSample sample = io::sample_spectra(*scene, 8);
  const core::SpectralPca pca = core::spectral_pca(sample.spectra);
  const int64_t n = pca.bands();

  // Held-out views (or the first 4 training views), noisy and clean.
  std::vector<int> views = scene->test;
  if (views.empty())
    views.assign(scene->train.begin(),
                 scene->train.begin() + std::min<size_t>(4, scene->train.size()));
  std::vector<torch::Tensor> noisy, clean;
  for (int v : views) {
    noisy.push_back(scene->image(v));
    clean.push_back(scene->clean_image(v));
    if (!clean.back().defined()) {
      std::fprintf(stderr, "%s: view %d has no clean cube\n", argv[1], v);
      return 1;
    }
  }
  // Per-band SNR: the clean signal's variance over the noise's.
  torch::Tensor signal = torch::zeros({n}, torch::kFloat64);
  for (const auto& c : clean) signal += c.to(torch::kFloat64).reshape({-1, n}).var(0);
  const torch::Tensor noise_mse = band_mse(noisy, clean);
  const torch::Tensor snr = signal / double(clean.size()) / noise_mse.clamp_min(1e-20);
  const int64_t worst_count = std::max<int64_t>(1, n / 10);
  const torch::Tensor worst = snr.argsort().slice(0, 0, worst_count);

  std::printf(
      "%s: %lld bands, signal rank %lld (whitened: %lld), %zu views; PSNR against the clean "
      "cubes (dB)\n",
      argv[1], (long long)n, (long long)pca.signal_rank(),
      (long long)core::whitened_signal_rank(sample.spectra, sample.noise_sigma), views.size());
  std::printf(
      "| rank | variance kept | all bands | lowest-SNR %lld bands |\n| --- | --- | --- | --- |\n",
      (long long)worst_count);
  std::printf("| views as captured | 100 %% | %.2f | %.2f |\n", psnr(noise_mse),
              psnr(noise_mse.index_select(0, worst)));
  const torch::Tensor mean = pca.mean.to(torch::kFloat32);
  for (int64_t k : ranks) {
    if (k < 1 || k > n) continue;
    const torch::Tensor u = pca.basis.slice(1, 0, k).to(torch::kFloat32);  // [N, K]
    std::vector<torch::Tensor> projected;
    for (const auto& x : noisy) {
      const torch::Tensor flat = x.reshape({-1, n}) - mean;
      projected.push_back((flat.matmul(u).matmul(u.t()) + mean).reshape(x.sizes()));
    }
    const torch::Tensor mse = band_mse(projected, clean);
    std::printf("| %lld | %.4f %% | %.2f | %.2f |\n", (long long)k, 100 * pca.kept(k), psnr(mse),
                psnr(mse.index_select(0, worst)));
  }
  return 0;
}
