#include "eval/rgb_export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tuple>

#include "core/band_map.h"
#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "model/gaussians.h"

namespace ddhgs::eval {
namespace {

constexpr double kSrgbLinearLimit = 0.0031308;  // below it the sRGB curve is 12.92 x

// Slope of srgb_encode(clamp(x, 0, 1)); zero where the clamp holds.
torch::Tensor srgb_slope(const torch::Tensor& linear) {  // double [...]
  torch::Tensor x = linear.clamp(kSrgbLinearLimit, 1.0);
  torch::Tensor power = (1.055 / 2.4) * x.pow(1.0 / 2.4 - 1.0);
  torch::Tensor slope = torch::where(linear <= kSrgbLinearLimit, torch::full_like(x, 12.92), power);
  return torch::where((linear < 0) | (linear > 1), torch::zeros_like(x), slope);
}

// A colour map and its slope (central difference over one 8-bit step, the
// map's resolution) at values [G]: double [G, 3] each.
std::pair<torch::Tensor, torch::Tensor> colormap_and_slope(const torch::Tensor& values,
                                                           Colormap map) {
  constexpr double kStep = 1.0 / 255;
  const int64_t G = values.size(0);
  torch::Tensor colour = torch::empty({G, 3}, torch::kFloat64);
  torch::Tensor slope = torch::empty({G, 3}, torch::kFloat64);
  auto v = values.accessor<double, 1>();
  auto c = colour.accessor<double, 2>();
  auto s = slope.accessor<double, 2>();
  for (int64_t g = 0; g < G; ++g) {
    const auto mid = colormap_rgb(map, v[g]);
    const double lo_v = std::clamp(v[g] - kStep, 0.0, 1.0),
                 hi_v = std::clamp(v[g] + kStep, 0.0, 1.0);
    const auto lo = colormap_rgb(map, lo_v), hi = colormap_rgb(map, hi_v);
    const bool flat = v[g] < 0 || v[g] > 1 || hi_v <= lo_v;
    for (int j = 0; j < 3; ++j) {
      c[g][j] = mid[j];
      s[g][j] = flat ? 0.0 : (hi[j] - lo[j]) / (hi_v - lo_v);
    }
  }
  return {colour, slope};
}

std::string nm_text(double wavelength_nm) {
  return core::format_g(wavelength_nm) + " nm";
}

}  // namespace

int64_t nearest_band(const std::vector<double>& wavelengths_nm, double wavelength_nm,
                     const std::string& option) {
  core::require(!wavelengths_nm.empty(),
                option +
                    ": the model's bands have no wavelengths (its PLY has no 'comment "
                    "wavelengths' line), so none can be chosen in nm; without " +
                    option + ", export shows three bands spread over them");
  auto nearest =
      std::min_element(wavelengths_nm.begin(), wavelengths_nm.end(), [&](double a, double b) {
        return std::abs(a - wavelength_nm) < std::abs(b - wavelength_nm);
      });
  const int64_t index = nearest - wavelengths_nm.begin();
  double spacing = 20;  // a lone band answers within 10 nm
  if (wavelengths_nm.size() > 1)
    spacing = (wavelengths_nm.back() - wavelengths_nm.front()) / double(wavelengths_nm.size() - 1);
  core::require(std::abs(*nearest - wavelength_nm) <= 0.5 * std::abs(spacing) + 1e-9,
                option + ": no band near " + nm_text(wavelength_nm) + " (the model covers " +
                    nm_text(wavelengths_nm.front()) + " to " + nm_text(wavelengths_nm.back()) +
                    ")");
  return index;
}

ColourMapping cie_mapping(const std::vector<double>& wavelengths_nm, int64_t bands,
                          bool srgb_curve) {
  ColourMapping mapping;
  if (core::is_rgb(wavelengths_nm, bands)) {
    mapping.linear = core::selection_map(3, {0, 1, 2});
    mapping.description = "RGB (the model's own three channels)";
    return mapping;
  }
  if (wavelengths_nm.empty()) {
    // Bands known by index only: three spread over them, long ones as red,
    // as render-ply previews such a model.
    const std::vector<int64_t> rows = {(bands - 1) * 3 / 4, (bands - 1) / 2, (bands - 1) / 4};
    mapping.linear = core::selection_map(bands, rows);
    mapping.description = "bands " + std::to_string(rows[0]) + ", " + std::to_string(rows[1]) +
                          ", " + std::to_string(rows[2]) +
                          " (by index: the model has no wavelengths) as R, G, B";
    return mapping;
  }
  core::require(int64_t(wavelengths_nm.size()) == bands,
                "pseudo-RGB needs one wavelength per band; the model has " + std::to_string(bands) +
                    " bands and " + std::to_string(wavelengths_nm.size()) +
                    " wavelengths (use --bands or --band)");
  mapping.linear =
      core::cie_linear_srgb_map(wavelengths_nm, core::Illuminant::D65).t().contiguous();
  core::require(
      mapping.linear.any().item<bool>(),
      "pseudo-RGB: no band lies in the visible range (380-780 nm); use --bands or --band");
  mapping.curve = srgb_curve ? ColourMapping::Curve::Srgb : ColourMapping::Curve::None;
  mapping.description = std::string("pseudo-RGB (CIE 1931, D65") +
                        (srgb_curve ? ", sRGB curve per Gaussian)" : ", linear light)");
  return mapping;
}

ColourMapping band_mapping(const std::vector<double>& wavelengths_nm,
                           const std::vector<double>& rgb_nm) {
  core::require(rgb_nm.size() == 3, "--bands: expected three wavelengths (nm) for R, G and B");
  std::vector<int64_t> rows;
  std::string text;
  for (double nm : rgb_nm) {
    rows.push_back(nearest_band(wavelengths_nm, nm, "--bands"));
    text += (text.empty() ? "" : ", ") + nm_text(wavelengths_nm[size_t(rows.back())]);
  }
  ColourMapping mapping;
  mapping.linear = core::selection_map(int64_t(wavelengths_nm.size()), rows);
  mapping.description = "bands " + text + " as R, G, B";
  return mapping;
}

ColourMapping single_band_mapping(const std::vector<double>& wavelengths_nm, double wavelength_nm,
                                  Colormap map) {
  const int64_t band = nearest_band(wavelengths_nm, wavelength_nm, "--band");
  ColourMapping mapping;
  mapping.linear = core::selection_map(int64_t(wavelengths_nm.size()), {band, band, band});
  mapping.curve =
      map == Colormap::Gray ? ColourMapping::Curve::None : ColourMapping::Curve::Colormap;
  mapping.colormap = map;
  mapping.description = "band " + nm_text(wavelengths_nm[size_t(band)]) +
                        (map == Colormap::Gray ? " as grey" : " through viridis");
  return mapping;
}

io::GaussianPly map_colours(const io::GaussianPly& model, const ColourMapping& mapping) {
  const int64_t N = model.bands();
  const torch::Tensor& L = mapping.linear;  // [3, N]
  core::require(L.dim() == 2 && L.size(0) == 3 && L.size(1) == N,
                "colour mapping: expected a [3, " + std::to_string(N) + "] map");
  const torch::Tensor dc = model.sh_dc.to(torch::kFloat64);  // [G, C]
  // The colour model's channels to bands, then to the three colours.
  const model::ColourModel colour_model{model.basis, model.mean, {}};
  const auto [A, offset] = colour_model.affine(N);  // [N, C], [N]
  const torch::Tensor LA = L.matmul(A);             // [3, C]
  // Each channel's DC value, offsets included: [G, 3].
  torch::Tensor base = (dc * model::kShC0).matmul(LA.t()) + L.matmul(offset);
  torch::Tensor rest;  // [G, 3, K]: view-dependent coefficients through the map
  if (model.sh_rest.defined() && model.sh_rest.size(2) > 0)
    rest = torch::einsum("jc,gck->gjk", {LA, model.sh_rest.to(torch::kFloat64)});

  torch::Tensor colour = base, slope = torch::ones_like(base);
  if (mapping.curve == ColourMapping::Curve::Srgb) {
    colour = core::srgb_encode(base.clamp(0, 1));
    slope = srgb_slope(base);
  } else if (mapping.curve == ColourMapping::Curve::Colormap) {
    torch::Tensor value = base.select(1, 0).contiguous();
    std::tie(colour, slope) = colormap_and_slope(value, mapping.colormap);
    if (rest.defined()) rest = rest.narrow(1, 0, 1).expand({-1, 3, -1});
  }

  io::GaussianPly out;
  out.means = model.means.clone();
  out.log_scales = model.log_scales.clone();
  out.quats = model.quats.clone();
  out.logit_opacities = model.logit_opacities.clone();
  out.sh_dc = ((colour - 0.5) / model::kShC0).to(torch::kFloat32);
  out.sh_rest = rest.defined() ? (slope.unsqueeze(2) * rest).to(torch::kFloat32).contiguous()
                               : torch::zeros({model.means.size(0), 3, 0});
  return out;
}

torch::Tensor map_background(const torch::Tensor& background, const ColourMapping& mapping) {
  torch::Tensor linear = mapping.linear.matmul(background.to(torch::kFloat64));  // [3]
  if (mapping.curve == ColourMapping::Curve::Srgb)
    return core::srgb_encode(linear.clamp(0, 1).to(torch::kFloat32));
  if (mapping.curve == ColourMapping::Curve::Colormap) {
    auto rgb = colormap_rgb(mapping.colormap, linear[0].item<double>());
    return torch::tensor({float(rgb[0]), float(rgb[1]), float(rgb[2])});
  }
  return linear.to(torch::kFloat32);
}

torch::Tensor crop_indices(const io::GaussianPly& model, const Crop& crop) {
  torch::Tensor keep = torch::sigmoid(model.logit_opacities.reshape({-1})) >= crop.min_opacity;
  if (crop.box) {
    const auto& b = *crop.box;
    for (int axis = 0; axis < 3; ++axis) {
      torch::Tensor x = model.means.select(1, axis);
      keep = keep.logical_and(x >= b[size_t(axis)]).logical_and(x <= b[size_t(axis) + 3]);
    }
  }
  return keep.nonzero().reshape({-1});
}

io::GaussianPly select_rows(const io::GaussianPly& model, const torch::Tensor& indices) {
  io::GaussianPly out = model;
  for (torch::Tensor* t :
       {&out.means, &out.log_scales, &out.quats, &out.logit_opacities, &out.sh_dc, &out.sh_rest})
    if (t->defined()) *t = t->index_select(0, indices).contiguous();
  return out;
}

}  // namespace ddhgs::eval
