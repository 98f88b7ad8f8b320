#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <random>

#include "core/error.h"
#include "io/blocks/block_grid.h"
#include "io/blocks/ground.h"
#include "io/blocks/partition.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;
using core::Vec3;

TEST(GroundFrame, PrincipalAxesOfAStretchedTiltedCloud) {
  // Points spread 3 : 1 : 0.1 along three known orthonormal axes.
  const Vec3 a = Vec3{1, 1, 0}.normalized(), b = Vec3{-1, 1, 1}.normalized();
  const Vec3 c = a.cross(b);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Vec3> points;
  for (int i = 0; i < 4000; ++i)
    points.push_back(Vec3{5, -2, 1} + a * (3 * normal(rng)) + b * normal(rng) +
                     c * (0.1 * normal(rng)));
  const PrincipalAxes axes = principal_axes(points);
  EXPECT_NEAR(std::abs(axes.vectors[2].dot(a)), 1, 1e-3);
  EXPECT_NEAR(std::abs(axes.vectors[1].dot(b)), 1, 1e-3);
  EXPECT_NEAR(std::abs(axes.vectors[0].dot(c)), 1, 1e-3);
  EXPECT_NEAR(axes.values[2], 9, 0.5);
  EXPECT_NEAR(axes.values[1], 1, 0.06);
  EXPECT_NEAR(axes.values[0], 0.01, 0.001);
  EXPECT_NEAR((axes.mean - Vec3{5, -2, 1}).norm(), 0, 0.15);
}

core::Camera nadir_camera(double x, double y, double height) {
  core::Camera camera;
  camera.intrinsics = {100, 100, 50, 40, 100, 80};
  camera.world_to_camera = core::look_at({x, y, height}, {x, y, 0}, {0, 1, 0});
  return camera;
}

TEST(GroundFrame, ANadirStripOverFlatPointsGivesTheGroundAndTheFlight) {
  std::vector<core::Camera> cameras;
  for (int i = 0; i < 6; ++i) cameras.push_back(nadir_camera(2.0 * i, 1, 10));
  std::vector<Vec3> points;
  for (int i = 0; i < 50; ++i)
    for (int j = 0; j < 10; ++j) points.push_back({0.25 * i - 2, 0.5 * j - 1.5, 0.5});
  const GroundFrame f = ground_frame(points, cameras);
  EXPECT_NEAR(f.n.z, 1, 1e-9);  // up, towards the cameras
  EXPECT_NEAR(std::abs(f.u.x), 1, 1e-9);
  EXPECT_NEAR(f.origin.z, 0.5, 1e-9);  // on the points' plane
  // The first camera sees 10 m x 8 m of ground from 9.5 m above it: 9.5 by 7.6.
  const GroundBox box = view_footprint(f, cameras[0], true);
  EXPECT_NEAR(box.u1 - box.u0, 9.5, 1e-9);
  EXPECT_NEAR(box.v1 - box.v0, 7.6, 1e-9);
  EXPECT_NEAR(0.5 * (box.u0 + box.u1), f.along(cameras[0].center()), 1e-9);
}

TEST(BlockGrid, CellsMarginsAndTheBlockOfAPoint) {
  BlockGrid g;
  g.footprint = {0, 8, -2, 2};
  g.rows = 2;
  g.cols = 4;
  g.overlap = 0.25;
  const GroundBox c = g.cell(5);  // row 1, column 1
  EXPECT_DOUBLE_EQ(c.u0, 2);
  EXPECT_DOUBLE_EQ(c.u1, 4);
  EXPECT_DOUBLE_EQ(c.v0, 0);
  EXPECT_DOUBLE_EQ(c.v1, 2);
  const GroundBox m = g.margined(5);
  EXPECT_DOUBLE_EQ(m.u0, 1.5);
  EXPECT_DOUBLE_EQ(m.u1, 4.5);
  EXPECT_DOUBLE_EQ(m.v0, -0.5);
  EXPECT_DOUBLE_EQ(m.v1, 2.5);
  EXPECT_EQ(g.block_of(3, 1), 5);
  EXPECT_EQ(g.block_of(-100, -100), 0);  // beyond the footprint: the nearest edge cell
  EXPECT_EQ(g.block_of(100, 100), 7);
  EXPECT_EQ(g.block_of(7.9, -1), 3);
  EXPECT_DOUBLE_EQ(m.shared(g.cell(6)), 0.5 * 2);  // 0.5 m of column 2, 2 m of row 1
  EXPECT_EQ(grid_shape(4, 10, 10), std::make_pair(2, 2));
  EXPECT_EQ(grid_shape(4, 40, 2), std::make_pair(1, 4));
  EXPECT_EQ(grid_shape(6, 30, 20), std::make_pair(2, 3));
  EXPECT_EQ(block_name(3, 4), "block_03");
  EXPECT_EQ(block_name(7, 150), "block_007");
}

// The cross-fade's weights against hand values: 1 deep in a cell, 1/2 on a
// border between two cells, 1/4 at a corner of four, linear across the
// margin on either side, nothing beyond it; no ramp at the footprint's outer
// edges; over all blocks they sum to 1 everywhere.
TEST(BlockGrid, BlendWeightsCrossFadeNeighboursAcrossTheirBorders) {
  BlockGrid g;
  g.footprint = {0, 8, -2, 2};
  g.rows = 2;
  g.cols = 4;
  g.overlap = 0.25;  // margins of 0.5 m along u and v
  // Block 5: row 1, column 1, cell [2, 4] x [0, 2]; block 4 is on its left.
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 3, 1, 1), 1);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2, 1, 1), 0.5);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2.25, 1, 1), 0.75);
  EXPECT_DOUBLE_EQ(g.blend_weight(4, 2.25, 1, 1), 0.25);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2.5, 1, 1), 1);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 1.5, 1, 1), 0);  // the far edge of its margin
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 1.4, 1, 1), 0);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2, 0, 1), 0.25);  // the corner of blocks 0, 1, 4, 5
  EXPECT_DOUBLE_EQ(g.blend_weight(0, 2, 0, 1), 0.25);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 3, 1.9, 1), 1);  // near the footprint's top edge
  EXPECT_DOUBLE_EQ(g.blend_weight(4, -5, 1, 1), 1);   // beyond the footprint's left edge
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 3, 5, 1), 1);    // beyond its top edge
  // Half the margin: the ramp is half as wide.
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2.125, 1, 0.5), 0.75);
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 1.75, 1, 0.5), 0);
  // blend 0, or no overlap: the cell alone.
  EXPECT_DOUBLE_EQ(g.blend_weight(5, 2.01, 1, 0), 1);
  EXPECT_DOUBLE_EQ(g.blend_weight(4, 2.01, 1, 0), 0);
  BlockGrid cut = g;
  cut.overlap = 0;
  EXPECT_DOUBLE_EQ(cut.blend_weight(5, 2.01, 1, 1), 1);
  EXPECT_DOUBLE_EQ(cut.blend_weight(4, 2.01, 1, 1), 0);
  // A partition of unity, also where margins as wide as a cell would make
  // the ramps of a cell's two borders meet (their half-width stops at half
  // the cell).
  BlockGrid wide = g;
  wide.overlap = 1;
  for (const BlockGrid* grid : {&g, &wide})
    for (double u = -1; u <= 9; u += 0.0625)
      for (double v = -3; v <= 3; v += 0.0625) {
        double sum = 0;
        for (int b = 0; b < grid->blocks(); ++b) {
          const double w = grid->blend_weight(b, u, v, 1);
          EXPECT_GE(w, 0);
          EXPECT_LE(w, 1);
          sum += w;
        }
        ASSERT_NEAR(sum, 1, 1e-12) << "at u " << u << ", v " << v;
      }
  // There the ramp's half-width is half the cell (1 m), not the 2 m margin.
  EXPECT_DOUBLE_EQ(wide.blend_weight(5, 2.5, 1, 1), 0.75);
}

TEST(BlocksFile, RoundTripsAndRefusesMalformedFiles) {
  const fs::path dir = test::temp_dir("blocks_file");
  BlocksFile file;
  file.scene = "/data/flight";
  file.grid.frame.origin = {1, 2, 3};
  file.grid.footprint = {0, 4, 0, 2};
  file.grid.rows = 1;
  file.grid.cols = 2;
  file.blocks = {{"block_00", 0, 0, {"a.npy", "b.npy"}, {"c.npy"}, 10},
                 {"block_01", 0, 1, {"b.npy"}, {}, 4}};
  write_blocks_file(dir / "blocks.json", file);
  const BlocksFile back = read_blocks_file(dir / "blocks.json");
  EXPECT_EQ(back.scene, file.scene);
  EXPECT_EQ(back.grid.cols, 2);
  EXPECT_DOUBLE_EQ(back.grid.frame.origin.z, 3);
  EXPECT_DOUBLE_EQ(back.grid.footprint.u1, 4);
  ASSERT_EQ(back.blocks.size(), 2u);
  EXPECT_EQ(back.blocks[0].train_views, file.blocks[0].train_views);
  EXPECT_EQ(back.blocks[0].test_views, file.blocks[0].test_views);
  EXPECT_EQ(back.blocks[1].points, 4);

  const std::string text = read_file(dir / "blocks.json");
  auto refused = [&](const std::string& from, const std::string& to, const std::string& says) {
    std::string bad = text;
    const size_t at = bad.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    bad.replace(at, from.size(), to);
    write_file_atomically(dir / "bad.json", bad);
    try {
      read_blocks_file(dir / "bad.json");
      ADD_FAILURE() << "accepted " << to;
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused("\"cols\": 2", "\"cols\": 3", "blocks");
  refused("\"block_01\"", "\"../elsewhere\"", "name");
  refused("\"ddhgs blocks\"", "\"other\"", "format");
  refused("\"overlap\": 0.2", "\"overlap\": -1", "overlap");
  refused("\"points\": 4", "\"points\": -4", "points");
}

TEST(BlockContext, RoundTripsAndRefusesMalformedFiles) {
  const fs::path dir = test::temp_dir("block_context");
  EXPECT_FALSE(read_block_context(dir).has_value());  // an ordinary scene
  BlockContext c;
  c.name = "block_01";
  c.frame.origin = {1, 2, 3};
  c.cell = {0, 2, 0, 1};
  c.margined = {-0.4, 2.4, -0.2, 1.2};
  c.flight_train_views = 44;
  c.flight_extent = 6.487953521;
  write_block_context(dir / kBlockContextFile, c);
  // A block.json written before the flight's backdrop: none, as it was.
  EXPECT_TRUE(read_block_context(dir)->background.empty());
  c.background = {0.125, 0.2567, 0.5};
  write_block_context(dir / kBlockContextFile, c);
  const std::optional<BlockContext> back = read_block_context(dir);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->name, "block_01");
  EXPECT_DOUBLE_EQ(back->frame.origin.y, 2);
  EXPECT_DOUBLE_EQ(back->cell.u1, 2);
  EXPECT_DOUBLE_EQ(back->margined.v0, -0.2);
  EXPECT_EQ(back->flight_train_views, 44);
  EXPECT_EQ(back->flight_extent, c.flight_extent);  // every digit
  EXPECT_EQ(back->background, c.background);

  const std::string text = read_file(dir / kBlockContextFile);
  const fs::path bad_dir = dir / "bad";
  fs::create_directories(bad_dir);
  auto refused = [&](const std::string& from, const std::string& to, const std::string& says) {
    std::string bad = text;
    const size_t at = bad.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    bad.replace(at, from.size(), to);
    write_file_atomically(bad_dir / kBlockContextFile, bad);
    try {
      read_block_context(bad_dir);
      ADD_FAILURE() << "accepted " << to;
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find(kBlockContextFile), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused("\"flight_train_views\": 44", "\"flight_train_views\": 0", "flight_train_views");
  refused("\"flight_extent\": 6.487953521", "\"flight_extent\": -1", "flight_extent");
  refused("\"ddhgs block\"", "\"ddhgs blocks\"", "format");
  refused("0.2567", "\"x\"", "background");
  refused("\"background\": [", "\"background\": [], \"was\": [", "background");
}

// A scene of `views` nadir views of bands x 16 x 20 float32 pixels, each
// band at `ground` on 60 % of its pixels and at values spread above and
// below on the rest, so the median of any large sample is `ground`.
fs::path backdrop_scene(const std::string& name, int views, const std::vector<double>& ground) {
  const fs::path root = test::temp_dir(name);
  fs::create_directories(root / "hyperspectral");
  TransformsFile file;
  const int64_t bands = int64_t(ground.size()), h = 16, w = 20;
  for (int64_t b = 0; b < bands; ++b) file.wavelengths_nm.push_back(450 + 50 * double(b));
  for (int i = 0; i < views; ++i) {
    TransformsFrame f;
    f.hyperspectral_file_path = "hyperspectral/v" + std::to_string(i) + ".npy";
    f.intrinsics = {20, 20, 10, 8, int(w), int(h)};
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(nadir_camera(i, 0, 10).world_to_camera);
    // Pixel k of the view: the ground on k % 5 < 3, else ground -/+ 0.1 to 0.3.
    torch::Tensor k = torch::arange(h * w, torch::kFloat32);
    torch::Tensor cube = torch::empty({h * w, bands});
    for (int64_t b = 0; b < bands; ++b) {
      const torch::Tensor r = torch::fmod(k, 5);
      const torch::Tensor off = torch::fmod(k, 7) / 6 * 0.2 + 0.1;
      cube.select(1, b).copy_(torch::where(r < 3, torch::full_like(k, ground[size_t(b)]),
                                           ground[size_t(b)] + (r == 3).to(torch::kFloat32) * off -
                                               (r == 4).to(torch::kFloat32) * off));
    }
    write_npy(root / f.hyperspectral_file_path, cube.view({h, w, bands}).contiguous());
    file.frames.push_back(f);
  }
  write_transforms(root / "transforms.json", file);
  return root;
}

TEST(FlightBackdrop, IsEachBandsMedianOverTheViewsItIsGiven) {
  const std::vector<double> ground = {0.35, 0.45, 0.5, 0.6};
  const fs::path root = backdrop_scene("backdrop", 20, ground);
  const auto scene = load_scene(root);
  std::vector<int> views(20);
  std::iota(views.begin(), views.end(), 0);
  const torch::Tensor all = flight_backdrop(*scene, views);
  ASSERT_EQ(all.numel(), 4);
  for (int64_t b = 0; b < 4; ++b) EXPECT_NEAR(all[b].item<double>(), ground[size_t(b)], 1e-6);
  // A view far brighter than the others: a sample with it is pulled up
  // only if it holds most of the sample.
  torch::Tensor bright = torch::full({16, 20, 4}, 0.9f);
  write_npy(root / "hyperspectral" / "v0.npy", bright);
  const auto changed = load_scene(root);
  EXPECT_NEAR(flight_backdrop(*changed, views)[2].item<double>(), 0.5, 1e-6);
  EXPECT_NEAR(flight_backdrop(*changed, {0})[2].item<double>(), 0.9, 1e-6);
}

TEST(FlightBackdrop, ARigsBandIsTheMedianOfTheViewsHoldingIt) {
  // Band-per-view: view i holds band i % 2 alone; band 0's views show the
  // ground of 0.3, band 1's 0.7 everywhere, so a median that mixed the
  // bands' views would be neither.
  const fs::path root = backdrop_scene("backdrop_rig", 6, {0.3});
  TransformsFile file = read_transforms(root / "transforms.json");
  file.wavelengths_nm = {500, 600};
  for (size_t i = 0; i < file.frames.size(); ++i) {
    file.frames[i].bands = {int(i % 2)};
    if (i % 2 == 1)  // band 1's views: their ground at 0.7
      write_npy(root / file.frames[i].hyperspectral_file_path, torch::full({16, 20, 1}, 0.7f));
  }
  write_transforms(root / "transforms.json", file);
  const auto scene = load_scene(root);
  ASSERT_TRUE(scene->band_per_view());
  const torch::Tensor b = flight_backdrop(*scene, {0, 1, 2, 3, 4, 5});
  EXPECT_NEAR(b[0].item<double>(), 0.3, 1e-6);
  EXPECT_NEAR(b[1].item<double>(), 0.7, 1e-6);
  // Without a view of band 1 there is no backdrop: refused, naming the band.
  try {
    flight_backdrop(*scene, {0, 2});
    ADD_FAILURE() << "a band no view holds was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("band 1 (600 nm)"), std::string::npos) << e.what();
  }
}

TEST(GroundBoxMask, APixelCountsWhereItsRayMeetsTheGroundInsideTheBox) {
  // 10 units above the ground, 100 x 80 pixels, focal length 100: a pixel
  // column x sees the ground at u = (x + 0.5 - 50) / 10 (image x along +u).
  const core::Camera camera = nadir_camera(0, 0, 10);
  GroundFrame frame;  // the plane z = 0, u along x, v along y
  const GroundBox box{1, 2, -100, 100};
  const torch::Tensor whole = ground_box_mask(frame, box, camera, 0, 0, 100, 80);
  ASSERT_EQ(whole.sizes(), (std::vector<int64_t>{80, 100}));
  // Columns 60 to 69 (u 1.05 to 1.95), every row.
  const torch::Tensor columns = whole.any(0);
  for (int x = 0; x < 100; ++x) EXPECT_EQ(columns[x].item<bool>(), x >= 60 && x < 70) << x;
  EXPECT_EQ(whole.sum().item<int64_t>(), 10 * 80);
  // A window of the image: its own pixels, at their place in the view.
  const torch::Tensor window = ground_box_mask(frame, box, camera, 55, 30, 20, 10);
  EXPECT_TRUE(torch::equal(window, whole.slice(0, 30, 40).slice(1, 55, 75)));
  // Rows follow v: a box across v takes the rows whose ground is in it.
  const GroundBox across{-100, 100, 0, 100};
  EXPECT_EQ(ground_box_mask(frame, across, camera, 0, 0, 100, 80).sum().item<int64_t>(), 40 * 100);
  // A camera under the ground sees none of it.
  EXPECT_EQ(
      ground_box_mask(frame, box, nadir_camera(0, 0, -10), 0, 0, 100, 80).sum().item<int64_t>(), 0);
}

TEST(GroundBoxMask, AgreesWithTheCamerasProjectionOfTheGround) {
  // A tilted, turned camera and a box off the image centre: ground points
  // projected into the image as the rasterizer projects them (OpenCV axes)
  // land on pixels the mask marks exactly when the box holds them, so a
  // flipped or swapped image axis cannot pass.
  core::Camera camera;
  camera.intrinsics = {120, 110, 64, 48, 128, 96};
  camera.world_to_camera = core::look_at({0.5, -1, 8}, {2, 1.5, 0}, {1, 0.3, 0});
  GroundFrame frame;
  frame.origin = {0, 0, 0.25};
  const GroundBox box{1.0, 3.5, 0.5, 2.0};
  const torch::Tensor mask = ground_box_mask(frame, box, camera, 0, 0, 128, 96);
  const core::Intrinsics& k = camera.intrinsics;
  int inside = 0, outside = 0;
  for (double u = -4; u <= 8; u += 0.05)
    for (double v = -4; v <= 7; v += 0.05) {
      // Away from the box's edges by more than a pixel's ground (< 0.1 here).
      const double edge = std::min(
          {std::abs(u - box.u0), std::abs(u - box.u1), std::abs(v - box.v0), std::abs(v - box.v1)});
      if (edge < 0.15) continue;
      const Vec3 c = camera.world_to_camera.transform_point({u, v, 0.25});
      const double x = k.fx * c.x / c.z + k.cx, y = k.fy * c.y / c.z + k.cy;
      if (c.z <= 0 || x < 0 || y < 0 || x >= k.width || y >= k.height) continue;
      const bool marked = mask[int(y)][int(x)].item<bool>();
      EXPECT_EQ(marked, box.contains(u, v)) << u << ", " << v;
      (marked ? inside : outside)++;
    }
  EXPECT_GT(inside, 100);  // the box is in view, and so is ground beyond it
  EXPECT_GT(outside, 100);
}

}  // namespace
}  // namespace ddhgs::io
