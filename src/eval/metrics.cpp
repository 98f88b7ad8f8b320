#include "eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/tensor_values.h"

namespace ddhgs::eval {
namespace {

constexpr double kMinMse = 1e-10;  // 10 log10(1 / 1e-10) = kMaxPsnrDb
constexpr int kWindow = 11;        // SSIM window side, pixels
constexpr double kSigma = 1.5;     // SSIM window standard deviation, pixels
constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;

std::string shape_string(const torch::Tensor& t) {
  std::ostringstream s;
  s << t.sizes();
  return s.str();
}

void require_comparable(const torch::Tensor& pred, const torch::Tensor& gt) {
  core::require(pred.defined() && gt.defined(), "metrics: an image is missing");
  core::require(pred.dim() == 3 && gt.dim() == 3 && pred.sizes() == gt.sizes(),
                "metrics: prediction " + shape_string(pred) + " and ground truth " +
                    shape_string(gt) + " must both be [H, W, N] of the same shape");
  core::require(pred.numel() > 0, "metrics: empty image " + shape_string(pred));
}

// Both images as double [H, W, N] after checking they are comparable.
std::pair<torch::Tensor, torch::Tensor> as_double(const torch::Tensor& pred,
                                                  const torch::Tensor& gt) {
  require_comparable(pred, gt);
  torch::Tensor p = pred.to(torch::kDouble), g = gt.to(torch::kDouble);
  core::require(torch::isfinite(p).all().item<bool>(),
                "metrics: prediction contains NaN or Inf values");
  core::require(torch::isfinite(g).all().item<bool>(),
                "metrics: ground truth contains NaN or Inf values");
  return {p, g};
}

double psnr_from_mse(double mse) {
  return 10.0 * std::log10(1.0 / std::max(mse, kMinMse));
}

// Normalised 1D Gaussian taps; the 2D window is their outer product.
torch::Tensor gaussian_taps() {
  torch::Tensor x = torch::arange(kWindow, torch::kDouble) - double(kWindow / 2);
  torch::Tensor w = torch::exp(-(x * x) / (2 * kSigma * kSigma));
  return w / w.sum();
}

// Gaussian-weighted local mean of each band over the windows that fit:
// [N, 1, H, W] -> [N, 1, H - 10, W - 10], separable: down the columns, then
// along the rows, as two 1D convolutions would. Direct loops over output
// rows, in double: LibTorch's double conv2d unrolls every window into a
// matrix (11 copies of the image) and took about 37 s per SSIM at
// 640x512x141.
torch::Tensor local_mean(const torch::Tensor& x, const torch::Tensor& taps) {
  const torch::Tensor in = x.contiguous();
  const int64_t n = in.size(0), h = in.size(2), w = in.size(3);
  const int64_t out_h = h - kWindow + 1, out_w = w - kWindow + 1;
  torch::Tensor out = torch::empty({n, 1, out_h, out_w}, torch::kDouble);
  double tap[kWindow];
  for (int k = 0; k < kWindow; ++k) tap[k] = taps[k].item<double>();
  const double* src = in.data_ptr<double>();
  double* dst = out.data_ptr<double>();
  core::parallel_for(0, n * out_h, 16, [&](int64_t begin, int64_t end) {
    std::vector<double> column(static_cast<size_t>(w));
    for (int64_t r = begin; r < end; ++r) {
      const int64_t band = r / out_h, row = r % out_h;
      const double* top = src + (band * h + row) * w;
      for (int64_t j = 0; j < w; ++j) {
        double s = 0;
        for (int k = 0; k < kWindow; ++k) s += tap[k] * top[k * w + j];
        column[size_t(j)] = s;
      }
      double* o = dst + r * out_w;
      for (int64_t j = 0; j < out_w; ++j) {
        double s = 0;
        for (int k = 0; k < kWindow; ++k) s += tap[k] * column[size_t(j + k)];
        o[j] = s;
      }
    }
  });
  return out;
}

// SSIM map averaged over pixels, one value per band: [N]. Bands are
// independent, so they go through in groups of kSsimBands: the dozen
// temporaries of a group stay small enough for the allocator to reuse
// (whole-image ones were fresh pages each, most of eval's time at
// 640x512x141).
constexpr int64_t kSsimBands = 8;

torch::Tensor ssim_group(const torch::Tensor& p, const torch::Tensor& g) {
  torch::Tensor x = p.permute({2, 0, 1}).unsqueeze(1).contiguous();  // [n, 1, H, W]
  torch::Tensor y = g.permute({2, 0, 1}).unsqueeze(1).contiguous();
  torch::Tensor taps = gaussian_taps();
  torch::Tensor mu_x = local_mean(x, taps), mu_y = local_mean(y, taps);
  torch::Tensor var_x = local_mean(x * x, taps) - mu_x * mu_x;
  torch::Tensor var_y = local_mean(y * y, taps) - mu_y * mu_y;
  torch::Tensor cov = local_mean(x * y, taps) - mu_x * mu_y;
  torch::Tensor map = ((2 * mu_x * mu_y + kC1) * (2 * cov + kC2)) /
                      ((mu_x * mu_x + mu_y * mu_y + kC1) * (var_x + var_y + kC2));
  return map.mean(std::vector<int64_t>{1, 2, 3});
}

torch::Tensor ssim_per_band(const torch::Tensor& p, const torch::Tensor& g) {
  core::require(p.size(0) >= kWindow && p.size(1) >= kWindow,
                "metrics: SSIM needs images of at least 11 x 11 pixels, got " + shape_string(p));
  std::vector<torch::Tensor> groups;
  for (int64_t b = 0; b < p.size(2); b += kSsimBands) {
    const int64_t n = std::min(kSsimBands, p.size(2) - b);
    groups.push_back(ssim_group(p.narrow(2, b, n), g.narrow(2, b, n)));
  }
  return torch::cat(groups);
}

std::vector<double> band_mse(const torch::Tensor& p, const torch::Tensor& g) {
  return core::to_doubles((p - g).square().mean(std::vector<int64_t>{0, 1}));
}

std::vector<double> band_psnr_checked(const torch::Tensor& p, const torch::Tensor& g) {
  std::vector<double> mse = band_mse(p, g);
  for (double& v : mse) v = psnr_from_mse(v);
  return mse;
}

double sam_checked(const torch::Tensor& p, const torch::Tensor& g) {
  torch::Tensor dot = (p * g).sum(-1);  // [H, W]
  torch::Tensor norm_p = p.norm(2, -1), norm_g = g.norm(2, -1);
  torch::Tensor valid = norm_g > 0;
  int64_t count = valid.sum().item<int64_t>();
  if (count == 0) return 0;
  torch::Tensor cosine = (dot / (norm_p * norm_g).clamp_min(1e-300)).clamp(-1, 1);
  torch::Tensor angle =
      torch::where(norm_p > 0, torch::acos(cosine), torch::full_like(cosine, M_PI / 2));
  return angle.masked_select(valid).sum().item<double>() / double(count);
}

// The mean squared difference of two comparable images, in double, in one
// pass over their samples: the same figure as the double tensors' (p -
// g).square().mean() up to the order of the sum, without the four
// whole-image double temporaries (1.4 GB of fresh pages for a 640x512x141
// view; the trainer's test records measure every held-out view). Float32
// and float64 images; blocks of a fixed size are summed in order, so the
// figure does not depend on the thread count.
double mean_squared_difference(const torch::Tensor& pred, const torch::Tensor& gt) {
  require_comparable(pred, gt);
  const bool f32 = pred.scalar_type() == torch::kFloat && gt.scalar_type() == torch::kFloat;
  const bool f64 = pred.scalar_type() == torch::kDouble && gt.scalar_type() == torch::kDouble;
  if (!f32 && !f64) {
    auto [p, g] = as_double(pred, gt);
    return (p - g).square().mean().item<double>();
  }
  const torch::Tensor p = pred.contiguous(), g = gt.contiguous();
  const int64_t n = p.numel();
  constexpr int64_t kBlock = int64_t(1) << 16;
  const int64_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> sums(size_t(blocks), 0.0);
  std::vector<char> finite_p(size_t(blocks), 1), finite_g(size_t(blocks), 1);
  auto run = [&](const auto* a, const auto* b) {
    core::parallel_for(0, blocks, 1, [&](int64_t begin, int64_t end) {
      for (int64_t k = begin; k < end; ++k) {
        double sum = 0;
        bool fa = true, fb = true;
        for (int64_t i = k * kBlock, stop = std::min(n, i + kBlock); i < stop; ++i) {
          const double x = double(a[i]), y = double(b[i]);
          fa = fa && std::isfinite(x);
          fb = fb && std::isfinite(y);
          sum += (x - y) * (x - y);
        }
        sums[size_t(k)] = sum;
        finite_p[size_t(k)] = fa;
        finite_g[size_t(k)] = fb;
      }
    });
  };
  if (f32)
    run(p.data_ptr<float>(), g.data_ptr<float>());
  else
    run(p.data_ptr<double>(), g.data_ptr<double>());
  core::require(std::all_of(finite_p.begin(), finite_p.end(), [](char c) { return c != 0; }),
                "metrics: prediction contains NaN or Inf values");
  core::require(std::all_of(finite_g.begin(), finite_g.end(), [](char c) { return c != 0; }),
                "metrics: ground truth contains NaN or Inf values");
  double total = 0;
  for (double s : sums) total += s;
  return total / double(n);
}

}  // namespace

double psnr_db(const torch::Tensor& pred, const torch::Tensor& gt) {
  return psnr_from_mse(mean_squared_difference(pred, gt));
}

std::vector<double> band_psnr_db(const torch::Tensor& pred, const torch::Tensor& gt) {
  auto [p, g] = as_double(pred, gt);
  return band_psnr_checked(p, g);
}

double rmse(const torch::Tensor& pred, const torch::Tensor& gt) {
  return std::sqrt(mean_squared_difference(pred, gt));
}

double ssim(const torch::Tensor& pred, const torch::Tensor& gt) {
  auto [p, g] = as_double(pred, gt);
  return ssim_per_band(p, g).mean().item<double>();
}

std::vector<double> band_ssim(const torch::Tensor& pred, const torch::Tensor& gt) {
  auto [p, g] = as_double(pred, gt);
  return core::to_doubles(ssim_per_band(p, g));
}

double sam_rad(const torch::Tensor& pred, const torch::Tensor& gt) {
  auto [p, g] = as_double(pred, gt);
  return sam_checked(p, g);
}

ImageMetrics compute_metrics(const torch::Tensor& pred, const torch::Tensor& gt) {
  torch::NoGradGuard no_grad;
  auto [p, g] = as_double(pred, gt);
  double mse = (p - g).square().mean().item<double>();
  ImageMetrics m;
  m.psnr_db = psnr_from_mse(mse);
  m.ssim = ssim_per_band(p, g).mean().item<double>();
  m.sam_rad = sam_checked(p, g);
  m.rmse = std::sqrt(mse);
  for (double band : band_mse(p, g)) {
    m.band_psnr_db.push_back(psnr_from_mse(band));
    m.band_rmse.push_back(std::sqrt(band));
  }
  return m;
}

ImageMetrics mean_metrics(const std::vector<ImageMetrics>& views) {
  ImageMetrics mean;
  if (views.empty()) return mean;
  // NaN marks a value a view does not have (a band it does not hold, the
  // spectral angle of a one-band view): each mean is over the views that do.
  auto average = [](double sum, double count) { return count > 0 ? sum / count : std::nan(""); };
  auto add = [](double value, double* sum, double* count) {
    if (std::isnan(value)) return;
    *sum += value;
    *count += 1;
  };
  const size_t bands = views.front().band_psnr_db.size();
  std::vector<double> psnr_sum(bands, 0), psnr_n(bands, 0), rmse_sum(bands, 0), rmse_n(bands, 0);
  double sums[4] = {0, 0, 0, 0}, counts[4] = {0, 0, 0, 0};
  for (const ImageMetrics& v : views) {
    core::require(v.band_psnr_db.size() == bands && v.band_rmse.size() == bands,
                  "metrics: views with different band counts cannot be averaged");
    add(v.psnr_db, &sums[0], &counts[0]);
    add(v.ssim, &sums[1], &counts[1]);
    add(v.sam_rad, &sums[2], &counts[2]);
    add(v.rmse, &sums[3], &counts[3]);
    for (size_t b = 0; b < bands; ++b) {
      add(v.band_psnr_db[b], &psnr_sum[b], &psnr_n[b]);
      add(v.band_rmse[b], &rmse_sum[b], &rmse_n[b]);
    }
  }
  mean.psnr_db = average(sums[0], counts[0]);
  mean.ssim = average(sums[1], counts[1]);
  mean.sam_rad = average(sums[2], counts[2]);
  mean.rmse = average(sums[3], counts[3]);
  for (size_t b = 0; b < bands; ++b) {
    mean.band_psnr_db.push_back(average(psnr_sum[b], psnr_n[b]));
    mean.band_rmse.push_back(average(rmse_sum[b], rmse_n[b]));
  }
  return mean;
}

ImageMetrics on_scene_bands(ImageMetrics m, const std::vector<int>& bands, int64_t scene_bands) {
  if (bands.empty()) return m;
  core::require(m.band_psnr_db.size() == bands.size(),
                "metrics: a view's band list and its per-band values differ in length");
  std::vector<double> psnr(size_t(scene_bands), std::nan("")),
      rmse(size_t(scene_bands), std::nan(""));
  for (size_t j = 0; j < bands.size(); ++j) {
    psnr[size_t(bands[j])] = m.band_psnr_db[j];
    rmse[size_t(bands[j])] = m.band_rmse[j];
  }
  m.band_psnr_db = psnr;
  m.band_rmse = rmse;
  if (bands.size() < 2) m.sam_rad = std::nan("");  // no spectrum, no angle
  return m;
}

std::optional<RegionMetrics> region_metrics(const torch::Tensor& pred, const torch::Tensor& gt,
                                            const torch::Tensor& mask) {
  torch::NoGradGuard no_grad;
  auto [p, g] = as_double(pred, gt);
  core::require(mask.defined() && mask.scalar_type() == torch::kBool && mask.dim() == 2 &&
                    mask.size(0) == p.size(0) && mask.size(1) == p.size(1),
                "metrics: the region mask " + (mask.defined() ? shape_string(mask) : "(none)") +
                    " must be [H, W] bool for images " + shape_string(p));
  const torch::Tensor rows = mask.reshape({-1});
  if (!rows.any().item<bool>()) return std::nullopt;
  const int64_t n = p.size(2);
  // [P, 1, N]: the region's pixels as a one-column image.
  const torch::Tensor pr = p.reshape({-1, n}).index({rows}).unsqueeze(1);
  const torch::Tensor gr = g.reshape({-1, n}).index({rows}).unsqueeze(1);
  return RegionMetrics{psnr_from_mse((pr - gr).square().mean().item<double>()),
                       sam_checked(pr, gr)};
}

RegionMetrics mean_region_metrics(const std::vector<RegionMetrics>& views) {
  RegionMetrics mean;
  int angles = 0;
  for (const RegionMetrics& v : views) {
    mean.psnr_db += v.psnr_db / double(views.size());
    if (std::isnan(v.sam_rad)) continue;  // a one-band view's: no angle
    mean.sam_rad += v.sam_rad;
    ++angles;
  }
  mean.sam_rad = angles > 0 ? mean.sam_rad / angles : std::nan("");
  return mean;
}

}  // namespace ddhgs::eval
