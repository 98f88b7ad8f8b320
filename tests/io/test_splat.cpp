// .splat files (io/splat.h) against records worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/splat/splat.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {

constexpr double kC0 = 0.28209479177387814;

struct Record {
  float xyz[3], scale[3];
  uint8_t rgba[4], rot[4];
};
static_assert(sizeof(Record) == kSplatRecordBytes);

// Two Gaussians: a small opaque one first, a large one second, so the
// larger-first order of the format swaps them.
GaussianPly two_gaussians() {
  GaussianPly ply;
  ply.means = torch::tensor({{1.f, 2.f, 3.f}, {-1.f, 0.5f, 0.f}});
  ply.log_scales = torch::tensor({{std::log(0.01f), std::log(0.02f), std::log(0.03f)},
                                  {std::log(1.f), std::log(2.f), std::log(0.5f)}});
  ply.quats = torch::tensor({{2.f, 0.f, 0.f, 0.f}, {0.f, 0.f, 0.f, -3.f}});  // unnormalised
  ply.logit_opacities = torch::tensor({{10.f}, {0.f}});
  // Colours 0.5 + C0 dc: (1.0, 0.5, 0.0) and (0.25, 2.0 -> clamped 1, 0.75).
  ply.sh_dc = torch::tensor({{float(0.5 / kC0), 0.f, float(-0.5 / kC0)},
                             {float(-0.25 / kC0), float(1.5 / kC0), float(0.25 / kC0)}});
  ply.sh_rest = torch::zeros({2, 3, 15});
  return ply;
}

TEST(Splat, WritesLargestFirstRecordsWorkedOutByHand) {
  const auto path = test::temp_dir("splat") / "two.splat";
  write_splat(path, two_gaussians());
  const std::string bytes = read_file(path);
  ASSERT_EQ(bytes.size(), 2 * sizeof(Record));
  Record r[2];
  std::memcpy(r, bytes.data(), bytes.size());

  // Large Gaussian (size 1 x 2 x 0.5 at opacity 0.5) first.
  EXPECT_EQ(r[0].xyz[0], -1.f);
  EXPECT_EQ(r[0].xyz[1], 0.5f);
  EXPECT_NEAR(r[0].scale[1], 2.f, 1e-6);
  EXPECT_NEAR(r[0].scale[2], 0.5f, 1e-6);
  EXPECT_EQ(r[0].rgba[0], 64);   // 0.25 * 255 = 63.75
  EXPECT_EQ(r[0].rgba[1], 255);  // clamped
  EXPECT_EQ(r[0].rgba[2], 191);  // 0.75 * 255 = 191.25
  EXPECT_EQ(r[0].rgba[3], 128);  // sigmoid(0) * 255 = 127.5, rounded away from zero
  EXPECT_EQ(r[0].rot[0], 128);   // w = 0
  EXPECT_EQ(r[0].rot[3], 0);     // z = -1 -> 0

  EXPECT_EQ(r[1].xyz[2], 3.f);
  EXPECT_NEAR(r[1].scale[0], 0.01f, 1e-8);
  EXPECT_EQ(r[1].rgba[0], 255);
  EXPECT_EQ(r[1].rgba[1], 128);
  EXPECT_EQ(r[1].rgba[2], 0);
  EXPECT_EQ(r[1].rgba[3], 255);  // sigmoid(10) = 0.99995
  EXPECT_EQ(r[1].rot[0], 255);   // w = 1 -> 256, clamped
  EXPECT_EQ(r[1].rot[1], 128);
}

TEST(Splat, RefusesModelsWithoutThreeChannelsAndLeavesNoFile) {
  GaussianPly ply = two_gaussians();
  ply.sh_dc = torch::zeros({2, 5});
  const auto path = test::temp_dir("splat_bad") / "five.splat";
  EXPECT_THROW(write_splat(path, ply), core::Error);
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace ddhgs::io
