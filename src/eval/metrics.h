// Image-quality metrics of N-band renders, exactly as the field computes them
// (supplementary notes, "Metrics as the field computes them"). All metrics
// take channels-last images in [0, 1] (data range 1) and compute in double.
#pragma once
#include "core/tensor.h"

#include <optional>
#include <vector>

namespace ddhgs::eval {

// PSNR of a perfect prediction is infinite, which JSON cannot hold and which
// would swamp a mean over views; every PSNR is therefore capped here (the MSE
// is floored at 1e-10).
constexpr double kMaxPsnrDb = 100;

// 10 log10(1 / MSE), MSE over every pixel and band. Capped at kMaxPsnrDb.
double psnr_db(const torch::Tensor& pred,  // [H, W, N]
               const torch::Tensor& gt);   // [H, W, N]

// PSNR of each band separately, capped at kMaxPsnrDb; N values.
std::vector<double> band_psnr_db(const torch::Tensor& pred,  // [H, W, N]
                                 const torch::Tensor& gt);   // [H, W, N]

// sqrt of the mean squared error over all elements.
double rmse(const torch::Tensor& pred,  // [H, W, N]
            const torch::Tensor& gt);   // [H, W, N]

// SSIM with an 11 x 11 Gaussian window (sigma 1.5, centred), K1 = 0.01,
// K2 = 0.03, data range 1, population covariances, per band, averaged over
// bands. Only windows that fit inside the image are averaged ("valid"
// filtering, (H - 10) x (W - 10) positions), as scikit-image's
// structural_similarity and model::ssim (the training loss) do, so borders are
// not biased by padding. Images must be at least 11 x 11 pixels.
double ssim(const torch::Tensor& pred,  // [H, W, N]
            const torch::Tensor& gt);   // [H, W, N]

// Per-band SSIM (same definition as ssim), N values.
std::vector<double> band_ssim(const torch::Tensor& pred,  // [H, W, N]
                              const torch::Tensor& gt);   // [H, W, N]

// Spectral angle mapper in radians: arccos(<p, g> / (|p| |g|)) per pixel, the
// cosine clamped to [-1, 1], averaged over pixels whose ground-truth spectrum
// is not all zero. A non-zero ground truth against an all-zero prediction has
// no defined angle; it counts as pi/2 (nothing of the spectrum's shape was
// recovered). When every ground-truth spectrum is zero the result is 0.
double sam_rad(const torch::Tensor& pred,  // [H, W, N]
               const torch::Tensor& gt);   // [H, W, N]

struct ImageMetrics {
  double psnr_db = 0;
  double ssim = 0;
  double sam_rad = 0;
  double rmse = 0;
  std::vector<double> band_psnr_db;  // [N]
  std::vector<double> band_rmse;     // [N]
};

// All metrics of one view. Throws core::Error when the shapes differ or a
// value is not finite.
ImageMetrics compute_metrics(const torch::Tensor& pred,  // [H, W, N]
                             const torch::Tensor& gt);   // [H, W, N]

// Element-wise mean over views (per-band values averaged band by band). A
// NaN value (a band the view does not hold) is left out of its mean; a mean
// with no values is NaN.
ImageMetrics mean_metrics(const std::vector<ImageMetrics>& views);

// The metrics of a view that holds some of the scene's bands (io::View::bands,
// ascending), spread onto the scene's band grid: NaN per-band values for the
// bands it does not hold, and a NaN spectral angle when it holds one band.
// Unchanged when `bands` is empty (the view holds every band).
ImageMetrics on_scene_bands(ImageMetrics m, const std::vector<int>& bands, int64_t scene_bands);

// PSNR and SAM over one region of a view: the MSE over the region's pixels
// and every band (capped as psnr_db is), and the spectral angle averaged over
// its pixels as sam_rad averages. For the object of a masked view
// (io/scene/backdrop.h), which whole-image figures mix with a backdrop that
// is matched almost exactly.
struct RegionMetrics {
  double psnr_db = 0;
  double sam_rad = 0;
};

// None when the mask selects no pixel. Throws core::Error when the mask is
// not [H, W] bool of the images' size.
std::optional<RegionMetrics> region_metrics(const torch::Tensor& pred,   // [H, W, N]
                                            const torch::Tensor& gt,     // [H, W, N]
                                            const torch::Tensor& mask);  // [H, W] bool

// Mean over views, value by value; a NaN spectral angle (a one-band view's)
// is left out of its mean, which is NaN when no view has one.
RegionMetrics mean_region_metrics(const std::vector<RegionMetrics>& views);

}  // namespace ddhgs::eval
