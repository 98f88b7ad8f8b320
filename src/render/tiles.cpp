#include "render/tiles.h"

#include <algorithm>
#include <cstring>
#include <numeric>

#include "core/error.h"
#include "render/splat_row.h"

namespace ddhgs::render {
namespace {

// Order-preserving map from float to unsigned (negative depths sort first).
uint32_t sortable_bits(float value) {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
}

// Sort scratch reused between calls; thread_local so concurrent renders on
// different threads never share it.
struct SortScratch {
  std::vector<uint32_t> keys, keys_tmp;
  std::vector<int32_t> order, order_tmp;
};

// Stable LSD radix sort of `order` by `keys` (11-bit digits, 3 passes), so
// equal depths keep increasing Gaussian index.
void radix_sort(SortScratch& s) {
  const size_t n = s.keys.size();
  s.keys_tmp.resize(n);
  s.order_tmp.resize(n);
  constexpr int kBits = 11, kBuckets = 1 << kBits;
  std::vector<uint32_t> count(kBuckets);
  for (int shift = 0; shift < 32; shift += kBits) {
    std::fill(count.begin(), count.end(), 0u);
    for (size_t i = 0; i < n; ++i) ++count[(s.keys[i] >> shift) & (kBuckets - 1)];
    uint32_t sum = 0;
    for (auto& c : count) {
      const uint32_t here = c;
      c = sum;
      sum += here;
    }
    for (size_t i = 0; i < n; ++i) {
      const uint32_t slot = count[(s.keys[i] >> shift) & (kBuckets - 1)]++;
      s.keys_tmp[slot] = s.keys[i];
      s.order_tmp[slot] = s.order[i];
    }
    s.keys.swap(s.keys_tmp);
    s.order.swap(s.order_tmp);
  }
}

// Tiles in bands of kBand tile rows, each band walked column by column in
// serpentine order (down one column, up the next; bands alternate left to
// right and right to left), cut into one contiguous run per thread of about
// equal cost. Consecutive tiles are neighbours, and a tile's neighbours in
// both directions were rendered at most 2 kBand tiles earlier, so the splat
// records and colour rows they share are still in cache. Deterministic, so
// backward gradient sums per thread are reproducible run to run.
void assign_tiles(int threads, TileBins& bins) {
  constexpr int kBand = 4;  // tile rows
  const int n = bins.num_tiles();
  std::vector<int32_t> walk;
  walk.reserve(n);
  for (int band = 0; band * kBand < bins.tiles_y; ++band) {
    const int y0 = band * kBand, y1 = std::min(bins.tiles_y, y0 + kBand);
    for (int i = 0; i < bins.tiles_x; ++i) {
      const int tx = band % 2 == 0 ? i : bins.tiles_x - 1 - i;
      for (int j = 0; j < y1 - y0; ++j) {
        const int ty = (i % 2 == 0) ? y0 + j : y1 - 1 - j;
        walk.push_back(ty * bins.tiles_x + tx);
      }
    }
  }
  auto cost = [&](int t) { return int64_t(bins.offsets[t + 1] - bins.offsets[t]) + 1; };
  int64_t total = 0;
  for (int t = 0; t < n; ++t) total += cost(t);
  bins.thread_tiles.resize(threads);
  for (auto& list : bins.thread_tiles) list.clear();
  int64_t done = 0;
  for (const int t : walk) {
    // The thread whose share of the total cost holds this tile's midpoint.
    const int k = int(std::min<int64_t>(threads - 1, (2 * done + cost(t)) * threads / (2 * total)));
    bins.thread_tiles[k].push_back(t);
    done += cost(t);
  }
}

}  // namespace

void bin_gaussians(const float* means2d, const float* conics, const float* opacities,
                   const float* depths, const int32_t* radii, int64_t count, int width, int height,
                   int threads, TileBins& bins) {
  thread_local SortScratch scratch;
  bins.tiles_x = tiles_along(width);
  bins.tiles_y = tiles_along(height);
  scratch.keys.clear();
  scratch.order.clear();
  for (int64_t i = 0; i < count; ++i) {
    if (radii[i] <= 0) continue;
    scratch.keys.push_back(sortable_bits(depths[i]));
    scratch.order.push_back(int32_t(i));
  }
  radix_sort(scratch);

  bins.order.assign(scratch.order.begin(), scratch.order.end());

  const int n_tiles = bins.num_tiles();
  const int32_t visible = int32_t(bins.order.size());
  std::vector<int64_t> counts(n_tiles + 1, 0);
  // Rects are computed and counted in Gaussian order, reading the inputs
  // sequentially, and gathered by rank only for the fill (in rank order the
  // reads of four input arrays missed the cache). Packed to 8 bytes so the
  // gather's working set stays small.
  struct PackedRect {
    uint16_t x0, y0, x1, y1;
  };
  core::require(bins.tiles_x < 65536 && bins.tiles_y < 65536,
                "rasterize: image wider or taller than 65535 tiles");
  thread_local std::vector<PackedRect> rects;
  rects.resize(count);
  bins.extents.resize(count);
  auto rect_of = [&](int32_t g) {
    const double u = means2d[2 * g], v = means2d[2 * g + 1];
    TileRect t = tile_rect(u, v, radii[g], bins.tiles_x, bins.tiles_y);
    const SplatExtent e = bins.extents[g] =
        splat_extent(conics[3 * g], conics[3 * g + 1], conics[3 * g + 2], opacities[g]);
    if (e.empty) return PackedRect{0, 0, 0, 0};
    // Pixel x (centre x + 0.5) is within ext_x of u for x in [u - ext_x - 0.5, u + ext_x - 0.5].
    t.x0 = std::max(t.x0, clamped_floor((u - e.ext_x - 0.5) / kTileSize, bins.tiles_x));
    t.x1 = std::min(t.x1, clamped_floor((u + e.ext_x - 0.5) / kTileSize, bins.tiles_x - 1) + 1);
    t.y0 = std::max(t.y0, clamped_floor((v - e.ext_y - 0.5) / kTileSize, bins.tiles_y));
    t.y1 = std::min(t.y1, clamped_floor((v + e.ext_y - 0.5) / kTileSize, bins.tiles_y - 1) + 1);
    if (t.empty()) return PackedRect{0, 0, 0, 0};
    return PackedRect{uint16_t(t.x0), uint16_t(t.y0), uint16_t(t.x1), uint16_t(t.y1)};
  };
  for (int64_t i = 0; i < count; ++i) {
    if (radii[i] <= 0) continue;
    const PackedRect t = rects[i] = rect_of(int32_t(i));
    for (int ty = t.y0; ty < t.y1; ++ty)
      for (int tx = t.x0; tx < t.x1; ++tx) ++counts[ty * bins.tiles_x + tx + 1];
  }
  std::partial_sum(counts.begin(), counts.end(), counts.begin());
  core::require(counts[n_tiles] < (int64_t(1) << 31),
                "rasterize: more than 2^31 Gaussian-tile pairs; reduce the number or size of "
                "the Gaussians");
  bins.offsets.assign(counts.begin(), counts.end());
  bins.ranks.resize(bins.offsets[n_tiles]);
  std::vector<int32_t> cursor(bins.offsets.begin(), bins.offsets.end() - 1);
  for (int32_t r = 0; r < visible; ++r) {
    const PackedRect t = rects[bins.order[r]];
    for (int ty = t.y0; ty < t.y1; ++ty)
      for (int tx = t.x0; tx < t.x1; ++tx) bins.ranks[cursor[ty * bins.tiles_x + tx]++] = r;
  }
  assign_tiles(std::max(1, threads), bins);
}

}  // namespace ddhgs::render
