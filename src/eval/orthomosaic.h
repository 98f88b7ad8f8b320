// Orthomosaics: a georeferenced model rendered straight down over the
// flight's footprint, one consistent reflectance per point of the ground, on
// a north-up grid of the scene's projected CRS (io/geo/georef.h).
//
// The rasterizer is perspective; the orthographic view is made of tiles
// (kOrthoTile pixels square), each seen by a pinhole camera straight above
// its centre, so far up and with so narrow a field of view that a point
// off the ground plane lands where an orthographic projection puts it to
// within kOrthoParallaxPx. A point h above the plane, r pixels from its
// tile's centre, is displaced by r h / (D - h) pixels from a camera D above
// the plane; D is chosen from the largest r (the tile's corner) and the
// model's relief. The camera's view direction is straight down to within
// r gsd / D radians everywhere, so view-dependent colour is the nadir one.
// This leaves the rasterizer, its Jacobian and its tests as they are.
#pragma once
#include "core/tensor.h"

#include <vector>

#include "core/camera.h"
#include "io/geo/georef.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

constexpr int kOrthoTile = 512;             // pixels, each side
constexpr double kOrthoParallaxPx = 0.05;   // the largest displacement allowed
constexpr double kOrthoCoveredAlpha = 0.5;  // a pixel at least half covered holds a value

// A north-up grid in the CRS: pixel (col, row) covers east left_m + col gsd
// to + gsd and north top_m - row gsd to - gsd.
struct OrthoGrid {
  double left_m = 0, top_m = 0, gsd_m = 0;
  int64_t width = 0, height = 0;
  std::vector<double> geotransform() const { return {left_m, gsd_m, 0, top_m, 0, -gsd_m}; }
};

// Where the ground lies and how far the model reaches from it (CRS heights,
// m): the median height of the Gaussians' centres, and the height of the
// 99.9th percentile of their distances from it (at least one GSD).
struct Ground {
  double height_m = 0, relief_m = 0;
};
Ground model_ground(const model::Gaussians& gaussians, const io::Georeference& georef);

// The flight's footprint: every view's image corners cast onto the ground,
// on a grid whose edges are whole multiples of the GSD. gsd_m 0: the
// flight's own (the median over views of the camera's height above the
// ground over its focal length). core::Error when a view does not look down
// at the ground or the grid would exceed 40,000 pixels a side.
OrthoGrid flight_grid(const io::Scene& scene, const io::Georeference& georef, const Ground& ground,
                      double gsd_m);

// The pinhole camera (scene frame) above tile (tile_col, tile_row) of the
// grid, and the CRS height of its centre.
core::Camera ortho_tile_camera(const OrthoGrid& grid, const io::Georeference& georef,
                               const Ground& ground, int64_t tile_col, int64_t tile_row);

struct Orthomosaic {
  torch::Tensor image;  // [H, W, M] float32: what a camera straight above sees
  torch::Tensor alpha;  // [H, W] float32: how much of the pixel the Gaussians cover
};

// The Gaussians rendered over the grid, tile by tile, over the run's
// background [N] as every view is rendered (a colour model's output map
// applies). Training fits that composite to the captures, so it is the
// model's reflectance; the Gaussians' colour alone (image / alpha) is not
// fitted where alpha < 1, and a model that leaves the ground part
// transparent (alpha 0.84 on average on the synthetic strip) would read
// brighter or darker there by its background's difference.
Orthomosaic render_orthomosaic(const model::Gaussians& gaussians, const io::Georeference& georef,
                               const OrthoGrid& grid, const Ground& ground,
                               const torch::Tensor& background);

}  // namespace ddhgs::eval
