// Screen tiles: which Gaussians touch which 16x16 tile, in depth order, and
// which thread renders which tile. Internal to the render layer.
#pragma once
#include <cmath>
#include <cstdint>
#include <vector>

#include "render/splat_row.h"

namespace ddhgs::render {

constexpr int kTileSize = 16;  // pixels per tile side

struct TileRect {
  int x0, y0, x1, y1;  // tile index range [x0, x1) x [y0, y1)
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// floor(x) clamped to [0, n] as an int; NaN gives 0. Plain comparisons, not
// std::fmin / std::fmax, which GCC leaves as library calls.
inline int clamped_floor(double x, int n) {
  const double f = std::floor(x);
  return !(f > 0.0) ? 0 : f < double(n) ? int(f) : n;
}

// Tiles covered by the square of half-width radius_px around (u, v), as in
// 3DGS's getRect. Clamps in floating point first so off-screen values far out
// of int range stay well defined.
inline TileRect tile_rect(double u, double v, double radius_px, int tiles_x, int tiles_y) {
  auto lo = [](double c, double r, int n) { return clamped_floor((c - r) / kTileSize, n); };
  auto hi = [](double c, double r, int n) {
    return clamped_floor((c + r + kTileSize - 1) / kTileSize, n);
  };
  return {lo(u, radius_px, tiles_x), lo(v, radius_px, tiles_y), hi(u, radius_px, tiles_x),
          hi(v, radius_px, tiles_y)};
}

inline int tiles_along(int pixels) {
  return (pixels + kTileSize - 1) / kTileSize;
}

// Visible Gaussians ranked by depth (ties by index), per-tile lists of those
// ranks, and a balanced, deterministic assignment of tiles to threads. Tile
// lists hold ranks rather than Gaussian indices so that per-rank data laid
// out in depth order is walked forwards through memory by every tile.
struct TileBins {
  int tiles_x = 0, tiles_y = 0;
  std::vector<int32_t> order;    // [visible] Gaussian index of each depth rank
  std::vector<int32_t> offsets;  // [tiles + 1] into ranks
  std::vector<int32_t> ranks;    // depth ranks, tile-major, increasing within a tile
  std::vector<std::vector<int32_t>> thread_tiles;  // [threads][...] tile indices
  // [G] alpha >= 1/255 extent of each Gaussian, by Gaussian index; set for
  // the visible ones only (the splat records reuse them).
  std::vector<SplatExtent> extents;

  int num_tiles() const { return tiles_x * tiles_y; }
};

// Fills bins (buffers keep their capacity between calls). radii == 0 means
// culled. A Gaussian is listed in the tiles of its radius square (3DGS) that
// its alpha >= 1/255 bounding box also touches: the other tiles could never
// blend it. means2d: [G, 2] pixels, conics: [G, 3], opacities: [G],
// depths: [G], radii: [G].
void bin_gaussians(const float* means2d, const float* conics, const float* opacities,
                   const float* depths, const int32_t* radii, int64_t count, int width, int height,
                   int threads, TileBins& bins);

}  // namespace ddhgs::render
