// Colour science: CIE 1931 2-degree colour-matching functions, illuminants,
// the sRGB transfer curve, and pseudo-RGB images from hyperspectral cubes.
//
// Pseudo-RGB (CIE mode): each band is a box of reflectance between the
// midpoints to its neighbours; the part of that box inside 380-780 nm is
// integrated against illuminant x CMF, normalised so a perfect white reflector
// (all ones) has Y = 1, then XYZ -> linear sRGB (D65) -> clamp -> sRGB curve.
// Bands outside 380-780 nm contribute nothing.
#pragma once
#include "core/tensor.h"

#include <array>
#include <string>
#include <vector>

namespace ddhgs::core {

// Visible range covered by the tabulated CMFs, nm.
constexpr double kCmfMinNm = 380.0;
constexpr double kCmfMaxNm = 780.0;

struct Xyz {
  double x = 0, y = 0, z = 0;
};

// CIE 1931 2-degree CMFs, linearly interpolated from the 5 nm table; zero
// outside 380-780 nm.
Xyz cie1931_cmf(double wavelength_nm);

enum class Illuminant {
  D65,    // CIE standard daylight (tabulated), relative power 100 at 560 nm
  A,      // CIE standard incandescent: Planck 2856 K, relative power 100 at 560 nm
  Equal,  // equal energy, 100 everywhere
};
// Relative spectral power; 0 outside 380-780 nm for D65.
double illuminant_power(Illuminant illuminant, double wavelength_nm);
// Black-body spectral radiance (W sr^-1 m^-3) at a temperature in kelvin.
double planck_radiance(double wavelength_nm, double temperature_k);
Illuminant parse_illuminant(const std::string& name);  // "D65", "A", "E"

// sRGB transfer curve (IEC 61966-2-1), on [0, 1] values.
double srgb_encode(double linear);
double srgb_decode(double encoded);
torch::Tensor srgb_encode(const torch::Tensor& linear);

// XYZ (D65 white) -> linear sRGB, row-major 3x3.
const std::array<double, 9>& xyz_to_linear_srgb_matrix();

enum class PseudoRgbMode {
  Cie,        // physical: CMFs x illuminant
  LinearMap,  // user 3 x N (or 3 x k with band_indices) matrix
  Bands,      // three bands nearest to rgb_bands_nm, as R, G, B
};

struct PseudoRgbOptions {
  PseudoRgbMode mode = PseudoRgbMode::Cie;
  Illuminant illuminant = Illuminant::D65;
  // Cie mode: scale linear RGB so a white reflector is neutral (von Kries in
  // linear sRGB); matters for non-D65 illuminants.
  bool white_balance = false;
  // LinearMap mode: [3, N], or [3, k] applied to the bands in band_indices.
  torch::Tensor linear_map;
  std::vector<int64_t> band_indices;
  // Bands mode: wavelengths (nm) shown as red, green and blue.
  std::vector<double> rgb_bands_nm;
  // LinearMap/Bands: true when the map yields linear light that still needs
  // the sRGB curve (false: it yields display values, e.g. a map fitted
  // against a JPEG photo). Cie mode always applies the curve.
  bool map_output_linear = false;
  // Multiplies linear values before clamping (previews of dark scenes).
  double exposure = 1.0;
};

// Parses a command-line choice: "cie", "cie:A", "cie:A:balanced",
// "bands:650,550,450" (nm), "map:FILE" (text file, 3 rows of N or k numbers;
// an optional 4th row lists k band indices). Throws core::Error on a bad spec.
PseudoRgbOptions parse_pseudo_rgb(const std::string& spec);

// Per-band XYZ weights [N, 3] (Cie mode integration, not yet normalised) for
// bands centred at wavelengths_nm (strictly increasing).
torch::Tensor cie_band_weights(const std::vector<double>& wavelengths_nm, Illuminant illuminant);

// Cie mode's linear part, double [N, 3]: linear sRGB = reflectance [N] x map,
// scaled so a perfect white reflector has Y = 1, before clamping and the sRGB
// curve. All zeros when no band reaches the visible range.
torch::Tensor cie_linear_srgb_map(const std::vector<double>& wavelengths_nm, Illuminant illuminant);

// Wavelengths (nm) an RGB dataset gives its R, G and B channels (io's RGB
// scenes); pseudo-RGB shows such a cube, or a 3-band one without wavelengths,
// as it is.
const std::vector<double>& rgb_channel_wavelengths_nm();
bool is_rgb(const std::vector<double>& wavelengths_nm, int64_t bands);

// cube: float [H, W, N] (reflectance, ~[0, 1]); wavelengths_nm: N entries,
// strictly increasing. Returns float32 [H, W, 3] in [0, 1], sRGB-encoded.
// An RGB cube (is_rgb) is shown as it is, clamped, without the sRGB curve.
// Throws core::Error when shapes and wavelengths disagree.
torch::Tensor pseudo_rgb(const torch::Tensor& cube, const std::vector<double>& wavelengths_nm,
                         const PseudoRgbOptions& options = {});

// Same, as uint8 [H, W, 3] (rounded).
torch::Tensor pseudo_rgb_u8(const torch::Tensor& cube, const std::vector<double>& wavelengths_nm,
                            const PseudoRgbOptions& options = {});

// float [..] in [0, 1] -> uint8, rounded to nearest.
torch::Tensor to_u8(const torch::Tensor& unit);

}  // namespace ddhgs::core
