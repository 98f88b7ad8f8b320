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

// Per-band median of up to pixels_per_view pixels of each of up to
// max_views of `views` (the views chosen as border_colour chooses them, the
// pixels drawn with a seed fixed per view): [N] float32, the colour most of
// the views' pixels show, e.g. a nadir flight's commonest ground. A band no
// chosen view holds is 0.
torch::Tensor sampled_colour(const Scene& scene, const std::vector<int>& views, int max_views,
                             int64_t pixels_per_view);

// A pixel belongs to the backdrop when every band is within this of the
// backdrop's value (reflectance units). JPEG noise on Basil's white backdrop
// stays within 0.02; its darkest leaves and its pot are 0.5 away and more.
constexpr double kBackdropTolerance = 0.04;

// A masked capture's backdrop needs at least this share of the border on it
// (a natural scene's border varies). Basil: 79 % (the rest is the black
// turntable in some views).
constexpr double kBackdropMinShare = 0.5;
// ... and on most views: at least this share of the views sampled must each
// have min_share of their own border on it (views masked to one backdrop
// agree; a few where the object fills the frame's edge are allowed).
constexpr double kBackdropMinViewShare = 2.0 / 3.0;
// ... and a near-constant colour: the robust spread of the border pixels on
// it (1.4826 x their median absolute deviation from the colour, per band;
// the median over the bands) at most this (reflectance). Noise gathers near
// the colour (the demo scene's: 0.009); a texture spreads evenly over the
// tolerance (0.03 for an even spread over +-0.04).
constexpr double kBackdropMaxSpread = 0.02;
// ... and an object in front of it: a view's middle third counts as filled
// when this share of it is on the colour, and at most kBackdropMaxFilledShare
// of the views may be filled. A field or a floor seen from above fills the
// middle as it fills the border (the synthetic nadir strip: 5 of 8 views,
// its mat within the tolerance of the grey backdrop's colour); an object
// on a backdrop stands in the middle (demo: none of 16 views).
constexpr double kBackdropFilledCentre = 0.9;
constexpr double kBackdropMaxFilledShare = 1.0 / 3.0;

// What the views' borders show: the border colour (as border_colour, with
// the default counts), the share of the same border pixels within tolerance
// of it in every band, the share of the views with min_share of their own
// border on it, the spread of the border pixels on it, the share of the
// views whose middle it fills, and the verdict. The one test of a masked
// capture: `ddhgs info`, training's background and eval's object all ask it.
struct BorderScan {
  torch::Tensor colour;     // [N]
  double share = 0;         // 0-1, of the border pixels
  double view_share = 0;    // 0-1, of the views sampled
  double spread = 0;        // reflectance
  double filled_share = 0;  // 0-1, of the views sampled
  bool masked = false;      // every test passes
  std::string why_not;      // the first test that failed, as text; "" when masked
};
BorderScan scan_border(const Scene& scene, const std::vector<int>& views,
                       double tolerance = kBackdropTolerance, double min_share = kBackdropMinShare);

// The views' backdrop when they are masked to a uniform one (scan_border's
// verdict): the border colour; otherwise none.
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
