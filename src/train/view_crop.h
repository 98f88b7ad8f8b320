// The part of a training view an iteration measures (loss.view_fraction).
// The rasterizer's cost is per Gaussian-pixel pair, so a step on a random
// crop of the view costs about the crop's share of a whole-view step: the
// render, the decode, the loss and their backward. The crops cover every
// pixel equally often, and the loss is weighted so that its gradient is the
// whole view's in expectation.
#pragma once
#include "core/tensor.h"

#include <cstdint>

#include "core/camera.h"

namespace ddhgs::train {

// Smallest crop side (pixels): the SSIM window (11) fits, and a crop spans
// at least one tile.
constexpr int kMinCropSide = 16;

struct ViewCrop {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // pixels [x0, x1) x [y0, y1) of the view
  // Multiplies the loss (a mean over the crop's pixels): crop area / mean
  // crop area, so every pixel's weight is 1 / mean crop area whatever crop
  // it falls in. With the equal coverage, the expected gradient over the
  // draws is the whole view's (exactly for per-pixel terms such as L1; the
  // D-SSIM windows at the crop's edges see the edge as an image border).
  double loss_scale = 1;
  // The coverage (mean crop area / view area): multiplies the screen-space
  // gradients that densification accumulates: given that a Gaussian lies in
  // the crop, its gradient is 1 / coverage times a whole-view step's, and
  // densification compares their mean with a threshold set for whole views.
  double coverage = 1;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
};

// The fraction of a width x height view a step measures on average:
// view_fraction for a view of at least from_pixels pixels
// (loss.view_fraction_from_pixels), 1 (the whole view) for a smaller one.
// On small views the per-Gaussian part of a step (projection, SH, Adam) is
// a larger share, so a crop saves less than it costs in pixels measured.
double crop_fraction(double view_fraction, int64_t from_pixels, int width, int height);

// A crop of a width x height view measuring about fraction of its pixels on
// average (0 < fraction <= 1), from seed alone. Along each side a window of
// L pixels starts at an offset drawn uniformly from [-L + m, side - m] (m =
// kMinCropSide) and is clipped to the view: every pixel farther than m from
// the border is measured with the same probability, sqrt(fraction) per
// side; pixels nearer the border slightly less. fraction 1, or a side under
// 2 m, gives the whole view with scales 1.
ViewCrop draw_view_crop(int width, int height, double fraction, uint64_t seed);

// The camera that sees exactly the crop: same pose and focal lengths, the
// principal point moved by the crop's corner, the crop's size, and the view
// as its frame (core::Intrinsics). camera must see a whole view.
core::Camera crop_camera(const core::Camera& camera, const ViewCrop& crop);

}  // namespace ddhgs::train
