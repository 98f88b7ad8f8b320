#include "eval/colormap.h"

#include <algorithm>
#include <array>

#include "core/error.h"
#include "core/text.h"

namespace ddhgs::eval {
namespace {

// Viridis by Stefan van der Walt and Nathaniel Smith (CC0), as listed in
// matplotlib's _cm_listed.py: entries 0, 16, 32, ..., 240 and 255 of its
// 256-entry table. Linear interpolation between these 17 anchors stays within
// about 0.005 of the full table, well under one 8-bit step.
constexpr int kViridisAnchors = 17;
constexpr double kViridis[kViridisAnchors][3] = {
    {0.267004, 0.004874, 0.329415}, {0.282327, 0.094955, 0.417331}, {0.278826, 0.175490, 0.483397},
    {0.258965, 0.251537, 0.524736}, {0.229739, 0.322361, 0.545706}, {0.199430, 0.387607, 0.554642},
    {0.172719, 0.448791, 0.557885}, {0.149039, 0.508051, 0.557250}, {0.127568, 0.566949, 0.550556},
    {0.120638, 0.625828, 0.533488}, {0.157851, 0.683765, 0.501686}, {0.246070, 0.738910, 0.452024},
    {0.369214, 0.788888, 0.382914}, {0.515992, 0.831158, 0.294279}, {0.678489, 0.863742, 0.189503},
    {0.845561, 0.887322, 0.099702}, {0.993248, 0.906157, 0.143936}};

// Table position (in 1/255 units) of anchor i.
double anchor_position(int i) {
  return i == kViridisAnchors - 1 ? 255.0 : 16.0 * i;
}

// ColorBrewer's 11-class RdYlGn (Cynthia Brewer, Apache 2.0), evenly spaced
// from 0 to 1; interpolated linearly between them.
constexpr int kRdYlGnAnchors = 11;
constexpr unsigned kRdYlGn[kRdYlGnAnchors] = {0xa50026, 0xd73027, 0xf46d43, 0xfdae61,
                                              0xfee08b, 0xffffbf, 0xd9ef8b, 0xa6d96a,
                                              0x66bd63, 0x1a9850, 0x006837};

std::array<double, 3> rdylgn(double v) {
  const double position = v * (kRdYlGnAnchors - 1);
  const int i = std::min(int(position), kRdYlGnAnchors - 2);
  const double t = position - i;
  std::array<double, 3> rgb{};
  for (int c = 0; c < 3; ++c) {
    const int shift = 16 - 8 * c;
    const double a = double((kRdYlGn[i] >> shift) & 0xff) / 255;
    const double b = double((kRdYlGn[i + 1] >> shift) & 0xff) / 255;
    rgb[size_t(c)] = a + t * (b - a);
  }
  return rgb;
}

}  // namespace

Colormap parse_colormap(const std::string& name) {
  if (name == "gray" || name == "grey") return Colormap::Gray;
  if (name == "viridis") return Colormap::Viridis;
  throw core::Error("--colormap: expected gray or viridis, got " + core::quoted_value(name));
}

std::array<double, 3> colormap_rgb(Colormap map, double value) {
  double v = std::clamp(value, 0.0, 1.0);
  if (map == Colormap::Gray) return {v, v, v};
  if (map == Colormap::RdYlGn) return rdylgn(v);
  double position = v * 255.0;
  int i = 0;
  while (i + 2 < kViridisAnchors && anchor_position(i + 1) <= position) ++i;
  double t = (position - anchor_position(i)) / (anchor_position(i + 1) - anchor_position(i));
  std::array<double, 3> rgb{};
  for (int c = 0; c < 3; ++c) rgb[c] = kViridis[i][c] + t * (kViridis[i + 1][c] - kViridis[i][c]);
  return rgb;
}

torch::Tensor apply_colormap(const torch::Tensor& values, Colormap map) {
  core::require(values.dim() == 2, "colormap: expected an [H, W] image");
  if (map == Colormap::Gray)
    return values.to(torch::kFloat).clamp(0, 1).unsqueeze(-1).expand({-1, -1, 3}).contiguous();
  // A 256-entry lookup table: finer than 8-bit output can show.
  torch::Tensor table = torch::empty({256, 3}, torch::kFloat);
  auto t = table.accessor<float, 2>();
  for (int i = 0; i < 256; ++i) {
    std::array<double, 3> rgb = colormap_rgb(map, i / 255.0);
    for (int c = 0; c < 3; ++c) t[i][c] = float(rgb[c]);
  }
  torch::Tensor index =
      (values.to(torch::kFloat).clamp(0, 1) * 255.0f).round().to(torch::kLong);  // [H, W]
  return table.index_select(0, index.flatten()).view({values.size(0), values.size(1), 3});
}

}  // namespace ddhgs::eval
