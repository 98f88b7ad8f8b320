// 8-bit images (PNG, JPEG) for pseudo-RGB views and previews.
#pragma once
#include "core/tensor.h"

#include <filesystem>

namespace ddhgs::io {

// uint8 [H, W, C] with C = 1 to 4 as stored (2: grey and alpha).
torch::Tensor read_image(const std::filesystem::path& path);

// image: uint8 [H, W, C] or [H, W] (C = 1 to 4), or float in [0, 1] (clamped,
// rounded; NaN written as 0). PNG; atomic write.
void write_png(const std::filesystem::path& path, const torch::Tensor& image);

}  // namespace ddhgs::io
