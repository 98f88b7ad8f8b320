#include "io/scene/backdrop.h"

#include <algorithm>
#include <cstdio>

#include "core/error.h"

namespace ddhgs::io {

namespace {

// The pixels within border_px of the edge of up to max_views of `views`:
// [P, N] float32.
torch::Tensor border_pixels(const Scene& scene, const std::vector<int>& views, int max_views,
                            int border_px) {
  core::require(!views.empty(), scene.root, "no views to take the border colour from");
  core::require(max_views > 0 && border_px > 0, "border_colour: expected positive counts");
  const size_t count = std::min(views.size(), size_t(max_views));
  std::vector<torch::Tensor> pixels;  // [P_i, N] each
  for (size_t i = 0; i < count; ++i) {
    const torch::Tensor image = scene.image(views[i * views.size() / count]);  // [H, W, N]
    const int64_t h = image.size(0), w = image.size(1), n = image.size(2);
    const int64_t b = std::min<int64_t>(border_px, std::min(h, w) / 2);
    if (b == 0) {
      pixels.push_back(image.reshape({-1, n}));
      continue;
    }
    // Copies: a view of the top or bottom rows would keep the whole float
    // image alive (185 MB for a 640x512x141 view) until the median.
    pixels.push_back(image.slice(0, 0, b).reshape({-1, n}).clone());
    pixels.push_back(image.slice(0, h - b, h).reshape({-1, n}).clone());
    pixels.push_back(image.slice(0, b, h - b).slice(1, 0, b).reshape({-1, n}));
    pixels.push_back(image.slice(0, b, h - b).slice(1, w - b, w).reshape({-1, n}));
  }
  return torch::cat(pixels, 0).to(torch::kFloat32);
}

torch::Tensor median_colour(const torch::Tensor& pixels) {  // [P, N]
  return std::get<0>(pixels.median(0)).contiguous();
}

}  // namespace

torch::Tensor border_colour(const Scene& scene, const std::vector<int>& views, int max_views,
                            int border_px) {
  return median_colour(border_pixels(scene, views, max_views, border_px));
}

BorderScan scan_border(const Scene& scene, const std::vector<int>& views, double tolerance) {
  const torch::Tensor pixels = border_pixels(scene, views, kBorderViews, kBorderPx);
  BorderScan scan;
  scan.colour = median_colour(pixels);
  scan.share =
      ((pixels - scan.colour).abs().amax(1) <= tolerance).to(torch::kFloat64).mean().item<double>();
  return scan;
}

std::optional<torch::Tensor> masked_backdrop(const Scene& scene, const std::vector<int>& views,
                                             double tolerance, double min_share) {
  BorderScan scan = scan_border(scene, views, tolerance);
  if (scan.share < min_share) return std::nullopt;
  return scan.colour;
}

std::string describe_colour(const torch::Tensor& values) {
  char text[96];
  if (values.numel() <= 4) {
    std::string out;
    for (int64_t i = 0; i < values.numel(); ++i) {
      std::snprintf(text, sizeof text, "%s%.3f", i ? ", " : "", values[i].item<double>());
      out += text;
    }
    return out;
  }
  std::snprintf(text, sizeof text, "%.3f to %.3f over %lld bands", values.min().item<double>(),
                values.max().item<double>(), (long long)values.numel());
  return text;
}

torch::Tensor object_mask(const torch::Tensor& image, const torch::Tensor& backdrop,
                          double tolerance) {
  core::require(image.dim() == 3 && backdrop.dim() == 1 && backdrop.size(0) == image.size(2),
                "object_mask: expected an [H, W, N] image and an [N] backdrop");
  const torch::Tensor b = backdrop.to(image.scalar_type()).view({1, 1, -1});
  return (image - b).abs().amax(2) > tolerance;
}

torch::Tensor interior(const torch::Tensor& mask) {
  core::require(mask.dim() == 2, "interior: expected an [H, W] mask");
  // A pixel is interior when no backdrop pixel is among its 8 neighbours:
  // max-pool the backdrop; the pooling's padding counts as object.
  const torch::Tensor backdrop = (~mask).to(torch::kFloat32).unsqueeze(0).unsqueeze(0);
  const torch::Tensor near = torch::max_pool2d(backdrop, {3, 3}, {1, 1}, {1, 1});
  return near.squeeze(0).squeeze(0) == 0;
}

}  // namespace ddhgs::io
