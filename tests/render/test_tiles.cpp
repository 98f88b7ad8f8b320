// Tile binning: which tiles list a Gaussian, and how tiles are shared among
// threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "render/tiles.h"

namespace ddhgs::test {
namespace {

using render::TileBins;

// One isotropic Gaussian (sigma 6 px) at the centre of a 64 x 64 image (4 x 4
// tiles) with a 3DGS radius of 20 px, whose square touches all 16 tiles.
TileBins bin_one(float opacity) {
  const float means2d[2] = {32.0f, 32.0f};
  const float conics[3] = {1.0f / 36, 0.0f, 1.0f / 36};
  const float depths[1] = {2.0f};
  const int32_t radii[1] = {20};
  TileBins bins;
  render::bin_gaussians(means2d, conics, &opacity, depths, radii, 1, 64, 64, 1, bins);
  return bins;
}

std::vector<int> tiles_listing_rank0(const TileBins& bins) {
  std::vector<int> tiles;
  for (int t = 0; t < bins.num_tiles(); ++t)
    for (int32_t b = bins.offsets[t]; b < bins.offsets[t + 1]; ++b)
      if (bins.ranks[b] == 0) tiles.push_back(t);
  return tiles;
}

TEST(TileBins, GaussianListedOnlyWhereItsAlphaCanReachOneIn255) {
  // o = 0.01: alpha >= 1/255 needs power <= ln(2.55) = 0.936, i.e. within
  // sqrt(2 * 0.936) * 6 = 8.2 px (+1 px margin) of the centre: pixel centres
  // 22.3-40.7, tiles 1 and 2 on each axis, 4 of the 16 in the radius square.
  EXPECT_EQ(tiles_listing_rank0(bin_one(0.01f)), (std::vector<int>{5, 6, 9, 10}));
  // o = 0.99: ln(252.45) = 5.53, 3.3 sigma = 20 px (+1): all 16 tiles.
  EXPECT_EQ(tiles_listing_rank0(bin_one(0.99f)).size(), 16u);
  // Below 1/255 the Gaussian can never blend: no tile lists it.
  EXPECT_TRUE(tiles_listing_rank0(bin_one(0.003f)).empty());
}

TEST(TileBins, ThreadsShareEveryTileOnceInContiguousRuns) {
  // 40 x 10 tiles with uneven costs: Gaussians stacked near one corner.
  std::vector<float> means2d, conics, opacities, depths;
  std::vector<int32_t> radii;
  for (int i = 0; i < 200; ++i) {
    means2d.insert(means2d.end(), {float(30 + (i * 37) % 300), float(10 + (i * 11) % 120)});
    conics.insert(conics.end(), {0.1f, 0.0f, 0.1f});
    opacities.push_back(0.5f);
    depths.push_back(float(i % 17));
    radii.push_back(10);
  }
  for (int threads : {1, 2, 3}) {
    TileBins bins;
    render::bin_gaussians(means2d.data(), conics.data(), opacities.data(), depths.data(),
                          radii.data(), 200, 640, 160, threads, bins);
    ASSERT_EQ(int(bins.thread_tiles.size()), threads);
    std::vector<int> seen(bins.num_tiles(), 0);
    int64_t total = 0, most = 0;
    int jumps = 0;
    for (const auto& list : bins.thread_tiles) {
      int64_t cost = 0;
      for (size_t i = 0; i < list.size(); ++i) {
        ++seen[list[i]];
        cost += bins.offsets[list[i] + 1] - bins.offsets[list[i]] + 1;
        if (i == 0) continue;
        // Consecutive tiles are neighbours (one step along x or y), except
        // where the walk moves on to the next band of tile rows.
        const int a = list[i - 1], b = list[i];
        const int dx = std::abs(a % bins.tiles_x - b % bins.tiles_x);
        const int dy = std::abs(a / bins.tiles_x - b / bins.tiles_x);
        if (dx + dy != 1) {
          EXPECT_EQ(dx, 0) << "tiles " << a << " and " << b;
          ++jumps;
        }
      }
      total += cost;
      most = std::max(most, cost);
    }
    EXPECT_LT(jumps, bins.tiles_y / 2);
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](int n) { return n == 1; }));
    // Balanced to within a few tiles' cost.
    EXPECT_LE(most, total / threads + 64) << threads << " threads";
  }
}

}  // namespace
}  // namespace ddhgs::test
