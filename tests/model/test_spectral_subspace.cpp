// The spectral subspace a denoiser prior works in: coefficients against a
// hand-made subspace, corrections that land in the bands, and a denoiser
// that works through it.
#include <gtest/gtest.h>
#include <torch/serialize.h>

#include <cmath>

#include "core/error.h"
#include "denoiser_fixtures.h"
#include "model/diffusion.h"
#include "model/spectral_subspace.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {

// Spectra m + a b1 + c b2 over 6 bands (b1, b2 orthonormal), a and c
// independent and uniform: a 2-D affine subspace with known axes.
struct PlaneSpectra {
  torch::Tensor mean = torch::tensor({0.3, 0.35, 0.4, 0.45, 0.5, 0.55}, torch::kFloat64);
  torch::Tensor b1 = torch::tensor({1, 1, 1, 1, 1, 1}, torch::kFloat64) / std::sqrt(6.0);
  torch::Tensor b2 = torch::tensor({-1, -1, -1, 1, 1, 1}, torch::kFloat64) / std::sqrt(6.0);
  torch::Tensor at(const torch::Tensor& a, const torch::Tensor& c) const {
    return mean + a.unsqueeze(-1) * b1 + c.unsqueeze(-1) * b2;
  }
};

TEST(SpectralSubspace, FitsTheSpectraAxesAndScalesByTheirSpread) {
  torch::manual_seed(1);
  PlaneSpectra plane;
  const auto a = (torch::rand({4000}, torch::kFloat64) - 0.5) * 0.4;  // std 0.115
  const auto c = (torch::rand({4000}, torch::kFloat64) - 0.5) * 0.2;  // std 0.058
  const auto spectra = plane.at(a, c);
  const model::SpectralSubspace s = model::fit_spectral_subspace(spectra, 4);
  ASSERT_EQ(s.bands(), 6);
  ASSERT_EQ(s.channels(), 4);
  // The first two columns span the plane (b1 leads: the larger spread).
  const auto basis = s.basis.to(torch::kFloat64);
  const auto plane_axes = basis.slice(1, 0, 2);
  for (const auto& axis : {plane.b1, plane.b2})
    EXPECT_NEAR(torch::matmul(plane_axes.t(), axis).norm().item<double>(), 1.0, 1e-6);
  EXPECT_GT(std::abs(torch::dot(basis.select(1, 0), plane.b1).item<double>()), 0.999);
  // Scale: 8 x the root mean square distance from the mean.
  const auto centred = spectra - spectra.mean(0);
  const double rms = std::sqrt(centred.pow(2).sum(1).mean().item<double>());
  EXPECT_NEAR(s.scale, model::SpectralSubspace::kScaleSigmas * rms, 1e-6 * s.scale);
  // The mean spectrum sits at 0.5 in every coefficient.
  const auto middle = s.encode(s.mean.unsqueeze(0));
  EXPECT_LT((middle - 0.5).abs().max().item<double>(), 1e-6);
}

// A render whose error lies in the subspace is corrected exactly by the
// truth's coefficients; what lies outside passes through unchanged.
TEST(SpectralSubspace, ACorrectionLandsInTheBandsAndLeavesTheRestAlone) {
  torch::manual_seed(2);
  PlaneSpectra plane;
  const auto spectra = plane.at((torch::rand({2000}, torch::kFloat64) - 0.5) * 0.4,
                                (torch::rand({2000}, torch::kFloat64) - 0.5) * 0.2);
  const model::SpectralSubspace s = model::fit_spectral_subspace(spectra, 2);
  const auto truth = plane
                         .at(torch::full({5, 7}, 0.05, torch::kFloat64),
                             torch::linspace(-0.05, 0.05, 7, torch::kFloat64).expand({5, 7}))
                         .to(torch::kFloat32);  // [5, 7, 6]
  const auto render =
      plane.at(torch::full({5, 7}, -0.02, torch::kFloat64), torch::zeros({5, 7}, torch::kFloat64))
          .to(torch::kFloat32);
  const auto corrected = s.apply(render, s.encode(render), s.encode(truth));
  EXPECT_LT((corrected - truth).abs().max().item<double>(), 1e-5);

  // Off the plane (a direction orthogonal to b1 and b2): no coefficient sees it.
  const auto off = torch::tensor({1, -1, 0, 0, 0, 0}, torch::kFloat32) / std::sqrt(2.0f) * 0.03f;
  const auto bumped = render + off;
  EXPECT_LT((s.encode(bumped) - s.encode(render)).abs().max().item<double>(), 1e-6);
  const auto moved = s.apply(bumped, s.encode(bumped), s.encode(truth));
  EXPECT_LT((moved - (truth + off)).abs().max().item<double>(), 1e-5);
}

TEST(SpectralSubspace, FewerBandsThanChannelsLeavesTheRestAtTheMiddle) {
  torch::manual_seed(3);
  const auto spectra = torch::rand({500, 3});
  const model::SpectralSubspace s = model::fit_spectral_subspace(spectra, 4);
  EXPECT_EQ(s.channels(), 4);
  EXPECT_EQ(s.basis.select(1, 3).abs().max().item<double>(), 0.0);
  const auto u = s.encode(torch::rand({4, 5, 3}));
  EXPECT_TRUE(torch::equal(u.select(2, 3), torch::full({4, 5}, 0.5)));
  // Three columns span all three bands: any change is reproduced.
  const auto a = torch::rand({4, 5, 3}), b = torch::rand({4, 5, 3}) * 0.2 + 0.4;
  EXPECT_LT((s.apply(a, s.encode(a), s.encode(b)) - b).abs().max().item<double>(), 1e-5);
}

TEST(SpectralSubspace, ConstantSpectraGiveAFiniteScale) {
  const model::SpectralSubspace s = model::fit_spectral_subspace(torch::full({10, 5}, 0.2), 4);
  EXPECT_TRUE(std::isfinite(s.scale));
  EXPECT_GT(s.scale, 0);
  EXPECT_LT((s.encode(torch::full({2, 5}, 0.2)) - 0.5).abs().max().item<double>(), 1e-6);
}

// A denoiser in a subspace that corrects nothing (an untrained residual
// U-Net) returns the render in its own bands, the parts outside the
// subspace included.
TEST(SpectralSubspace, AnUntrainedDenoiserInASubspaceReturnsTheRender) {
  torch::manual_seed(4);
  const model::SpectralSubspace s =
      model::fit_spectral_subspace(torch::rand({800, 9}, torch::kFloat64), 2);
  model::Denoiser d{model::UNet(test::tiny_unet_options(2)), model::NoiseSchedule(),
                    model::Prediction::Residual};
  d.subspace = s;
  EXPECT_EQ(d.bands(), 9);
  const auto render = torch::rand({10, 8, 9}) * 0.8 + 0.1;
  model::SamplerOptions o;
  o.start_strength = 0.1;
  o.steps = 1;
  EXPECT_LT((model::denoise_view(d, render, o) - render).abs().max().item<double>(), 1e-5);

  // A live network's change is the subspace change projected onto each
  // pixel's own spectrum: the render scaled per pixel (its spectral angle
  // kept) where the output is not clamped to [0, 1].
  d.unet = test::live_unet(test::tiny_unet_options(2), 5);
  {
    torch::NoGradGuard no_grad;  // a gentler correction: fewer pixels clamped
    for (auto& p : d.unet->named_parameters())
      if (p.key().rfind("output_conv.", 0) == 0) p.value().mul_(0.05);
  }
  const auto denoised = model::denoise_view(d, render, o);
  const auto inside = ((denoised > 1e-6) & (denoised < 1 - 1e-6)).all(2);  // [H, W]
  ASSERT_GT(inside.sum().item<int64_t>(), 40);
  const auto change = (denoised - render).index({inside});  // [M, 9]
  EXPECT_GT(change.abs().max().item<double>(), 1e-3);
  // The same draw as denoise_view's, its subspace change unprojected.
  const auto coeffs = s.encode(render);
  const auto sampled = model::sample(model::as_predictor(d), d.schedule,
                                     coeffs.permute({2, 0, 1}).unsqueeze(0).contiguous(), o)
                           .squeeze(0)
                           .permute({1, 2, 0});
  const auto in_subspace = s.apply(render, coeffs, sampled);
  const auto r = render.index({inside});
  const auto gain = (r * in_subspace.index({inside})).sum(-1, true) / (r * r).sum(-1, true);
  EXPECT_LT((change - r * (gain - 1)).abs().max().item<double>(), 1e-5);
}

// The projection by hand: a pixel (3, 4) corrected to (4, 3) keeps the
// direction (0.6, 0.8) at length 4.8 (the corrected pixel's component along
// it); a black pixel stays black whatever its correction.
TEST(SpectralSubspace, KeepingTheSpectralDirectionIsAGainPerPixel) {
  const auto render = torch::tensor({{3.0f, 4.0f}, {0.0f, 0.0f}});
  const auto corrected = torch::tensor({{4.0f, 3.0f}, {0.5f, 0.2f}});
  const auto kept = model::keep_spectral_direction(render, corrected);
  EXPECT_TRUE(torch::allclose(kept, torch::tensor({{2.88f, 3.84f}, {0.0f, 0.0f}}), 1e-6, 1e-6))
      << kept;
}

// The denoiser written to dir/name under the key "denoiser", read back.
model::Denoiser round_trip(model::Denoiser& denoiser, const std::string& name) {
  const auto file = test::temp_dir("subspace_denoiser") / name;
  {
    torch::serialize::OutputArchive archive;
    model::save_denoiser(archive, "denoiser", denoiser);
    archive.save_to(file.string());
  }
  torch::serialize::InputArchive archive;
  archive.load_from(file.string());
  return model::load_denoiser(archive, "denoiser", file);
}

TEST(SpectralSubspace, TheDenoiserFileKeepsItsSubspace) {
  torch::manual_seed(6);
  model::Denoiser d{test::live_unet(test::tiny_unet_options(2), 7), model::NoiseSchedule(),
                    model::Prediction::Residual};
  d.subspace = model::fit_spectral_subspace(torch::rand({300, 5}), 2);
  const model::Denoiser loaded = round_trip(d, "denoiser.pt");
  ASSERT_TRUE(loaded.subspace.has_value());
  EXPECT_TRUE(torch::equal(loaded.subspace->mean, d.subspace->mean));
  EXPECT_TRUE(torch::equal(loaded.subspace->basis, d.subspace->basis));
  EXPECT_EQ(loaded.subspace->scale, d.subspace->scale);
  model::SamplerOptions o;
  o.start_strength = 0.1;
  const auto render = torch::rand({6, 5, 5});
  EXPECT_TRUE(
      torch::equal(model::denoise_view(d, render, o), model::denoise_view(loaded, render, o)));

  // A subspace whose width is not the U-Net's is refused, naming the file.
  model::Denoiser wrong{test::live_unet(test::tiny_unet_options(3), 8), model::NoiseSchedule(),
                        model::Prediction::Residual};
  wrong.subspace = d.subspace;
  try {
    round_trip(wrong, "wrong.pt");
    FAIL() << "a mismatched subspace was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("wrong.pt"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("subspace"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ddhgs
