// Initial state on small RGB scenes written here: random points for wide and
// narrow fields of view, the border colour that starts the background (and
// tells a masked backdrop from a natural scene's border), and the fallback to
// random points.
#include <ATen/CPUGeneratorImpl.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "core/colour.h"
#include "io/image/image.h"
#include "io/scene/backdrop.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"
#include "train/init.h"

namespace ddhgs::train {
namespace {
namespace fs = std::filesystem;

constexpr double kRadius = 3;  // cameras on a ring around the origin
constexpr int kWidth = 16, kHeight = 12, kViews = 10;

core::Mat4 w2c_of(int i) {
  const double a = 2 * M_PI * i / kViews;
  return core::look_at({kRadius * std::cos(a), kRadius * std::sin(a), 0.5}, {0, 0, 0}, {0, 0, 1});
}

// Every view: a white backdrop with a dark object in the middle; in view 1 the
// object reaches the top edge, and view 2's border is tinted, so the median
// has minorities to ignore.
torch::Tensor picture(int view) {
  auto image = torch::full({kHeight, kWidth, 3}, 255, torch::kUInt8);
  image.slice(0, 3, 9).slice(1, 5, 11).fill_(20);
  if (view == 1) image.slice(0, 0, 9).slice(1, 5, 11).fill_(20);
  if (view == 2) image.select(2, 0).fill_(200);
  return image;
}

fs::path write_scene(const std::string& name, double fx,
                     const std::function<torch::Tensor(int)>& pictures = picture) {
  const fs::path root = test::temp_dir(name);
  fs::create_directories(root / "images");
  io::TransformsFile file;
  for (int i = 0; i < kViews; ++i) {
    io::TransformsFrame f;
    f.file_path = "images/r_" + std::to_string(i) + ".png";
    f.intrinsics.fx = f.intrinsics.fy = fx;
    f.intrinsics.cx = kWidth / 2.0;
    f.intrinsics.cy = kHeight / 2.0;
    f.intrinsics.width = kWidth;
    f.intrinsics.height = kHeight;
    f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(w2c_of(i));
    io::write_png(root / f.file_path, pictures(i));
    file.frames.push_back(f);
  }
  io::write_transforms(root / "transforms.json", file);
  return root;
}

// Half the image diagonal over the focal length: tan of the corner angle.
double corner_tan(double fx) {
  return std::hypot(kWidth / 2.0, kHeight / 2.0) / fx;
}

TEST(Init, RandomPointsFillTheFrustumSlabForAWideField) {
  // About 60 degrees across: depths from 0.5 to 1.5 times the distance.
  auto scene = io::load_scene(write_scene("init_wide", 14.0));
  auto generator = at::make_generator<at::CPUGeneratorImpl>(3);
  const torch::Tensor points = sample_view_volume(*scene, scene->train, 2000, generator);
  const double distance = std::hypot(kRadius, 0.5);
  const double farthest = points.norm(2, 1).max().item<double>();
  EXPECT_GT(farthest, 0.9 * distance);
  EXPECT_LT(farthest, distance * std::hypot(0.5, 1.5 * corner_tan(14.0)));
}

TEST(Init, RandomPointsStayAroundTheObjectForANarrowField) {
  const double fx = 150;
  auto scene = io::load_scene(write_scene("init_random", fx));
  auto generator = at::make_generator<at::CPUGeneratorImpl>(7);
  const torch::Tensor points = sample_view_volume(*scene, scene->train, 2000, generator);
  ASSERT_EQ(points.sizes(), (std::vector<int64_t>{2000, 3}));
  // Within the field's radius of the origin (depth and lateral), with some
  // slack for the corners of the frustum slab.
  const double field = std::hypot(kRadius, 0.5) * corner_tan(fx);
  const double farthest = points.norm(2, 1).max().item<double>();
  EXPECT_LT(farthest, 1.6 * field);
  EXPECT_GT(farthest, 0.5 * field);

  InitOptions options;
  options.random_points = 300;
  options.sh_degree = 1;
  // No points in the dataset and random not asked for: random points anyway.
  const model::Gaussians g = initialise_gaussians(*scene, options);
  EXPECT_EQ(g.size(), 300);
}

TEST(Init, ExtraRandomPointsJoinTheDatasetsPoints) {
  const double fx = 150;
  auto scene = io::load_scene(write_scene("init_extra", fx));
  // Three sparse points of known colour, as structure from motion would give.
  scene->points.xyz = torch::tensor({0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.1, 0.0}).view({3, 3});
  scene->points.rgb = torch::tensor({255, 0, 0, 0, 255, 0, 0, 0, 255}, torch::kUInt8).view({3, 3});
  InitOptions options;
  options.sh_degree = 1;
  options.extra_random_per_pixel = 1.5;  // of a 16 x 12 view: 288 points
  const model::Gaussians g = initialise_gaussians(*scene, options);
  ASSERT_EQ(g.size(), 3 + 288);
  // The dataset's points come first, unchanged, with their colours.
  EXPECT_TRUE(torch::equal(g.means.detach().slice(0, 0, 3), scene->points.xyz.to(torch::kFloat32)));
  const torch::Tensor rgb =
      g.sh_dc.detach().slice(0, 0, 3).squeeze(-1) * float(model::kShC0) + 0.5f;
  EXPECT_TRUE(torch::allclose(rgb, torch::eye(3), 0, 1e-5)) << rgb;
  // The extra ones lie in the views' volume around the object and start grey.
  const double field = std::hypot(kRadius, 0.5) * corner_tan(fx);
  EXPECT_LT(g.means.detach().slice(0, 3).norm(2, 1).max().item<double>(), 1.6 * field);
  const torch::Tensor grey = g.sh_dc.detach().slice(0, 3) * float(model::kShC0) + 0.5f;
  EXPECT_TRUE(torch::allclose(grey, torch::full_like(grey, 0.5f), 0, 1e-6));
}

// The ring's views look at the origin from all around, 0.5 above it at a
// radius of 3: their mean direction is straight down, and each is 90 -
// atan(0.5 / 3) degrees from it. Views that all look down within a few
// degrees are a one-sided capture, which gets no extra random points.
TEST(Init, OneSidedCapturesGetNoExtraRandomPoints) {
  auto ring = io::load_scene(write_scene("init_ring_spread", 150));
  std::vector<int> every(ring->views.size());
  for (size_t i = 0; i < every.size(); ++i) every[i] = int(i);
  EXPECT_NEAR(view_direction_spread_deg(*ring, every), 90 - std::atan(0.5 / 3) * 180 / M_PI, 1e-6);
  auto strip = io::load_scene(write_scene("init_strip", 150));
  // Nadir cameras along x; the last one tilted 10 degrees about y.
  for (size_t i = 0; i < strip->views.size(); ++i)
    strip->views[i].camera.world_to_camera =
        core::look_at({0.3 * double(i), 0, 3}, {0.3 * double(i), 0, 0}, {0, 1, 0});
  const double t = 10 * M_PI / 180;
  strip->views.back().camera.world_to_camera =
      core::look_at({0.3 * 9, 0, 3}, {0.3 * 9 + 3 * std::tan(t), 0, 0}, {0, 1, 0});
  std::vector<int> all(strip->views.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = int(i);
  // The mean leans 1 degree towards the tilted view: it is 9 degrees away.
  EXPECT_NEAR(view_direction_spread_deg(*strip, all), 9.0, 0.05);
  strip->points.xyz = torch::tensor({0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.1, 0.0}).view({3, 3});
  strip->points.rgb = torch::full({3, 3}, 128, torch::kUInt8);
  strip->train = all;
  InitOptions options;
  options.sh_degree = 1;
  options.extra_random_per_pixel = 1.5;
  EXPECT_EQ(initialise_gaussians(*strip, options).size(), 3);
  ring->points = strip->points;
  EXPECT_EQ(initialise_gaussians(*ring, options).size(), 3 + 288);
}

TEST(Init, BorderColourIsTheMedianOfTheBorderPixels) {
  auto scene = io::load_scene(write_scene("init_border", 14.0));
  const torch::Tensor colour = io::border_colour(*scene, scene->train);
  ASSERT_EQ(colour.sizes(), (std::vector<int64_t>{3}));
  // The object on view 1's top edge and view 2's tint are minorities.
  EXPECT_TRUE(torch::allclose(colour, torch::ones({3}), 0, 1e-6)) << colour;
  // Only view 2 (tinted red channel): its own border colour.
  const torch::Tensor tinted = io::border_colour(*scene, {2});
  EXPECT_NEAR(tinted[0].item<double>(), 200.0 / 255, 1e-6);
  EXPECT_NEAR(tinted[1].item<double>(), 1.0, 1e-6);
}

TEST(Init, MaskedBackdropNeedsMostOfTheBorderOnIt) {
  auto scene = io::load_scene(write_scene("init_backdrop", 14.0));
  // 96 border pixels (2 wide) per 16 x 12 view, 10 views: the object covers
  // 12 of view 1's, and view 2's 96 are tinted; 852 of 960 (0.8875) are white.
  std::vector<int> all(kViews);
  for (int i = 0; i < kViews; ++i) all[size_t(i)] = i;
  const auto found = io::masked_backdrop(*scene, all, io::kBackdropTolerance, 0.88);
  ASSERT_TRUE(found.has_value());
  EXPECT_TRUE(torch::allclose(*found, torch::ones({3}), 0, 1e-6)) << *found;
  EXPECT_FALSE(io::masked_backdrop(*scene, all, io::kBackdropTolerance, 0.89).has_value());
  // The tint (55 levels, 0.216) counts once the tolerance admits it: 948 of 960.
  EXPECT_TRUE(io::masked_backdrop(*scene, all, 0.22, 0.98).has_value());
}

// A masked capture's verdict: the white-backdrop scene passes every test.
TEST(Init, AMaskedCapturePassesEveryTestOfTheBorder) {
  auto scene = io::load_scene(write_scene("init_masked", 14.0));
  const io::BorderScan scan = io::scan_border(*scene, scene->train);
  EXPECT_TRUE(scan.masked) << scan.why_not;
  EXPECT_EQ(scan.spread, 0);        // every border pixel on the backdrop is exactly white
  EXPECT_EQ(scan.filled_share, 0);  // the object stands in every view's middle
  EXPECT_NEAR(scan.view_share, 8.0 / 9.0, 1e-12);  // the tinted view is off it
}

// A textured surface whose mean is a backdrop's colour: half the border and
// more within the tolerance of the median, on every view, but spread evenly
// over it (reflectance 0.5 +- 0.06, independent per pixel) as no backdrop is.
TEST(Init, ATexturedFieldIsNoBackdrop) {
  auto texture = [](int view) {
    torch::manual_seed(uint64_t(view) + 1);
    const torch::Tensor grey = 0.5 + 0.12 * (torch::rand({kHeight, kWidth, 1}) - 0.5);
    return core::to_u8(grey.repeat({1, 1, 3}));
  };
  auto scene = io::load_scene(write_scene("init_field", 14.0, texture));
  const io::BorderScan scan = io::scan_border(*scene, scene->train);
  EXPECT_GT(scan.share, 0.5);
  EXPECT_GT(scan.view_share, 0.66);
  EXPECT_GT(scan.spread, io::kBackdropMaxSpread);
  EXPECT_FALSE(scan.masked);
  EXPECT_NE(scan.why_not.find("a texture"), std::string::npos) << scan.why_not;
  EXPECT_FALSE(io::masked_backdrop(*scene, scene->train).has_value());
}

// A uniform floor filling every frame, seen from above with noise: its border
// is as constant as a backdrop's, but it fills the middle of the views too,
// where a masked capture shows its object.
TEST(Init, AFloorFillingTheFrameIsNoBackdrop) {
  auto floor = [](int view) {
    torch::manual_seed(uint64_t(view) + 1);
    const torch::Tensor grey = 0.5 + 0.005 * torch::randn({kHeight, kWidth, 1});
    return core::to_u8(grey.repeat({1, 1, 3}));
  };
  auto scene = io::load_scene(write_scene("init_floor", 14.0, floor));
  const io::BorderScan scan = io::scan_border(*scene, scene->train);
  EXPECT_GT(scan.share, 0.99);
  EXPECT_LE(scan.spread, io::kBackdropMaxSpread);
  EXPECT_EQ(scan.filled_share, 1.0);
  EXPECT_FALSE(scan.masked);
  EXPECT_NE(scan.why_not.find("fills the middle of 100 % of the views"), std::string::npos)
      << scan.why_not;
}

TEST(Init, ANaturalBorderIsNoBackdrop) {
  // Every border pixel a different grey: nothing within the tolerance of the median.
  auto ramp = [](int) {
    auto image = torch::arange(kHeight * kWidth, torch::kFloat32).view({kHeight, kWidth, 1});
    return (image * (250.0f / (kHeight * kWidth))).to(torch::kUInt8).repeat({1, 1, 3});
  };
  auto scene = io::load_scene(write_scene("init_natural", 14.0, ramp));
  EXPECT_FALSE(io::masked_backdrop(*scene, scene->train).has_value());
}

// A field of two colours in a checkerboard to every edge, as many of each:
// each channel's median is the lower value, a colour no pixel has, so no
// border pixel lies on it (a survey's textured ground did this).
TEST(Init, ABorderWithNoPixelOnItsMedianColourIsNoBackdrop) {
  auto checker = [](int) {
    const torch::Tensor y = torch::arange(kHeight).view({kHeight, 1, 1});
    const torch::Tensor x = torch::arange(kWidth).view({1, kWidth, 1});
    const torch::Tensor a = ((x + y) % 2).to(torch::kUInt8) * 255;  // [H, W, 1]
    return torch::cat({a, 255 - a, torch::full_like(a, 128)}, 2);
  };
  auto scene = io::load_scene(write_scene("init_checker", 14.0, checker));
  const io::BorderScan scan = io::scan_border(*scene, scene->train);
  EXPECT_EQ(scan.share, 0);
  EXPECT_EQ(scan.spread, 0);
  EXPECT_FALSE(scan.masked);
  EXPECT_NE(scan.why_not.find("0 % of the view borders"), std::string::npos) << scan.why_not;
}

}  // namespace
}  // namespace ddhgs::train
