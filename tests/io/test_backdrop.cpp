// io/scene/backdrop: the object of a masked view and its interior, on small
// hand-made images whose answers can be read off the pixels.
#include <gtest/gtest.h>

#include "core/error.h"
#include "io/scene/backdrop.h"

namespace ddhgs::io {
namespace {

// A 6 x 7 two-band view on the backdrop (1.0, 0.5) with a 4 x 4 object at
// rows 1-4, columns 2-5.
torch::Tensor masked_view() {
  auto image = torch::empty({6, 7, 2});
  image.select(2, 0).fill_(1.0);
  image.select(2, 1).fill_(0.5);
  image.slice(0, 1, 5).slice(1, 2, 6).fill_(0.2);
  return image;
}

TEST(Backdrop, ObjectIsThePixelsUnlikeTheBackdropInSomeBand) {
  const torch::Tensor backdrop = torch::tensor({1.0f, 0.5f});
  torch::Tensor image = masked_view();
  image[0][0][1] = 0.5f + 0.03f;  // within the tolerance (0.04) in its one band
  image[5][6][0] = 1.0f - 0.05f;  // beyond it in one band of two
  const torch::Tensor mask = object_mask(image, backdrop);
  ASSERT_EQ(mask.sizes(), (std::vector<int64_t>{6, 7}));
  EXPECT_EQ(mask.scalar_type(), torch::kBool);
  EXPECT_FALSE(mask[0][0].item<bool>());
  EXPECT_TRUE(mask[5][6].item<bool>());
  EXPECT_EQ(mask.sum().item<int64_t>(), 16 + 1);
  EXPECT_TRUE(mask.slice(0, 1, 5).slice(1, 2, 6).all().item<bool>());
  // A tighter tolerance takes the 0.03 pixel too.
  EXPECT_TRUE(object_mask(image, backdrop, 0.02)[0][0].item<bool>());
  EXPECT_THROW(object_mask(image, torch::ones({3})), core::Error);
}

TEST(Backdrop, InteriorLeavesOutTheOnePixelOutline) {
  const torch::Tensor mask = object_mask(masked_view(), torch::tensor({1.0f, 0.5f}));
  const torch::Tensor inside = interior(mask);
  // The 4 x 4 block keeps its middle 2 x 2: rows 2-3, columns 3-4.
  EXPECT_EQ(inside.sum().item<int64_t>(), 4);
  EXPECT_TRUE(inside.slice(0, 2, 4).slice(1, 3, 5).all().item<bool>());
  // Diagonal neighbours count: a backdrop pixel at a corner's diagonal makes
  // the corner outline.
  torch::Tensor notch = mask.clone();
  notch[1][2] = false;
  EXPECT_FALSE(interior(notch)[2][3].item<bool>());
  EXPECT_TRUE(interior(notch)[3][4].item<bool>());
}

TEST(Backdrop, AnObjectCutByTheFrameHasNoOutlineThere) {
  // The object fills the left three columns of a 4 x 5 view.
  torch::Tensor mask = torch::zeros({4, 5}, torch::kBool);
  mask.slice(1, 0, 3).fill_(true);
  const torch::Tensor inside = interior(mask);
  // Columns 0-1 stay interior to the frame's edges; column 2 borders the backdrop.
  EXPECT_TRUE(inside.slice(1, 0, 2).all().item<bool>());
  EXPECT_FALSE(inside.slice(1, 2, 5).any().item<bool>());
  EXPECT_THROW(interior(torch::ones({2, 2, 1}, torch::kBool)), core::Error);
}

TEST(Backdrop, DescribeColourListsFewBandsAndRangesMany) {
  EXPECT_EQ(describe_colour(torch::tensor({1.0f, 0.5f, 0.25f})), "1.000, 0.500, 0.250");
  EXPECT_EQ(describe_colour(torch::linspace(0.1, 0.9, 128)), "0.100 to 0.900 over 128 bands");
}

}  // namespace
}  // namespace ddhgs::io
