#include "train/background.h"

#include <algorithm>

#include "core/error.h"

namespace ddhgs::train {

torch::Tensor border_colour(const io::Scene& scene, const std::vector<int>& views, int max_views,
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
  return std::get<0>(torch::cat(pixels, 0).median(0)).to(torch::kFloat32).contiguous();
}

}  // namespace ddhgs::train
