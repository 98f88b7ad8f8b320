// 8-bit images (PNG, JPEG) for pseudo-RGB views and previews.
#pragma once
#include <torch/torch.h>

#include <filesystem>

namespace ddhgs::io {

// uint8 [H, W, C] with C = 1, 3 or 4 as stored.
torch::Tensor read_image(const std::filesystem::path& path);

// image: uint8 [H, W, C] (C = 1 or 3), or float [H, W, C] in [0, 1] (clamped,
// rounded). PNG; atomic write.
void write_png(const std::filesystem::path& path, const torch::Tensor& image);

}  // namespace ddhgs::io
