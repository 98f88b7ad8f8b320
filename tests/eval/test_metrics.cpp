// Metrics against hand-computed values and against an independent numpy
// computation on random images.
#include <gtest/gtest.h>
#include <torch/nn/functional/conv.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/tensor.h"
#include "eval/metrics.h"
#include "model/ssim.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::eval {
namespace {

torch::Tensor pixels(std::vector<std::vector<double>> spectra) {  // -> [1, P, N]
  int64_t p = int64_t(spectra.size()), n = int64_t(spectra[0].size());
  torch::Tensor t = torch::empty({1, p, n}, torch::kDouble);
  for (int64_t i = 0; i < p; ++i)
    for (int64_t b = 0; b < n; ++b) t[0][i][b] = spectra[size_t(i)][size_t(b)];
  return t.to(torch::kFloat);
}

TEST(Metrics, ConstantOffsetGivesTwentyDecibels) {
  torch::Tensor gt = torch::rand({12, 13, 4}) * 0.5;
  torch::Tensor pred = gt + 0.1;
  EXPECT_NEAR(psnr_db(pred, gt), 20.0, 1e-5);
  EXPECT_NEAR(rmse(pred, gt), 0.1, 1e-7);
  for (double b : band_psnr_db(pred, gt)) EXPECT_NEAR(b, 20.0, 1e-5);
}

TEST(Metrics, PerBandPsnrSeparatesBands) {
  torch::Tensor gt = torch::zeros({5, 6, 2}, torch::kDouble);
  torch::Tensor pred = gt.clone();
  pred.select(2, 0).fill_(0.1);
  pred.select(2, 1).fill_(0.01);
  std::vector<double> bands = band_psnr_db(pred, gt);
  ASSERT_EQ(bands.size(), 2u);
  EXPECT_NEAR(bands[0], 20.0, 1e-9);
  EXPECT_NEAR(bands[1], 40.0, 1e-9);
  // The view PSNR pools the squared errors of all bands: MSE = (0.01 + 0.0001) / 2.
  EXPECT_NEAR(psnr_db(pred, gt), 10 * std::log10(2 / 0.0101), 1e-9);
  EXPECT_NEAR(rmse(pred, gt), std::sqrt(0.0101 / 2), 1e-12);
}

TEST(Metrics, IdenticalImagesArePerfectAndPsnrIsCapped) {
  torch::Tensor gt = torch::rand({16, 12, 3});
  ImageMetrics m = compute_metrics(gt, gt);
  EXPECT_DOUBLE_EQ(m.psnr_db, kMaxPsnrDb);
  EXPECT_NEAR(m.ssim, 1.0, 1e-12);
  EXPECT_NEAR(m.sam_rad, 0.0, 1e-6);
  EXPECT_DOUBLE_EQ(m.rmse, 0.0);
  for (double b : m.band_psnr_db) EXPECT_DOUBLE_EQ(b, kMaxPsnrDb);
}

TEST(Metrics, SpectralAngles) {
  // Orthogonal spectra are pi/2 apart; a scaled spectrum has angle 0.
  EXPECT_NEAR(sam_rad(pixels({{0, 1}}), pixels({{1, 0}})), M_PI / 2, 1e-12);
  EXPECT_NEAR(sam_rad(pixels({{0.2, 0.4, 0.6}}), pixels({{0.1, 0.2, 0.3}})), 0.0, 1e-6);
  // 45 degrees, and a zero ground-truth pixel that is left out of the mean.
  EXPECT_NEAR(sam_rad(pixels({{1, 1}, {0.5, 0.5}}), pixels({{1, 0}, {0, 0}})), M_PI / 4, 1e-12);
  // An all-zero prediction against a non-zero ground truth counts as pi/2.
  EXPECT_NEAR(sam_rad(pixels({{0, 0}, {1, 0}}), pixels({{0.3, 0.3}, {1, 0}})), M_PI / 4, 1e-12);
  // Nothing to measure: every ground-truth spectrum is zero.
  EXPECT_DOUBLE_EQ(sam_rad(pixels({{1, 0}}), pixels({{0, 0}})), 0.0);
  // Opposite spectra (negative values only arise from bad renders) give pi.
  EXPECT_NEAR(sam_rad(pixels({{-1, -2}}), pixels({{1, 2}})), M_PI, 1e-6);
}

TEST(Metrics, SsimOfConstantImagesMatchesHandFormula) {
  // Constant images have zero variance in every window, so SSIM reduces to
  // the luminance term (2ab + C1) / (a^2 + b^2 + C1) at every valid position.
  double a = 0.7, b = 0.3, c1 = 1e-4;
  torch::Tensor pred = torch::full({11, 14, 2}, a, torch::kDouble);
  torch::Tensor gt = torch::full({11, 14, 2}, b, torch::kDouble);
  EXPECT_NEAR(ssim(pred, gt), (2 * a * b + c1) / (a * a + b * b + c1), 1e-12);
  // Smaller than one window: no valid position.
  EXPECT_THROW(ssim(pred.narrow(0, 0, 10), gt.narrow(0, 0, 10)), core::Error);
}

TEST(Metrics, SsimAveragesOnlyWindowsInsideTheImage) {
  // A change at the corner pixel of a 12 x 12 image is seen by exactly one of
  // the 2 x 2 valid windows; the other three keep SSIM 1. Zero padding would
  // spread it over 36 of 144 positions instead.
  torch::Tensor gt = torch::rand({12, 12, 1}, torch::kDouble) * 0.5;
  torch::Tensor pred = gt.clone();
  pred[0][0][0] += 0.5;
  double corner =
      ssim(pred.narrow(0, 0, 11).narrow(1, 0, 11), gt.narrow(0, 0, 11).narrow(1, 0, 11));
  EXPECT_LT(corner, 1.0);
  EXPECT_NEAR(ssim(pred, gt), (corner + 3.0) / 4.0, 1e-12);
}

TEST(Metrics, SsimIsSymmetricAndAveragesBands) {
  torch::Tensor a = torch::rand({20, 24, 3}), b = torch::rand({20, 24, 3});
  EXPECT_NEAR(ssim(a, b), ssim(b, a), 1e-12);
  EXPECT_LT(ssim(a, b), 0.5);
  std::vector<double> bands = band_ssim(a, b);
  ASSERT_EQ(bands.size(), 3u);
  EXPECT_NEAR(ssim(a, b), (bands[0] + bands[1] + bands[2]) / 3, 1e-12);
  // Band 1 identical: its SSIM is exactly 1, the others are unchanged.
  torch::Tensor c = b.clone();
  c.select(2, 1).copy_(a.select(2, 1));
  std::vector<double> mixed = band_ssim(a, c);
  EXPECT_NEAR(mixed[1], 1.0, 1e-12);
  EXPECT_NEAR(mixed[0], bands[0], 1e-12);
}

// The separable local means (direct loops) against LibTorch's convolution,
// in double, on an image of odd size with several bands.
TEST(Metrics, SsimMatchesAConvolutionReference) {
  torch::manual_seed(5);
  const torch::Tensor a = torch::rand({37, 41, 5}, torch::kDouble);
  const torch::Tensor b = (a + 0.2 * torch::randn({37, 41, 5}, torch::kDouble)).clamp(0, 1);
  namespace F = torch::nn::functional;
  torch::Tensor taps = torch::arange(11, torch::kDouble) - 5.0;
  taps = torch::exp(-(taps * taps) / (2 * 1.5 * 1.5));
  taps = taps / taps.sum();
  const torch::Tensor window = (taps.view({11, 1}) * taps.view({1, 11})).view({1, 1, 11, 11});
  auto mean = [&](const torch::Tensor& t) { return F::conv2d(t, window); };
  const torch::Tensor x = a.permute({2, 0, 1}).unsqueeze(1), y = b.permute({2, 0, 1}).unsqueeze(1);
  const torch::Tensor mx = mean(x), my = mean(y);
  const torch::Tensor vx = mean(x * x) - mx * mx, vy = mean(y * y) - my * my;
  const torch::Tensor cxy = mean(x * y) - mx * my;
  const double c1 = 1e-4, c2 = 9e-4;
  const torch::Tensor map =
      ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
  const torch::Tensor expected = map.mean(std::vector<int64_t>{1, 2, 3});
  const std::vector<double> got = band_ssim(a, b);
  ASSERT_EQ(got.size(), 5u);
  for (int64_t i = 0; i < 5; ++i) EXPECT_NEAR(got[size_t(i)], expected[i].item<double>(), 1e-12);
}

TEST(Metrics, SsimAgreesWithTheTrainingLoss) {
  // model::ssim (float, differentiable, used by the loss) and this double
  // evaluation metric share one definition.
  torch::manual_seed(11);
  torch::Tensor a = torch::rand({19, 23, 4}), b = (a + 0.1 * torch::randn({19, 23, 4})).clamp(0, 1);
  EXPECT_NEAR(ssim(a, b), model::ssim(a, b).item<double>(), 1e-5);
  std::vector<double> bands = band_ssim(a, b);
  torch::Tensor loss_bands = model::ssim(a, b, true);
  for (int64_t i = 0; i < 4; ++i) EXPECT_NEAR(bands[size_t(i)], loss_bands[i].item<double>(), 1e-5);
}

TEST(Metrics, BadInputThrowsOneLineError) {
  torch::Tensor a = torch::rand({12, 12, 3});
  EXPECT_THROW(psnr_db(a, torch::rand({12, 12, 2})), core::Error);
  EXPECT_THROW(ssim(a, torch::rand({12, 12})), core::Error);
  torch::Tensor nan = a.clone();
  nan[1][2][0] = std::nan("");
  EXPECT_THROW(compute_metrics(nan, a), core::Error);
  try {
    rmse(a, torch::rand({12, 5, 3}));
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("[12, 5, 3]"), std::string::npos);
  }
}

// psnr_db and rmse sum the squared differences in one pass (no double
// copies of the images): the same figures as the double tensors' mean, over
// several of its blocks of 65,536 samples, for float and double images and
// a non-contiguous one, and NaN or Inf in either image is still refused.
TEST(Metrics, PsnrAndRmseMatchTheDoubleTensorReference) {
  torch::manual_seed(12);
  const torch::Tensor a = torch::rand({70, 60, 40}), b = torch::rand({70, 60, 40});
  auto reference_mse = [](const torch::Tensor& p, const torch::Tensor& g) {
    return (p.to(torch::kDouble) - g.to(torch::kDouble)).square().mean().item<double>();
  };
  const double mse = reference_mse(a, b);
  EXPECT_NEAR(psnr_db(a, b), 10 * std::log10(1 / mse), 1e-10);
  EXPECT_NEAR(rmse(a, b), std::sqrt(mse), 1e-12);  // the sums run in another order
  EXPECT_NEAR(psnr_db(a.to(torch::kDouble), b.to(torch::kDouble)), 10 * std::log10(1 / mse), 1e-10);
  const torch::Tensor strided = a.transpose(0, 1).contiguous().transpose(0, 1);
  ASSERT_FALSE(strided.is_contiguous());
  EXPECT_NEAR(psnr_db(strided, b), 10 * std::log10(1 / mse), 1e-10);
  // Half precision goes through the double tensors.
  EXPECT_NEAR(psnr_db(a.to(torch::kHalf), b.to(torch::kHalf)),
              10 * std::log10(1 / reference_mse(a.to(torch::kHalf), b.to(torch::kHalf))), 1e-10);
  for (const double bad : {std::nan(""), double(INFINITY)}) {
    torch::Tensor p = a.clone(), g = b.clone();
    p[69][59][39] = bad;
    g[0][0][0] = bad;
    EXPECT_TRUE(
        test::contains(test::error_of([&] { psnr_db(p, b); }), "prediction contains NaN or Inf"));
    EXPECT_TRUE(
        test::contains(test::error_of([&] { rmse(a, g); }), "ground truth contains NaN or Inf"));
  }
}

TEST(Metrics, MeanOverViews) {
  ImageMetrics a{20, 0.5, 0.1, 0.1, {10, 30}, {0.1, 0.3}};
  ImageMetrics b{30, 0.7, 0.3, 0.2, {20, 40}, {0.2, 0.4}};
  ImageMetrics m = mean_metrics({a, b});
  EXPECT_DOUBLE_EQ(m.psnr_db, 25);
  EXPECT_DOUBLE_EQ(m.ssim, 0.6);
  EXPECT_DOUBLE_EQ(m.sam_rad, 0.2);
  EXPECT_NEAR(m.rmse, 0.15, 1e-15);
  EXPECT_EQ(m.band_psnr_db, (std::vector<double>{15, 35}));
  ASSERT_EQ(m.band_rmse.size(), 2u);
  EXPECT_NEAR(m.band_rmse[0], 0.15, 1e-15);
  EXPECT_NEAR(m.band_rmse[1], 0.35, 1e-15);
  ImageMetrics c{20, 0.5, 0.1, 0.1, {10}, {0.1}};
  EXPECT_THROW(mean_metrics({a, c}), core::Error);
}

// Views of a band-per-view scene: each view's per-band values land on its
// own bands, and each band's mean is over the views that hold it.
TEST(Metrics, MeanOverViewsThatHoldSomeBands) {
  const ImageMetrics one{30, 0.9, 0, 0.03, {30}, {0.03}};             // holds band 2
  const ImageMetrics two{20, 0.7, 0.2, 0.1, {24, 18}, {0.06, 0.12}};  // bands 0 and 2
  const ImageMetrics a = on_scene_bands(one, {2}, 3);
  const ImageMetrics b = on_scene_bands(two, {0, 2}, 3);
  EXPECT_TRUE(std::isnan(a.band_psnr_db[0]) && std::isnan(a.band_psnr_db[1]));
  EXPECT_EQ(a.band_psnr_db[2], 30);
  EXPECT_TRUE(std::isnan(a.sam_rad));  // one band: no spectral angle
  EXPECT_EQ(b.sam_rad, 0.2);
  const ImageMetrics m = mean_metrics({a, b});
  EXPECT_DOUBLE_EQ(m.psnr_db, 25);
  EXPECT_DOUBLE_EQ(m.sam_rad, 0.2);  // from the view that has one
  EXPECT_EQ(m.band_psnr_db[0], 24);
  EXPECT_TRUE(std::isnan(m.band_psnr_db[1]));  // no view holds band 1
  EXPECT_EQ(m.band_psnr_db[2], 24);            // (30 + 18) / 2
  EXPECT_DOUBLE_EQ(m.band_rmse[2], 0.075);
  // Unchanged for a view that holds every band.
  EXPECT_EQ(on_scene_bands(two, {}, 2).band_psnr_db, two.band_psnr_db);
}

TEST(Metrics, RegionMetricsCoverTheMaskedPixelsOnly) {
  // 2 x 2 pixels, 2 bands; the mask takes the top row.
  const torch::Tensor gt = torch::full({2, 2, 2}, 0.5, torch::kDouble);
  const torch::Tensor pred = gt.clone();
  pred[0][0][0] = 0.6;                     // in the region: 0.1 off in one band
  pred[1][0] = torch::tensor({0.9, 0.1});  // outside it
  const torch::Tensor mask = torch::tensor({true, true, false, false}).view({2, 2});
  const auto m = region_metrics(pred, gt, mask);
  ASSERT_TRUE(m.has_value());
  // MSE over 2 pixels x 2 bands: 0.01 / 4.
  EXPECT_NEAR(m->psnr_db, 10 * std::log10(400.0), 1e-9);
  // The angle of (0.6, 0.5) to (0.5, 0.5), and 0 for the exact pixel
  // (LibTorch's vectorised acos agrees with std::acos to 1e-8 here).
  const double angle = std::acos(0.55 / (std::sqrt(0.61) * std::sqrt(0.5)));
  EXPECT_NEAR(m->sam_rad, angle / 2, 1e-7);
  // The whole image sees the pixel outside the region too.
  EXPECT_LT(psnr_db(pred, gt), m->psnr_db);

  EXPECT_FALSE(region_metrics(pred, gt, torch::zeros({2, 2}, torch::kBool)).has_value());
  EXPECT_THROW(region_metrics(pred, gt, torch::ones({2, 2})), core::Error);  // not bool
  EXPECT_THROW(region_metrics(pred, gt, torch::ones({2, 3}, torch::kBool)), core::Error);

  const RegionMetrics mean = mean_region_metrics({{20, 0.1}, {30, 0.3}});
  EXPECT_DOUBLE_EQ(mean.psnr_db, 25);
  EXPECT_DOUBLE_EQ(mean.sam_rad, 0.2);
}

void write_raw(const std::filesystem::path& path, const torch::Tensor& t) {
  torch::Tensor d = t.to(torch::kDouble).contiguous();
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(d.data_ptr<double>()),
            std::streamsize(d.numel() * sizeof(double)));
}

// An independent implementation: plain numpy, the 2D window applied as an
// explicit sum of shifted image crops (valid positions only).
const char* kNumpyMetrics = R"PY(
import json, sys
import numpy as np
h, w, n = (int(v) for v in sys.argv[3:6])
p = np.fromfile(sys.argv[1], dtype='<f8').reshape(h, w, n)
g = np.fromfile(sys.argv[2], dtype='<f8').reshape(h, w, n)
mse = np.mean((p - g) ** 2)
band_mse = np.mean((p - g) ** 2, axis=(0, 1))
x = np.arange(11) - 5.0
k = np.exp(-x ** 2 / (2 * 1.5 ** 2)); k /= k.sum()
win = np.outer(k, k)
def filt(img):
    out = np.zeros((h - 10, w - 10))
    for dy in range(11):
        for dx in range(11):
            out += win[dy, dx] * img[dy:dy + h - 10, dx:dx + w - 10]
    return out
ssims = []
for b in range(n):
    a, c = p[:, :, b], g[:, :, b]
    ma, mc = filt(a), filt(c)
    va = filt(a * a) - ma ** 2; vc = filt(c * c) - mc ** 2; cv = filt(a * c) - ma * mc
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    ssims.append(np.mean((2 * ma * mc + c1) * (2 * cv + c2) /
                         ((ma ** 2 + mc ** 2 + c1) * (va + vc + c2))))
dot = np.sum(p * g, axis=2)
npn, ngn = np.linalg.norm(p, axis=2), np.linalg.norm(g, axis=2)
valid = ngn > 0
ang = np.arccos(np.clip(dot[valid] / (npn[valid] * ngn[valid]), -1, 1))
print(json.dumps({"psnr": float(10 * np.log10(1 / mse)), "rmse": float(np.sqrt(mse)),
                  "ssim": float(np.mean(ssims)), "sam": float(np.mean(ang)),
                  "band_psnr": [float(v) for v in 10 * np.log10(1 / band_mse)]}))
)PY";

double json_number(const std::string& text, const std::string& key) {
  size_t at = text.find("\"" + key + "\":");
  if (at == std::string::npos) return std::nan("");
  return std::stod(text.substr(at + key.size() + 3));
}

TEST(Metrics, MatchIndependentNumpyComputation) {
  auto dir = test::temp_dir("metrics_numpy");
  std::ofstream(dir / "metrics.py") << kNumpyMetrics;
  torch::manual_seed(7);
  const int64_t h = 23, w = 17, n = 5;
  torch::Tensor gt = torch::rand({h, w, n});
  // A plausible render: ground truth plus noise and a tint, some pixels black
  // in the ground truth (left out of SAM).
  torch::Tensor pred = (gt * 0.9 + 0.05 + 0.05 * torch::randn({h, w, n})).clamp(0, 1);
  gt.index_put_({torch::indexing::Slice(0, 3), torch::indexing::Slice(0, 4)}, 0);
  write_raw(dir / "pred.bin", pred);
  write_raw(dir / "gt.bin", gt);
  std::ostringstream cmd;
  cmd << test::python() << " " << dir / "metrics.py"
      << " " << dir / "pred.bin"
      << " " << dir / "gt.bin"
      << " " << h << " " << w << " " << n;
  std::string out;
  ASSERT_EQ(test::run_command(cmd.str(), &out), 0) << out;

  ImageMetrics m = compute_metrics(pred, gt);
  EXPECT_NEAR(m.psnr_db, json_number(out, "psnr"), 1e-5);
  EXPECT_NEAR(m.rmse, json_number(out, "rmse"), 1e-7);
  EXPECT_NEAR(m.ssim, json_number(out, "ssim"), 1e-7);
  EXPECT_NEAR(m.sam_rad, json_number(out, "sam"), 1e-7);
  size_t at = out.find("\"band_psnr\": [");
  ASSERT_NE(at, std::string::npos) << out;
  std::istringstream bands(out.substr(at + 14));
  for (int64_t b = 0; b < n; ++b) {
    double v;
    char sep;
    bands >> v >> sep;
    EXPECT_NEAR(m.band_psnr_db[size_t(b)], v, 1e-5) << "band " << b;
  }
}

}  // namespace
}  // namespace ddhgs::eval
