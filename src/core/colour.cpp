#include "core/colour.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/colour_tables.h"
#include "core/error.h"

namespace ddhgs::core {

namespace {

// Linear interpolation in a 5 nm table; zero outside 380-780 nm.
template <typename Get>
double table_lookup(double wavelength_nm, Get get) {
  double t = (wavelength_nm - kColourTableStartNm) / kColourTableStepNm;
  if (!(t >= 0) || t > kColourTableRows - 1) return 0.0;
  int i = std::min(int(t), kColourTableRows - 2);
  double f = t - i;
  return get(i) * (1 - f) + get(i + 1) * f;
}

// CIE's own definition of illuminant A (c2 = 1.435e7 nm K with 2848 K, which
// equals 2856 K with today's c2), relative power 100 at 560 nm.
double illuminant_a(double wavelength_nm) {
  const double c = 1.435e7 / 2848.0;  // nm
  return 100.0 * std::pow(560.0 / wavelength_nm, 5) * std::expm1(c / 560.0) /
         std::expm1(c / wavelength_nm);
}

void check_wavelengths(const std::vector<double>& wavelengths_nm) {
  for (size_t i = 0; i < wavelengths_nm.size(); ++i) {
    require(std::isfinite(wavelengths_nm[i]),
            "wavelengths: expected finite values (nm), got a NaN or Inf");
    require(i == 0 || wavelengths_nm[i] > wavelengths_nm[i - 1],
            "wavelengths: expected strictly increasing values (nm)");
  }
}

// Integral of illuminant x CMF over [lo, hi] nm (trapezoids of at most 1 nm).
Xyz integrate(double lo_nm, double hi_nm, Illuminant illuminant) {
  Xyz sum;
  if (hi_nm <= lo_nm) return sum;
  int steps = std::max(1, int(std::ceil(hi_nm - lo_nm)));
  double h = (hi_nm - lo_nm) / steps;
  for (int k = 0; k <= steps; ++k) {
    double nm = lo_nm + k * h;
    double w = (k == 0 || k == steps) ? 0.5 * h : h;
    double s = illuminant_power(illuminant, nm) * w;
    Xyz c = cie1931_cmf(nm);
    sum.x += s * c.x;
    sum.y += s * c.y;
    sum.z += s * c.z;
  }
  return sum;
}

torch::Tensor matrix_tensor() {
  const auto& m = xyz_to_linear_srgb_matrix();
  return torch::tensor(std::vector<double>(m.begin(), m.end()), torch::kFloat64).reshape({3, 3});
}

// Linear RGB [P, 3] -> display [P, 3] in [0, 1].
torch::Tensor finish(torch::Tensor linear, double exposure, bool encode) {
  linear = (linear * exposure).clamp(0.0, 1.0);
  return encode ? srgb_encode(linear) : linear;
}

std::vector<double> parse_numbers(const std::string& text, const std::string& where) {
  std::string cleaned = text;
  for (char& ch : cleaned)
    if (ch == ',' || ch == ';') ch = ' ';
  std::istringstream in(cleaned);
  std::vector<double> values;
  std::string token;
  while (in >> token) {
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(token, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    require(used == token.size() && std::isfinite(v),
            where + ": expected numbers, got '" + token + "'");
    values.push_back(v);
  }
  return values;
}

PseudoRgbOptions read_map_file(const std::string& path) {
  std::ifstream in(path);
  require(bool(in), path, "cannot open the pseudo-RGB map file");
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    auto values = parse_numbers(line, path);
    if (!values.empty()) rows.push_back(std::move(values));
  }
  require(rows.size() == 3 || rows.size() == 4, path,
          "expected 3 rows (R, G, B weights) and an optional row of band indices");
  size_t k = rows[0].size();
  for (const auto& row : rows) require(row.size() == k, path, "expected rows of equal length");
  PseudoRgbOptions options;
  options.mode = PseudoRgbMode::LinearMap;
  std::vector<float> flat;
  for (int r = 0; r < 3; ++r) flat.insert(flat.end(), rows[r].begin(), rows[r].end());
  options.linear_map = torch::tensor(flat).reshape({3, int64_t(k)});
  if (rows.size() == 4)
    for (double v : rows[3]) {
      require(v >= 0 && v == std::floor(v), path, "expected non-negative integer band indices");
      options.band_indices.push_back(int64_t(v));
    }
  return options;
}

}  // namespace

Xyz cie1931_cmf(double wavelength_nm) {
  return {table_lookup(wavelength_nm, [](int i) { return kCie1931Cmf[i][0]; }),
          table_lookup(wavelength_nm, [](int i) { return kCie1931Cmf[i][1]; }),
          table_lookup(wavelength_nm, [](int i) { return kCie1931Cmf[i][2]; })};
}

double illuminant_power(Illuminant illuminant, double wavelength_nm) {
  switch (illuminant) {
    case Illuminant::D65:
      return table_lookup(wavelength_nm, [](int i) { return kD65Power[i]; });
    case Illuminant::A:
      return wavelength_nm > 0 ? illuminant_a(wavelength_nm) : 0.0;
    case Illuminant::Equal:
      return 100.0;
  }
  return 0.0;
}

double planck_radiance(double wavelength_nm, double temperature_k) {
  const double h = 6.62607015e-34, c = 2.99792458e8, k = 1.380649e-23;
  double lambda = wavelength_nm * 1e-9;
  return 2 * h * c * c / std::pow(lambda, 5) / std::expm1(h * c / (lambda * k * temperature_k));
}

Illuminant parse_illuminant(const std::string& name) {
  if (name == "D65" || name == "d65") return Illuminant::D65;
  if (name == "A" || name == "a") return Illuminant::A;
  if (name == "E" || name == "e") return Illuminant::Equal;
  throw Error("illuminant '" + name + "': expected D65, A or E");
}

double srgb_encode(double linear) {
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
}

double srgb_decode(double encoded) {
  return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

torch::Tensor srgb_encode(const torch::Tensor& linear) {
  auto x = linear.clamp_min(0);
  return torch::where(x <= 0.0031308, x * 12.92, 1.055 * x.pow(1 / 2.4) - 0.055);
}

const std::array<double, 9>& xyz_to_linear_srgb_matrix() {
  // sRGB primaries with the D65 white point (Lindbloom's precise form).
  static const std::array<double, 9> m{3.2404542, -1.5371385, -0.4985314, -0.9692660, 1.8760108,
                                       0.0415560, 0.0556434,  -0.2040259, 1.0572252};
  return m;
}

PseudoRgbOptions parse_pseudo_rgb(const std::string& spec) {
  PseudoRgbOptions options;
  auto colon = spec.find(':');
  std::string kind = spec.substr(0, colon);
  std::string rest = colon == std::string::npos ? "" : spec.substr(colon + 1);
  if (kind == "cie") {
    std::istringstream parts(rest);
    std::string part;
    while (std::getline(parts, part, ':')) {
      if (part == "balanced")
        options.white_balance = true;
      else
        options.illuminant = parse_illuminant(part);
    }
    return options;
  }
  if (kind == "bands") {
    options.mode = PseudoRgbMode::Bands;
    options.rgb_bands_nm = parse_numbers(rest, "pseudo-RGB '" + spec + "'");
    require(options.rgb_bands_nm.size() == 3,
            "pseudo-RGB '" + spec + "': expected bands:R,G,B with three wavelengths in nm");
    options.map_output_linear = true;  // band values are linear reflectance
    return options;
  }
  if (kind == "map") {
    require(!rest.empty(), "pseudo-RGB '" + spec + "': expected map:FILE");
    return read_map_file(rest);
  }
  throw Error("pseudo-RGB '" + spec +
              "': expected cie[:D65|A|E][:balanced], bands:R,G,B or map:FILE");
}

torch::Tensor cie_band_weights(const std::vector<double>& wavelengths_nm, Illuminant illuminant) {
  check_wavelengths(wavelengths_nm);
  const int64_t n = int64_t(wavelengths_nm.size());
  auto weights = torch::zeros({n, 3}, torch::kFloat64);
  auto w = weights.accessor<double, 2>();
  for (int64_t i = 0; i < n; ++i) {
    // A band spans the midpoints to its neighbours; the outer bands extend
    // as far outwards as inwards (a lone band is taken as 10 nm wide).
    double left = i > 0   ? wavelengths_nm[i - 1]
                  : n > 1 ? 2 * wavelengths_nm[0] - wavelengths_nm[1]
                          : wavelengths_nm[0] - 10;
    double right = i + 1 < n ? wavelengths_nm[i + 1]
                   : n > 1   ? 2 * wavelengths_nm[n - 1] - wavelengths_nm[n - 2]
                             : wavelengths_nm[0] + 10;
    double lo = std::max(0.5 * (left + wavelengths_nm[i]), kCmfMinNm);
    double hi = std::min(0.5 * (right + wavelengths_nm[i]), kCmfMaxNm);
    Xyz s = integrate(lo, hi, illuminant);
    w[i][0] = s.x;
    w[i][1] = s.y;
    w[i][2] = s.z;
  }
  return weights;
}

const std::vector<double>& rgb_channel_wavelengths_nm() {
  static const std::vector<double> wavelengths = {610, 550, 465};
  return wavelengths;
}

bool is_rgb(const std::vector<double>& wavelengths_nm, int64_t bands) {
  return bands == 3 && (wavelengths_nm.empty() || wavelengths_nm == rgb_channel_wavelengths_nm());
}

torch::Tensor cie_linear_srgb_map(const std::vector<double>& wavelengths_nm,
                                  Illuminant illuminant) {
  auto weights = cie_band_weights(wavelengths_nm, illuminant);  // [N, 3]
  double white_y = weights.select(1, 1).sum().item<double>();
  if (white_y <= 0) return torch::zeros_like(weights);
  return weights.matmul(matrix_tensor().t()) / white_y;
}

torch::Tensor pseudo_rgb(const torch::Tensor& cube, const std::vector<double>& wavelengths_nm,
                         const PseudoRgbOptions& options) {
  require(cube.defined() && cube.dim() == 3, "pseudo-RGB: expected a cube [H, W, N]");
  const int64_t h = cube.size(0), w = cube.size(1), n = cube.size(2);
  auto pixels = cube.reshape({h * w, n}).to(torch::kFloat64);
  torch::Tensor rgb;
  if (is_rgb(wavelengths_nm, n) && options.mode == PseudoRgbMode::Cie) {
    rgb = finish(pixels, options.exposure, false);
  } else if (options.mode == PseudoRgbMode::Cie) {
    require(int64_t(wavelengths_nm.size()) == n, "pseudo-RGB: expected one wavelength per band (" +
                                                     std::to_string(n) + "), got " +
                                                     std::to_string(wavelengths_nm.size()));
    auto to_rgb = cie_linear_srgb_map(wavelengths_nm, options.illuminant);  // [N, 3]
    if (!to_rgb.any().item<bool>()) return torch::zeros({h, w, 3}, torch::kFloat32);
    auto linear = pixels.matmul(to_rgb);
    if (options.white_balance) linear = linear / to_rgb.sum(0).clamp_min(1e-12);
    rgb = finish(linear, options.exposure, true);
  } else if (options.mode == PseudoRgbMode::LinearMap) {
    const auto& map = options.linear_map;
    require(map.defined() && map.dim() == 2 && map.size(0) == 3,
            "pseudo-RGB map: expected a 3 x N or 3 x k matrix");
    torch::Tensor selected = pixels;
    if (!options.band_indices.empty()) {
      require(int64_t(options.band_indices.size()) == map.size(1),
              "pseudo-RGB map: expected one band index per column");
      for (int64_t b : options.band_indices)
        require(b >= 0 && b < n, "pseudo-RGB map: band index " + std::to_string(b) +
                                     " outside the cube's " + std::to_string(n) + " bands");
      selected = pixels.index_select(1, torch::tensor(options.band_indices, torch::kInt64));
    }
    require(map.size(1) == selected.size(1),
            "pseudo-RGB map: expected " + std::to_string(selected.size(1)) +
                " columns (one per band), got " + std::to_string(map.size(1)));
    rgb = finish(selected.matmul(map.to(torch::kFloat64).t()), options.exposure,
                 options.map_output_linear);
  } else {
    require(options.rgb_bands_nm.size() == 3, "pseudo-RGB bands: expected three wavelengths");
    require(int64_t(wavelengths_nm.size()) == n,
            "pseudo-RGB bands: expected one wavelength per band (" + std::to_string(n) + ")");
    std::vector<int64_t> index;
    for (double target : options.rgb_bands_nm) {
      auto nearest = std::min_element(
          wavelengths_nm.begin(), wavelengths_nm.end(),
          [&](double a, double b) { return std::abs(a - target) < std::abs(b - target); });
      index.push_back(int64_t(nearest - wavelengths_nm.begin()));
    }
    rgb = finish(pixels.index_select(1, torch::tensor(index, torch::kInt64)), options.exposure,
                 options.map_output_linear);
  }
  return rgb.to(torch::kFloat32).reshape({h, w, 3});
}

torch::Tensor to_u8(const torch::Tensor& unit) {
  return (unit.to(torch::kFloat32).clamp(0, 1) * 255.0f).round().to(torch::kUInt8);
}

torch::Tensor pseudo_rgb_u8(const torch::Tensor& cube, const std::vector<double>& wavelengths_nm,
                            const PseudoRgbOptions& options) {
  return to_u8(pseudo_rgb(cube, wavelengths_nm, options));
}

}  // namespace ddhgs::core
