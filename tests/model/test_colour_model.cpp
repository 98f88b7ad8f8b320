// The colour model (model/colour_model.h): the latent form against per-band
// rendering and against the dense double-precision reference, its gradients
// against finite differences, and its maps (tests/eval: its PLY form).
#include <gtest/gtest.h>
#include <torch/linalg.h>

#include "core/band_map.h"
#include "model/colour_fixtures.h"
#include "model/colour_model.h"
#include "model/gaussians.h"
#include "render/reference.h"
#include "render/sh_reference.h"

namespace ddhgs::test {
namespace {

using torch::Tensor;

Tensor centre_of(const core::Camera& camera, torch::ScalarType dtype) {
  const core::Vec3 c = camera.center();
  return torch::tensor({c.x, c.y, c.z}, torch::kFloat64).to(dtype);
}

// The dense reference render of Gaussians whose per-Gaussian band colours
// are `colours` [G, N] (float64).
render::RenderOutput reference_render(const model::Gaussians& g, const Tensor& colours,
                                      const core::Camera& camera, const Tensor& background) {
  const auto f64 = torch::kFloat64;
  return render::rasterize_reference(g.means.to(f64), g.log_scales.to(f64), g.quats.to(f64),
                                     g.logit_opacities.to(f64), colours,
                                     render::RenderCamera::from(camera), background.to(f64));
}

TEST(ColourModel, FullRankIdentityBasisRendersAsThePerBandModel) {
  const int n = 6;
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  model::Gaussians per_band = scene_gaussians(3, 60, n);
  const Tensor background = torch::rand({n}) * 0.5;

  // The per-band model against the double-precision reference...
  const auto f64 = torch::kFloat64;
  const Tensor colours =
      render::eval_sh_reference(per_band.sh_dc.to(f64), per_band.sh_rest.to(f64),
                                per_band.means.to(f64), centre_of(camera, f64), 1);
  ASSERT_GT(colours.min().item<double>(), 0.0);  // no clamp: the two models agree exactly
  const Tensor expected = reference_render(per_band, colours, camera, background).image;
  const Tensor got_per_band = model::render_gaussians(per_band, camera, background).image;
  EXPECT_LT(scaled_error(got_per_band, expected), 1e-4);

  // ...and the latent model with K = N, an identity basis and a mean of 0.5
  // (the per-band model's offset) on the same coefficients.
  model::Gaussians latent = per_band;
  latent.colour.basis = torch::eye(n);
  latent.colour.mean = torch::full({n}, 0.5f);
  ASSERT_EQ(latent.channels(), n);
  ASSERT_EQ(latent.bands(), n);
  const Tensor got_latent = model::render_gaussians(latent, camera, background).image;
  EXPECT_LT(scaled_error(got_latent, expected), 1e-4);
  EXPECT_GT(
      render::rasterize_reference(per_band.means.to(f64), per_band.log_scales.to(f64),
                                  per_band.quats.to(f64), per_band.logit_opacities.to(f64), colours,
                                  render::RenderCamera::from(camera), background.to(f64))
          .alpha.max()
          .item<double>(),
      0.99);
}

TEST(ColourModel, DecodingAfterBlendingEqualsBlendingDecodedColours) {
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  const model::Gaussians g = latent_scene(5);
  const Tensor background = torch::rand({9});  // not zero: decode must add it exactly

  // Every Gaussian's colour decoded first (float64), then blended over the
  // background by the dense reference.
  const auto f64 = torch::kFloat64;
  const Tensor latent =
      render::eval_sh_reference(g.sh_dc.to(f64), g.sh_rest.to(f64), g.means.to(f64),
                                centre_of(camera, f64), 1, {}, /*linear=*/true);  // [G, 3]
  const Tensor decoded = latent.matmul(g.colour.basis.to(f64).t()) + g.colour.mean.to(f64);
  const render::RenderOutput expected = reference_render(g, decoded, camera, background);
  // Some pixels are background only, some fully covered: both ends of alpha.
  ASSERT_LT(expected.alpha.min().item<double>(), 1e-3);
  ASSERT_GT(expected.alpha.max().item<double>(), 0.99);

  const render::RenderOutput got = model::render_gaussians(g, camera, background);
  ASSERT_EQ(got.image.size(2), 9);
  EXPECT_LT(scaled_error(got.image, expected.image), 1e-4);
  EXPECT_LT(scaled_error(got.alpha, expected.alpha), 1e-4);
}

TEST(ColourModel, GradientsOfBasisMeanBackgroundAndLatentShMatchFiniteDifferences) {
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  model::Gaussians g = latent_scene(7);
  Tensor background = torch::rand({9});
  std::vector<Tensor*> params = {&g.colour.basis, &g.colour.mean, &background, &g.sh_dc,
                                 &g.sh_rest};
  for (Tensor* p : params) p->requires_grad_(true);
  torch::manual_seed(11);
  const Tensor weights = torch::randn({kHeight, kWidth, 9}, torch::kFloat64);
  auto loss = [&] {
    return (model::render_gaussians(g, camera, background).image.to(torch::kFloat64) * weights)
        .sum();
  };
  loss().backward();
  // The image is linear in each of these, so a large step is exact up to
  // float32 rounding.
  const double step = 0.25;
  const char* names[] = {"basis", "mean", "background", "sh_dc", "sh_rest"};
  for (size_t i = 0; i < params.size(); ++i) {
    Tensor& p = *params[i];
    const Tensor grad = p.grad().clone();
    ASSERT_TRUE(grad.defined()) << names[i];
    const Tensor flat_grad = grad.reshape({-1});
    // The entries with the largest gradients, and the first.
    std::vector<int64_t> entries = {0, flat_grad.abs().argmax().item<int64_t>()};
    for (int64_t e : entries) {
      double values[2];
      for (int side = 0; side < 2; ++side) {
        torch::NoGradGuard no_grad;
        const double delta = side == 0 ? step : -step;
        p.view({-1})[e] += delta;
        values[side] = loss().item<double>();
        p.view({-1})[e] -= delta;
      }
      const double numeric = (values[0] - values[1]) / (2 * step);
      const double analytic = flat_grad[e].item<double>();
      EXPECT_NEAR(analytic, numeric, 1e-3 * std::max(1.0, std::abs(numeric)))
          << names[i] << " entry " << e;
    }
  }
  // Not a model that ignores its basis: the basis gradient is far from zero.
  EXPECT_GT(g.colour.basis.grad().abs().max().item<double>(), 1.0);
}

TEST(ColourModel, CoefficientsForSpectraInTheBasisSpanGiveThemBack) {
  model::ColourModel latent;
  // An orthogonal basis scaled as latent_from_pca scales it.
  latent.basis = std::get<0>(torch::linalg_qr(torch::randn({12, 4}, torch::kFloat64))) * 3.0;
  latent.basis = latent.basis.to(torch::kFloat32);
  latent.mean = torch::rand({12});
  const Tensor z = torch::randn({20, 4}, torch::kFloat64);
  const Tensor spectra =
      z.matmul(latent.basis.to(torch::kFloat64).t()) + latent.mean.to(torch::kFloat64);
  const Tensor dc = latent.sh_dc_for(spectra);
  EXPECT_LT((dc * model::kShC0 - z).abs().max().item<double>(), 1e-5);
  EXPECT_LT((latent.spectra(dc * model::kShC0) - spectra).abs().max().item<double>(), 1e-5);
  // Per band: the 3DGS convention, colour = SH value + 0.5.
  const model::ColourModel per_band;
  const Tensor values = torch::rand({5, 12}, torch::kFloat64);
  EXPECT_TRUE(torch::allclose(per_band.spectra(per_band.sh_dc_for(values) * model::kShC0), values));
  EXPECT_EQ(per_band.channels(12), 12);
  EXPECT_EQ(latent.channels(12), 4);
}

TEST(ColourModel, AnOutputMapAppliesAfterDecodingInBothForms) {
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  const Tensor map = torch::rand({2, 9});  // two output channels from nine bands
  const Tensor background = torch::rand({9});
  model::Gaussians latent = latent_scene(13);
  model::Gaussians per_band = scene_gaussians(13, 50, 9);
  for (model::Gaussians* g : {&latent, &per_band}) {
    const Tensor bands = model::render_gaussians(*g, camera, background).image;
    model::Gaussians mapped = *g;
    mapped.colour = g->colour.mapped(map);
    const Tensor got = model::render_gaussians(mapped, camera, background).image;
    ASSERT_EQ(got.size(2), 2);
    EXPECT_LT(scaled_error(got, torch::matmul(bands, map.t())), 1e-5);
  }
}

TEST(ColourModel, AResponseRenderIsTheResponseWeightedSumOfTheDenseWavelengthRender) {
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  const std::vector<double> bands = {400, 450, 500, 550, 600, 650, 700, 750, 800};
  core::ResponseFunctions response;
  for (double w = 380; w <= 820; w += 4) response.wavelengths_nm.push_back(w);
  response.channels = {"narrow", "wide"};
  const auto w = torch::tensor(response.wavelengths_nm, torch::kFloat64);
  response.values =
      torch::stack({torch::exp(-((w - 560) / 20).pow(2)), torch::exp(-((w - 640) / 90).pow(2))}, 1);
  const core::ResponseMap srf = core::response_map(response, bands);
  // The samples inside the bands, rendered as wavelengths of their own.
  std::vector<double> inside;
  std::vector<int64_t> rows;
  for (size_t s = 0; s < response.wavelengths_nm.size(); ++s)
    if (response.wavelengths_nm[s] >= 400 && response.wavelengths_nm[s] <= 800) {
      inside.push_back(response.wavelengths_nm[s]);
      rows.push_back(int64_t(s));
    }
  const std::vector<double> trapezoid = core::trapezoid_weights(response.wavelengths_nm);
  const Tensor background = torch::rand({9});
  for (model::Gaussians g : {latent_scene(17), scene_gaussians(17, 50, 9)}) {
    model::Gaussians dense = g, sensor = g;
    dense.colour = g.colour.mapped(core::interpolation_map(bands, inside));
    sensor.colour = g.colour.mapped(srf.map);
    const Tensor dense_image =
        model::render_gaussians(dense, camera, background).image.to(torch::kFloat64);
    const Tensor got = model::render_gaussians(sensor, camera, background).image;
    for (int64_t c = 0; c < 2; ++c) {
      // sum_s w_s r_c(s) image(s) / sum_s w_s r_c(s) over the samples inside.
      Tensor weights =
          torch::tensor(trapezoid, torch::kFloat64).index_select(0, torch::tensor(rows)) *
          response.values.select(1, c).index_select(0, torch::tensor(rows));
      weights = weights / weights.sum();
      const Tensor expected = torch::matmul(dense_image, weights);
      EXPECT_LT(scaled_error(got.select(2, c), expected), 1e-5) << response.channels[c];
    }
  }
}

}  // namespace
}  // namespace ddhgs::test
