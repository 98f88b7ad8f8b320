#include "eval/figures.h"

#include <algorithm>
#include <cstdio>

#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"

namespace ddhgs::eval {
namespace {

std::string trimmed_number(double value) {
  return core::format_g(value);
}

torch::Tensor pad_width(const torch::Tensor& picture, int64_t width) {
  if (picture.size(1) == width) return picture;
  torch::Tensor out = torch::ones({picture.size(0), width, 3}, torch::kFloat);
  out.narrow(1, 0, picture.size(1)).copy_(picture);
  return out;
}

}  // namespace

BandSelection select_bands(const std::string& band_index, const std::string& band_range_nm,
                           const std::vector<double>& wavelengths_nm) {
  BandSelection s;
  int64_t n = int64_t(wavelengths_nm.size());
  if (!band_index.empty()) {
    core::require(band_range_nm.empty(), "--band and --bands: give one of them, not both");
    size_t used = 0;
    int64_t index = -1;
    try {
      index = std::stoll(band_index, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    core::require(used == band_index.size() && index >= 0 && index < n,
                  "--band: expected a band index in 0.." + std::to_string(n - 1) + ", got " +
                      core::quoted_value(band_index));
    s.pseudo_rgb = false;
    s.first = s.last = index;
    s.label = "band" + std::to_string(index);
    return s;
  }
  if (band_range_nm.empty()) return s;
  double lo = 0, hi = 0;
  char colon = 0, extra = 0;
  int fields = std::sscanf(band_range_nm.c_str(), "%lf %c %lf %c", &lo, &colon, &hi, &extra);
  core::require(
      fields == 3 && colon == ':' && lo <= hi,
      "--bands: expected MIN:MAX in nm (e.g. 750:768), got " + core::quoted_value(band_range_nm));
  s.first = n;
  s.last = -1;
  for (int64_t b = 0; b < n; ++b)
    if (wavelengths_nm[size_t(b)] >= lo && wavelengths_nm[size_t(b)] <= hi) {
      s.first = std::min(s.first, b);
      s.last = std::max(s.last, b);
    }
  core::require(s.last >= 0, "--bands: no band lies in " + trimmed_number(lo) + "-" +
                                 trimmed_number(hi) + " nm (the model covers " +
                                 (n ? trimmed_number(wavelengths_nm.front()) + "-" +
                                          trimmed_number(wavelengths_nm.back()) + " nm)"
                                    : std::string("no bands)")));
  s.pseudo_rgb = false;
  s.label = trimmed_number(lo) + "-" + trimmed_number(hi) + "nm";
  return s;
}

torch::Tensor band_mean(const torch::Tensor& image, const BandSelection& bands) {
  if (bands.pseudo_rgb) return image.mean(-1);
  return image.narrow(-1, bands.first, bands.last - bands.first + 1).mean(-1);
}

torch::Tensor picture(const torch::Tensor& image, const std::vector<double>& wavelengths_nm,
                      const BandSelection& bands, Colormap map) {
  if (bands.pseudo_rgb) return core::pseudo_rgb(image, wavelengths_nm);
  return apply_colormap(band_mean(image, bands), map);
}

torch::Tensor error_heatmap(const torch::Tensor& render, const torch::Tensor& truth,
                            const BandSelection& bands, double max_error, Colormap map) {
  core::require(render.sizes() == truth.sizes(),
                "error heatmap: render and ground truth differ in shape");
  core::require(max_error > 0, "--diff-max: expected a positive error scale");
  torch::Tensor error = band_mean((render - truth).abs(), bands);  // [H, W]
  return apply_colormap(error / max_error, map);
}

torch::Tensor colour_bar(int64_t height, int64_t width, Colormap map) {
  torch::Tensor ramp = torch::linspace(0, 1, width).unsqueeze(0).expand({height, width});
  return apply_colormap(ramp.contiguous(), map);
}

torch::Tensor side_by_side(const std::vector<torch::Tensor>& pictures, int64_t gap_px) {
  core::require(!pictures.empty(), "side_by_side: no pictures");
  std::vector<torch::Tensor> parts;
  for (size_t i = 0; i < pictures.size(); ++i) {
    core::require(pictures[i].size(0) == pictures[0].size(0),
                  "side_by_side: pictures differ in height");
    if (i > 0) parts.push_back(torch::ones({pictures[0].size(0), gap_px, 3}, torch::kFloat));
    parts.push_back(pictures[i].to(torch::kFloat));
  }
  return torch::cat(parts, 1);
}

torch::Tensor stacked(const torch::Tensor& top, const torch::Tensor& bottom, int64_t gap_px) {
  int64_t width = std::max(top.size(1), bottom.size(1));
  return torch::cat(
      {pad_width(top.to(torch::kFloat), width), torch::ones({gap_px, width, 3}, torch::kFloat),
       pad_width(bottom.to(torch::kFloat), width)},
      0);
}

torch::Tensor comparison_panels(const torch::Tensor& truth, const torch::Tensor& render,
                                const torch::Tensor& error, Colormap map, int64_t bar_px,
                                int64_t gap_px) {
  torch::Tensor blank = torch::ones({bar_px, error.size(1), 3}, torch::kFloat);
  torch::Tensor legend =
      side_by_side({blank, blank, colour_bar(bar_px, error.size(1), map)}, gap_px);
  return stacked(side_by_side({truth, render, error}, gap_px), legend, gap_px);
}

}  // namespace ddhgs::eval
