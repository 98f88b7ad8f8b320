// Orthomosaics: each tile's far pinhole camera puts points anywhere within
// the model's relief where an orthographic projection does, to within
// kOrthoParallaxPx (measured over random points of every tile), in a scene
// frame turned, scaled and moved against the CRS; rendered Gaussians at
// different heights land at their CRS pixel; the footprint and the flight's
// own GSD follow from the cameras.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "eval/orthomosaic.h"

namespace ddhgs::eval {
namespace {

io::Georeference turned_georef() {
  io::Georeference g;
  g.epsg = 32630;
  g.scene_to_crs.scale = 2.5;  // metres per scene unit
  g.scene_to_crs.rotation = core::quat_to_rotation(0.9, 0.2, -0.3, 0.25);
  g.scene_to_crs.translation = {681100.0, 5743050.0, 120.0};
  return g;
}

// The scene point at CRS position (east, north, height).
core::Vec3 scene_point(const io::Georeference& g, const core::Vec3& crs) {
  const core::Similarity& s = g.scene_to_crs;
  return (s.rotation.transposed() * (crs - s.translation)) * (1 / s.scale);
}

TEST(Orthomosaic, TileCamerasAreOrthographicWithinTheBound) {
  const io::Georeference g = turned_georef();
  OrthoGrid grid;
  grid.left_m = 681090;
  grid.top_m = 5743060;
  grid.gsd_m = 0.02;
  grid.width = 1100;  // three tiles across, the last one narrow
  grid.height = 700;
  Ground ground{121.0, 1.5};
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0, 1);
  double worst = 0;
  for (int64_t row = 0; row < 2; ++row)
    for (int64_t col = 0; col < 3; ++col) {
      const core::Camera cam = ortho_tile_camera(grid, g, ground, col, row);
      EXPECT_NEAR(cam.world_to_camera.rotation().determinant(), 1, 1e-12);
      const core::Intrinsics& k = cam.intrinsics;
      for (int i = 0; i < 400; ++i) {
        const double x = k.width * unit(rng), y = k.height * unit(rng);  // pixel position in tile
        const double h = ground.height_m + ground.relief_m * (2 * unit(rng) - 1);
        const core::Vec3 crs{grid.left_m + (col * kOrthoTile + x) * grid.gsd_m,
                             grid.top_m - (row * kOrthoTile + y) * grid.gsd_m, h};
        const core::Vec3 c = cam.world_to_camera.transform_point(scene_point(g, crs));
        ASSERT_GT(c.z, 0);
        const double u = k.fx * c.x / c.z + k.cx, v = k.fy * c.y / c.z + k.cy;
        worst = std::max(worst, std::hypot(u - x, v - y));
      }
    }
  EXPECT_LT(worst, kOrthoParallaxPx + 1e-6);
  EXPECT_GT(worst, 0.2 * kOrthoParallaxPx);  // the bound is tight, not vacuous
}

// One small round Gaussian per (east, north, height), per-band colour.
model::Gaussians blobs(const io::Georeference& g, const std::vector<core::Vec3>& crs,
                       double sigma_m) {
  const int64_t n = int64_t(crs.size());
  model::Gaussians m;
  m.means = torch::empty({n, 3});
  for (int64_t i = 0; i < n; ++i) {
    const core::Vec3 p = scene_point(g, crs[size_t(i)]);
    m.means[i][0] = p.x;
    m.means[i][1] = p.y;
    m.means[i][2] = p.z;
  }
  m.log_scales = torch::full({n, 3}, std::log(sigma_m / g.scene_to_crs.scale));
  m.quats = torch::zeros({n, 4});
  m.quats.select(1, 0).fill_(1);
  m.logit_opacities = torch::full({n, 1}, 4.0);
  m.sh_dc = torch::full({n, 2}, float((0.8 - 0.5) / model::kShC0));
  m.sh_rest = torch::zeros({n, 2, 0});
  return m;
}

TEST(Orthomosaic, GaussiansLandAtTheirCrsPixelWhateverTheirHeight) {
  const io::Georeference g = turned_georef();
  OrthoGrid grid;
  grid.left_m = 681090;
  grid.top_m = 5743060;
  grid.gsd_m = 0.05;
  grid.width = 600;
  grid.height = 300;
  // Heights from the ground to 2 m above it, in two tiles.
  const std::vector<core::Vec3> at = {{681095.013, 5743055.021, 120.0},
                                      {681105.526, 5743050.474, 121.2},
                                      {681113.77, 5743047.33, 122.0},
                                      {681096.1, 5743049.9, 120.7}};
  const model::Gaussians m = blobs(g, at, 0.12);
  const Ground ground = model_ground(m, g);
  EXPECT_NEAR(ground.height_m, 120.95, 0.3);
  const Orthomosaic mosaic = render_orthomosaic(m, g, grid, ground, torch::zeros({2}));
  ASSERT_EQ(mosaic.image.size(0), 300);
  ASSERT_EQ(mosaic.image.size(1), 600);
  const torch::Tensor alpha = mosaic.alpha.to(torch::kFloat64);
  for (const core::Vec3& p : at) {
    const double col = (p.x - grid.left_m) / grid.gsd_m, row = (grid.top_m - p.y) / grid.gsd_m;
    // The alpha-weighted centre of the blob's window (pixel centres at +0.5).
    const int64_t c0 = int64_t(col) - 12, r0 = int64_t(row) - 12;
    const torch::Tensor w = alpha.slice(0, r0, r0 + 25).slice(1, c0, c0 + 25);
    const torch::Tensor xs = torch::arange(25, torch::kFloat64) + double(c0) + 0.5;
    const torch::Tensor ys = torch::arange(25, torch::kFloat64) + double(r0) + 0.5;
    const double total = w.sum().item<double>();
    ASSERT_GT(total, 1);
    EXPECT_NEAR((w.sum(0) * xs).sum().item<double>() / total, col, 0.1);
    EXPECT_NEAR((w.sum(1) * ys).sum().item<double>() / total, row, 0.1);
    // The blob's own colour where it covers, no background.
    const int64_t ci = int64_t(col), ri = int64_t(row);
    EXPECT_NEAR(mosaic.image[ri][ci][0].item<double>() / mosaic.alpha[ri][ci].item<double>(), 0.8,
                1e-3);
  }
  // Far from every blob: nothing covers.
  EXPECT_EQ(mosaic.alpha[290][590].item<float>(), 0);

  // Over a background, as every view is rendered: the blob's colour plus
  // the background through what it leaves uncovered, the background alone
  // far from it.
  const Orthomosaic over = render_orthomosaic(m, g, grid, ground, torch::tensor({0.3f, 0.1f}));
  for (const core::Vec3& p : at) {
    const int64_t ci = int64_t((p.x - grid.left_m) / grid.gsd_m) + 3;
    const int64_t ri = int64_t((grid.top_m - p.y) / grid.gsd_m);
    const double a = mosaic.alpha[ri][ci].item<double>();
    ASSERT_GT(a, 0.05);
    ASSERT_LT(a, 0.95);
    EXPECT_NEAR(over.image[ri][ci][0].item<double>(), 0.8 * a + 0.3 * (1 - a), 1e-3);
    EXPECT_NEAR(over.image[ri][ci][1].item<double>(), 0.8 * a + 0.1 * (1 - a), 1e-3);
  }
  EXPECT_NEAR(over.image[290][590][0].item<float>(), 0.3, 1e-6);
  EXPECT_NEAR(over.image[290][590][1].item<float>(), 0.1, 1e-6);
  EXPECT_THROW(render_orthomosaic(m, g, grid, ground, torch::zeros({3})), core::Error);
}

}  // namespace
}  // namespace ddhgs::eval
