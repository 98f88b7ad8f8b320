// Three-channel exports of N-band models (eval/rgb_export.h) checked through
// the renderer's own SH evaluation: the linear part maps view-dependent
// colours exactly, a curve to first order.
#include <gtest/gtest.h>

#include "core/colour.h"
#include "core/error.h"
#include "eval/rgb_export.h"
#include "model/gaussians.h"
#include "render/rasterize.h"

namespace ddhgs::eval {
namespace {

const std::vector<double> kWavelengths = {420, 470, 520, 570, 620, 670, 720};

// A model whose band values lie in [0.3, 0.7] at the DC, with view-dependent
// coefficients of size rest_size.
io::GaussianPly random_model(int64_t G, double rest_size, uint64_t seed) {
  torch::manual_seed(seed);
  const int64_t N = int64_t(kWavelengths.size());
  io::GaussianPly ply;
  ply.means = torch::randn({G, 3});
  ply.log_scales = torch::randn({G, 3}) * 0.3 - 2;
  ply.quats = torch::randn({G, 4});
  ply.logit_opacities = torch::randn({G, 1});
  ply.sh_dc = ((torch::rand({G, N}) * 0.4 + 0.3 - 0.5) / model::kShC0).to(torch::kFloat32);
  ply.sh_rest = torch::randn({G, N, 15}) * rest_size;
  ply.wavelengths_nm = kWavelengths;
  return ply;
}

// Colours [G, C] of a model seen from a camera at `eye`, at SH degree 3.
torch::Tensor colours(const io::GaussianPly& ply, const torch::Tensor& eye) {  // [3]
  return render::eval_sh(ply.sh_dc, ply.sh_rest, ply.means, eye, 3).to(torch::kFloat64);
}

TEST(RgbExport, LinearMapMapsViewDependentColoursExactly) {
  const io::GaussianPly model = random_model(64, 0.05, 1);
  ColourMapping mapping;
  mapping.linear = torch::rand({3, int64_t(kWavelengths.size())}, torch::kFloat64) / 4;
  const io::GaussianPly rgb = map_colours(model, mapping);
  ASSERT_EQ(rgb.bands(), 3);
  ASSERT_EQ(rgb.sh_degree(), 3);
  EXPECT_TRUE(rgb.wavelengths_nm.empty());
  EXPECT_TRUE(torch::equal(rgb.means, model.means));
  EXPECT_TRUE(torch::equal(rgb.logit_opacities, model.logit_opacities));
  for (const auto& eye : {torch::tensor({4.f, 0.f, 0.f}), torch::tensor({-1.f, 3.f, -2.f})}) {
    torch::Tensor expected = colours(model, eye).matmul(mapping.linear.t());  // [G, 3]
    EXPECT_LT((colours(rgb, eye) - expected).abs().max().item<double>(), 2e-6);
  }
}

TEST(RgbExport, SrgbCurveIsExactAtTheDcAndFirstOrderInViewDependence) {
  const ColourMapping cie = cie_mapping(kWavelengths, int64_t(kWavelengths.size()));
  ASSERT_EQ(cie.curve, ColourMapping::Curve::Srgb);
  const torch::Tensor eye = torch::tensor({3.f, -2.f, 1.f});
  std::vector<double> errors;
  for (double rest : {0.0, 0.02, 0.002}) {
    const io::GaussianPly model = random_model(64, rest, 2);
    // What `render` shows: pseudo-RGB of the band colours, per Gaussian.
    torch::Tensor expected = core::pseudo_rgb(colours(model, eye).unsqueeze(0), kWavelengths)
                                 .squeeze(0)
                                 .to(torch::kFloat64);
    errors.push_back((colours(map_colours(model, cie), eye) - expected).abs().max().item<double>());
  }
  EXPECT_LT(errors[0], 1e-5);            // no view dependence: only float rounding
  EXPECT_GT(errors[1], 1e-7);            // a curve cannot be linear...
  EXPECT_LT(errors[2], errors[1] / 30);  // ...but the error is second order
}

TEST(RgbExport, LinearLightCieMapsLikeThePseudoRgbMatrix) {
  const ColourMapping linear = cie_mapping(kWavelengths, int64_t(kWavelengths.size()), false);
  EXPECT_EQ(linear.curve, ColourMapping::Curve::None);
  // A spectrum through the map, then the sRGB curve, is core::pseudo_rgb.
  torch::Tensor spectrum = torch::rand({int64_t(kWavelengths.size())}, torch::kFloat64) * 0.5 + 0.2;
  torch::Tensor via_map = core::srgb_encode(linear.linear.matmul(spectrum).clamp(0, 1));
  torch::Tensor direct = core::pseudo_rgb(spectrum.view({1, 1, -1}), kWavelengths).reshape({3});
  EXPECT_LT((via_map - direct.to(torch::kFloat64)).abs().max().item<double>(), 1e-6);
  EXPECT_LT((map_background(spectrum, cie_mapping(kWavelengths, spectrum.size(0))) - direct)
                .abs()
                .max()
                .item<double>(),
            1e-6);
}

TEST(RgbExport, RgbModelsAndBandChoicesSelectBandsUnchanged) {
  io::GaussianPly model = random_model(16, 0.1, 3);
  // Three bands as R, G, B (nearest bands), with their coefficients as they are.
  const io::GaussianPly chosen = map_colours(model, band_mapping(kWavelengths, {670, 571, 421}));
  const std::vector<int64_t> bands = {5, 3, 0};
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT((chosen.sh_dc.select(1, j) - model.sh_dc.select(1, bands[size_t(j)]))
                  .abs()
                  .max()
                  .item<float>(),
              1e-6);
    EXPECT_TRUE(
        torch::allclose(chosen.sh_rest.select(1, j), model.sh_rest.select(1, bands[size_t(j)])));
  }
  // An RGB dataset's run is exported as it is.
  const ColourMapping rgb = cie_mapping(core::rgb_channel_wavelengths_nm(), 3);
  EXPECT_EQ(rgb.curve, ColourMapping::Curve::None);
  EXPECT_TRUE(torch::equal(rgb.linear, torch::eye(3, torch::kFloat64)));
}

TEST(RgbExport, OneBandThroughViridisHasTheMapsColourAtTheDc) {
  const io::GaussianPly model = random_model(8, 0.0, 4);
  const io::GaussianPly out =
      map_colours(model, single_band_mapping(kWavelengths, 570, Colormap::Viridis));
  for (int64_t g = 0; g < 8; ++g) {
    const double value = model.sh_dc[g][3].item<double>() * model::kShC0 + 0.5;
    const auto rgb = colormap_rgb(Colormap::Viridis, value);
    for (int j = 0; j < 3; ++j)
      EXPECT_NEAR(out.sh_dc[g][j].item<double>() * model::kShC0 + 0.5, rgb[size_t(j)], 1e-6);
  }
}

TEST(RgbExport, BadBandChoicesNameTheOption) {
  EXPECT_THROW(nearest_band(kWavelengths, 900, "--band"), core::Error);  // outside 420-720
  EXPECT_THROW(nearest_band({}, 550, "--bands"), core::Error);           // no wavelengths
  EXPECT_THROW(band_mapping(kWavelengths, {600, 500}), core::Error);     // two bands
  EXPECT_THROW(cie_mapping({900, 950, 1000}, 3), core::Error);           // nothing visible
  EXPECT_EQ(nearest_band(kWavelengths, 544, "--band"), 2);
}

TEST(RgbExport, AModelWithoutWavelengthsShowsThreeBandsByIndex) {
  // Bands known by index only (a dataset without wavelengths): bands 5, 3
  // and 1 of 8 as R, G, B, as render-ply previews them, unchanged.
  io::GaussianPly model = random_model(6, 0.1, 5);
  model.sh_dc = torch::randn({6, 8});
  model.sh_rest = torch::randn({6, 8, 15});
  model.wavelengths_nm.clear();
  const ColourMapping mapping = cie_mapping({}, 8);
  EXPECT_EQ(mapping.curve, ColourMapping::Curve::None);
  EXPECT_NE(mapping.description.find("bands 5, 3, 1 (by index"), std::string::npos)
      << mapping.description;
  const io::GaussianPly out = map_colours(model, mapping);
  const std::vector<int64_t> bands = {5, 3, 1};
  for (int j = 0; j < 3; ++j)
    EXPECT_TRUE(
        torch::allclose(out.sh_rest.select(1, j), model.sh_rest.select(1, bands[size_t(j)])));
  // Choosing bands in nm says why it cannot, and what works instead.
  try {
    nearest_band({}, 550, "--bands");
    FAIL() << "chose a band by wavelength in a model without wavelengths";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("--bands: the model's bands have no wavelengths (its PLY "
                                         "has no 'comment wavelengths' line)"),
              std::string::npos)
        << e.what();
  }
}

TEST(RgbExport, CropKeepsCentresInTheBoxAndOpaqueEnoughGaussians) {
  io::GaussianPly model = random_model(4, 0.1, 5);
  model.means =
      torch::tensor({{0.f, 0.f, 0.f}, {2.f, 0.f, 0.f}, {0.5f, 0.5f, 0.5f}, {0.f, -3.f, 0.f}});
  model.logit_opacities = torch::tensor({{3.f}, {3.f}, {-3.f}, {3.f}});  // 0.95, 0.95, 0.05, 0.95
  Crop box;
  box.box = std::array<double, 6>{-1, -1, -1, 1, 1, 1};
  EXPECT_TRUE(torch::equal(crop_indices(model, box), torch::tensor({0, 2}, torch::kInt64)));
  box.min_opacity = 0.5;
  EXPECT_TRUE(torch::equal(crop_indices(model, box), torch::tensor({0}, torch::kInt64)));
  Crop opacity;
  opacity.min_opacity = 0.5;
  const torch::Tensor kept = crop_indices(model, opacity);
  EXPECT_TRUE(torch::equal(kept, torch::tensor({0, 1, 3}, torch::kInt64)));
  const io::GaussianPly cropped = select_rows(model, kept);
  EXPECT_TRUE(torch::equal(cropped.sh_rest[2], model.sh_rest[3]));
}

}  // namespace
}  // namespace ddhgs::eval
