// Colour maps for single-band pictures and error heatmaps.
#pragma once
#include "core/tensor.h"

#include <array>
#include <string>

namespace ddhgs::eval {

enum class Colormap {
  Gray,     // black to white
  Viridis,  // perceptually uniform, colour-blind friendly (matplotlib's default)
  RdYlGn,   // diverging red - yellow - green: vegetation indices, -1 at 0 and 1 at 1
};

// "gray" / "grey" / "viridis" (the --colormap choices); core::Error naming the
// option otherwise. RdYlGn is for vegetation indices only.
Colormap parse_colormap(const std::string& name);

// Colour of a value in [0, 1] (clamped) as linear-interpolated display RGB in [0, 1].
std::array<double, 3> colormap_rgb(Colormap map, double value);

// values: float [H, W] in [0, 1] (clamped). Returns float32 [H, W, 3]
// display RGB in [0, 1].
torch::Tensor apply_colormap(const torch::Tensor& values, Colormap map);

}  // namespace ddhgs::eval
