// A calibration panel's QR label, and the panel region it places.
//
// MicaSense reflectance panels carry a QR code beside the grey square; its
// text is the panel's serial, RPvv-nnnnnnn-XX (vv: the panel's version;
// from version 4 a suffix adds the albedo at two wavelengths). The square
// lies at a fixed place relative to the code, one place per version, so the
// camera maker's library measures the region the label places, not the
// square it sees. The layouts here are those of MicaSense's library
// (micasense/imageprocessing, MIT), written in the code's own frame: the
// code's corners, in the order the decoder gives them, are (0, 0), (1, 0),
// (1, 1), (0, 1), so a unit is the code's side and the region follows the
// label however it lies in the image. Versions 1-2: a square 1.33 code
// sides wide, level with the code and half a side beyond it; versions 3 and
// later: a square 0.73 sides wide, 0.7 sides beyond the code's edge.
//
// The frame is a pinhole one, as the maker's: the label is read in the
// undistorted image and the layout applied there (a panel is flat, so the
// layout is affine in a pinhole image, not in a distorted one); the region's
// corners are then distorted back into the image. The decoder does not say which
// corner is the code's first, so all four cyclic orders are tried and the
// most even region (lowest spread over mean) lying inside the image is kept,
// as the maker's library does.
#pragma once
#include <array>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/tensor.h"
#include "io/rig/panel_finder.h"

namespace ddhgs::io {

struct PanelLabel {
  std::string serial;  // the code's text, RPvv-nnnnnnn-XX...
  int version = 0;     // vv
  // The code's corners in image pixels (x, y; pixel centres at integers), in
  // the decoder's order.
  std::array<std::array<double, 2>, 4> corners{};
};

// The QR label of a MicaSense panel in an image ([H, W], scaled to 8 bits
// between its darkest and brightest pixel for the decoder, zbar); corners in
// that image's pixels. nullopt when no code is decoded or its text
// is not a panel serial.
std::optional<PanelLabel> read_panel_label(const torch::Tensor& signal);

// The pinhole camera of the maker's undistorted images: OpenCV's
// getOptimalNewCameraMatrix with alpha 1 for `lens` (with distortion), whose
// frame just holds the undistorted 9 x 9 grid of points spanning the image
// (pixel centres at integers); the same size, no distortion.
core::Intrinsics maker_pinhole(const core::Intrinsics& lens);

// The panel a MicaSense label places in a band image (signal: [H, W] counts
// above the black level) seen through `lens` (the band camera: focal
// lengths, principal point, distortion), found as the maker's library finds
// it: the label is read in the undistorted image (OpenCV's
// getOptimalNewCameraMatrix camera with alpha 1, bilinear), the layout
// applied there, and the region's corners distorted back into the image.
// The region's corners, the label's serial and its corners (in the image)
// are recorded. nullopt when no label is read, its version has no known
// layout, or no order of its corners places a region wholly inside the
// image.
std::optional<PanelRegion> find_labelled_panel(const torch::Tensor& signal,
                                               const core::Intrinsics& lens);

}  // namespace ddhgs::io
