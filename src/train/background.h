// Where the background colour starts. Real captures are often masked to a
// uniform backdrop (white for Hyper-NeRF's Surface Optics scenes): with a
// fixed black background the Gaussians must paint that backdrop themselves,
// and test views fail wherever they did not. Starting from the colour the
// views show at their borders puts the backdrop in the background instead.
#pragma once
#include <torch/torch.h>

#include <vector>

#include "io/scene/scene.h"

namespace ddhgs::train {

// Per-band median of the pixels within border_px of the image edge, over up
// to max_views of `views` spread along the list: [N] float32. The median
// ignores the object where it touches the border in a minority of the pixels.
torch::Tensor border_colour(const io::Scene& scene, const std::vector<int>& views,
                            int max_views = 16, int border_px = 2);

}  // namespace ddhgs::train
