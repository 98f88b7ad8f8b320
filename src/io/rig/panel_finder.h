// Finding a calibration panel in a band image of a panel capture, wherever it
// lies.
//
// A reflectance panel is a flat, evenly grey square, brighter than the ground
// it lies on; beside it lie its QR label (white, but printed: not even) and
// whatever else the frame holds. The finder looks for it on a grid of
// blocks a few pixels wide (about 240 across the shorter side): windows of
// 5 x 5 blocks whose spread is under 3 % of their mean and whose mean is at
// least a quarter of the image's bright end, grouped into connected regions;
// a region is a panel candidate when it is as compact as a square or a
// rectangle (its area within 15 % of what its second moments give a
// rectangle, sides at most 1.5 : 1), and the largest candidate wins. At full
// resolution the panel is then grown from the candidate's centre over pixels
// within 25 % of its level, and the region measured is that panel shrunk by
// a sixth of its side on every side: its middle two thirds, away from the
// blurred edges, scratches at the rim and the shadow of a frame.
#pragma once
#include "core/tensor.h"

#include <array>
#include <optional>
#include <string>

namespace ddhgs::io {

struct PanelRegion {
  torch::Tensor mask;  // [H, W] bool: the pixels measured
  // Corners of the region, (x, y) pixels: top-left, top-right, bottom-right,
  // bottom-left (the region's extreme points along the diagonals).
  std::array<std::array<double, 2>, 4> corners{};
  int64_t pixels = 0;
  double panel_side_px = 0;  // the whole panel's side, sqrt of its area (0: given)
  bool found = true;         // false: the region was given (--panel-region)
  // Placed from the panel's QR label (io/rig/panel_label.h): its serial and
  // the code's corners (x, y pixels); empty label: not placed from one.
  std::string label;
  std::array<std::array<double, 2>, 4> label_corners{};
  double spread = 0;  // the signal's spread over its mean in the region (label placement)
};

// How the region was had, as process.json and `info` name it: "placed from
// its QR label", "found" or "given (--panel-region)".
std::string panel_region_source(const PanelRegion& region);

// signal: [H, W] float, counts above the black level. nullopt when no panel
// can be told apart.
std::optional<PanelRegion> find_panel(const torch::Tensor& signal);

// The rectangle x, y, w, h (pixels) of an H x W image as a region.
// core::Error naming `what` when it does not lie inside the image.
PanelRegion panel_region_from_box(int64_t height, int64_t width, const std::array<int64_t, 4>& box,
                                  const std::string& what);

}  // namespace ddhgs::io
