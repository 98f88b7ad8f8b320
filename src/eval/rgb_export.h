// Three-channel versions of an N-band Gaussian model, for the 3DGS viewers
// and editors that only read f_dc_0..2 / f_rest_0..44 (`ddhgs export`), and
// the per-band colours the report's 3D viewer shows.
//
// A mapping is a linear map from band values to three channels, optionally
// followed by a curve applied per Gaussian (the sRGB transfer, or a colour
// map for one band). The SH colour of band n is linear in its coefficients,
//   value_n(dir) = C0 dc_n + 0.5 + sum_k rest_nk Y_k(dir),
// so the linear part maps coefficients exactly: dc' and rest' are the
// bands' coefficients through the map (the 0.5 offsets through the map too).
// A curve is applied to the Gaussian's view-independent (DC) value, and its
// view-dependent coefficients are scaled by the curve's slope there (first
// order), so view dependence survives as the viewer's SH evaluation shows it.
#pragma once
#include "core/tensor.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "eval/colormap.h"
#include "io/ply/ply.h"

namespace ddhgs::eval {

struct ColourMapping {
  enum class Curve {
    None,      // the linear map's output is the colour
    Srgb,      // linear light -> sRGB transfer (clamped to [0, 1]) per Gaussian
    Colormap,  // channel 0 (one band) through `colormap` per Gaussian
  };
  torch::Tensor linear;  // double [3, N]: band values -> channels
  Curve curve = Curve::None;
  Colormap colormap = Colormap::Gray;
  std::string description;  // e.g. "pseudo-RGB (CIE 1931, D65)", for logs and file comments
};

// Pseudo-RGB as `ddhgs render` shows it: CIE 1931 + D65 to linear sRGB, then
// the sRGB curve (srgb_curve false: linear light, for tools that apply the
// curve to the image). An RGB model (core::is_rgb: an RGB dataset's run) is
// RGB already: the identity, no curve. A model without wavelengths (bands by
// index) shows three bands spread over them, the longest as red, as
// render-ply previews it. core::Error when the wavelengths miss 380-780 nm.
ColourMapping cie_mapping(const std::vector<double>& wavelengths_nm, int64_t bands,
                          bool srgb_curve = true);

// Three bands as R, G, B (nearest band to each wavelength, nm), shown as
// reflectance on a fixed 0-1 scale: true colour (650,550,450) or a false-colour
// composite (800,660,550: NIR, red, green).
ColourMapping band_mapping(const std::vector<double>& wavelengths_nm,
                           const std::vector<double>& rgb_nm);

// One band (nearest to wavelength_nm) as grey or through a colour map.
ColourMapping single_band_mapping(const std::vector<double>& wavelengths_nm, double wavelength_nm,
                                  Colormap map);

// Index of the band nearest to wavelength_nm; core::Error naming `option`
// when the model has no wavelengths or the nearest band is more than half a
// band spacing (or 10 nm for one band) away.
int64_t nearest_band(const std::vector<double>& wavelengths_nm, double wavelength_nm,
                     const std::string& option);

// The model with three channels: same geometry and opacities, SH degree and
// coefficients mapped as described above, no wavelengths.
io::GaussianPly map_colours(const io::GaussianPly& model, const ColourMapping& mapping);

// The background [N] as the mapping shows it: float [3].
torch::Tensor map_background(const torch::Tensor& background, const ColourMapping& mapping);

// Keeps the Gaussians whose centre lies inside an axis-aligned box (scene
// units; min x, y, z then max x, y, z) and whose opacity is at least
// min_opacity (0-1). Returns the kept rows' indices, int64 [G'].
struct Crop {
  std::optional<std::array<double, 6>> box;
  double min_opacity = 0;
};
torch::Tensor crop_indices(const io::GaussianPly& model, const Crop& crop);
io::GaussianPly select_rows(const io::GaussianPly& model, const torch::Tensor& indices);  // [G']

}  // namespace ddhgs::eval
