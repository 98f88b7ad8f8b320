#include "eval/vegetation_index.h"

#include <cmath>

#include "core/band_map.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"

namespace ddhgs::eval {

namespace {

// MicaSense RedEdge-MX's published centres and widths (the bands most
// plant-science indices are defined with).
constexpr BroadBand kGreen{"green", 560, 27};
constexpr BroadBand kRed{"red", 668, 14};
constexpr BroadBand kRedEdge{"red edge", 717, 12};
constexpr BroadBand kNir{"NIR", 842, 57};

// One row: the mean of the bands inside the window, else the interpolation
// at its centre.
torch::Tensor broad_band_row(const BroadBand& band, const std::vector<double>& wavelengths_nm) {
  const int64_t n = int64_t(wavelengths_nm.size());
  torch::Tensor row = torch::zeros({n}, torch::kFloat64);
  int64_t inside = 0;
  for (int64_t i = 0; i < n; ++i)
    if (std::abs(wavelengths_nm[size_t(i)] - band.centre_nm) <= band.fwhm_nm / 2) {
      row[i] = 1.0;
      ++inside;
    }
  if (inside > 0) return row / double(inside);
  try {
    return core::interpolation_map(wavelengths_nm, {band.centre_nm})[0];
  } catch (const core::Error& e) {
    throw core::Error(std::string("the ") + band.name + " band at " +
                      core::format_g(band.centre_nm) + " nm: " + e.what());
  }
}

}  // namespace

const std::vector<VegetationIndex>& vegetation_indices() {
  static const std::vector<VegetationIndex> indices = {
      {"ndvi", kNir, kRed}, {"ndre", kNir, kRedEdge}, {"gndvi", kNir, kGreen}};
  return indices;
}

const VegetationIndex& find_vegetation_index(const std::string& name, const std::string& option) {
  std::string names;
  for (const VegetationIndex& index : vegetation_indices()) {
    if (index.name == name) return index;
    names += (names.empty() ? "" : ", ") + index.name;
  }
  throw core::Error(option + ": unknown index " + core::quoted_value(name) + " (one of " + names +
                    ")");
}

torch::Tensor index_band_map(const VegetationIndex& index,
                             const std::vector<double>& wavelengths_nm) {
  try {
    return torch::stack(
        {broad_band_row(index.a, wavelengths_nm), broad_band_row(index.b, wavelengths_nm)});
  } catch (const core::Error& e) {
    throw core::Error(index.name + ": " + e.what());
  }
}

torch::Tensor index_values(const torch::Tensor& image, const torch::Tensor& band_map,
                           double min_sum) {
  core::require(image.dim() == 3 && image.size(2) == band_map.size(1),
                "vegetation index: the image's bands do not match the band map");
  const torch::Tensor ab = torch::matmul(image.to(torch::kFloat64), band_map.t());  // [H, W, 2]
  const torch::Tensor a = ab.select(2, 0), b = ab.select(2, 1);
  const torch::Tensor sum = a + b;
  torch::Tensor values = (a - b) / sum;
  values = torch::where(sum > min_sum, values, torch::full_like(values, NAN));
  return values.to(torch::kFloat);
}

torch::Tensor index_picture(const torch::Tensor& values) {
  const torch::Tensor valid = values.isfinite();
  const torch::Tensor shown = torch::where(valid, (values + 1) / 2, torch::zeros_like(values));
  torch::Tensor picture = apply_colormap(shown, Colormap::RdYlGn);
  return torch::where(valid.unsqueeze(-1), picture, torch::full_like(picture, 0.5f));
}

}  // namespace ddhgs::eval
