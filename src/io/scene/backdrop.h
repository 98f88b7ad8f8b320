// The backdrop of a capture. Real captures are often masked to a uniform
// backdrop (white for Hyper-NeRF's Surface Optics scenes). Training starts
// its background from the colour the views show at their borders, so the
// backdrop goes into the background instead of being painted by Gaussians;
// evaluation measures the object alone (the pixels that differ from the
// backdrop), since on a masked view the backdrop is most of the image and is
// matched almost exactly, which lifts the whole-image figures.
#pragma once
#include "core/tensor.h"

#include <optional>
#include <string>
#include <vector>

#include "io/scene/scene.h"

namespace ddhgs::io {

// How much of the views the border is read from: up to this many views,
// this many pixels in from the edge.
constexpr int kBorderViews = 16;
constexpr int kBorderPx = 2;

// Per-band median of the pixels within border_px of the image edge, over up
// to max_views of `views` spread along the list: [N] float32. The median
// ignores the object where it touches the border in a minority of the pixels.
torch::Tensor border_colour(const Scene& scene, const std::vector<int>& views,
                            int max_views = kBorderViews, int border_px = kBorderPx);

// A pixel belongs to the backdrop when every band is within this of the
// backdrop's value (reflectance units). JPEG noise on Basil's white backdrop
// stays within 0.02; its darkest leaves and its pot are 0.5 away and more.
constexpr double kBackdropTolerance = 0.04;

// The border colour (as above, with the default counts) and the share of the
// same border pixels that lie within tolerance of it in every band.
struct BorderScan {
  torch::Tensor colour;  // [N]
  double share = 0;      // 0-1
};
BorderScan scan_border(const Scene& scene, const std::vector<int>& views,
                       double tolerance = kBackdropTolerance);

// A masked capture's backdrop needs at least this share of the border on it
// (a natural scene's border varies). Basil: 79 % (the rest is the black
// turntable in some views).
constexpr double kBackdropMinShare = 0.5;

// The views' backdrop when they are masked to a uniform one: the border
// colour if at least min_share of the border lies on it; otherwise none.
std::optional<torch::Tensor> masked_backdrop(const Scene& scene, const std::vector<int>& views,
                                             double tolerance = kBackdropTolerance,
                                             double min_share = kBackdropMinShare);

// "0.990, 0.980, 1.000" for up to 4 bands, else "0.100 to 0.900 over 128 bands".
std::string describe_colour(const torch::Tensor& values);  // [N]

// The object of a masked view: [H, W] bool, true where some band differs
// from the backdrop by more than tolerance.
torch::Tensor object_mask(const torch::Tensor& image,     // [H, W, N]
                          const torch::Tensor& backdrop,  // [N]
                          double tolerance = kBackdropTolerance);

// The object's interior: the pixels of mask whose 8 neighbours are all in it
// (outside the image counts as in it, so an object cut by the frame has no
// outline there): [H, W] bool. The one-pixel outline left out is where a
// novel view's silhouette error sits.
torch::Tensor interior(const torch::Tensor& mask);  // [H, W] bool

}  // namespace ddhgs::io
