// Raw counts to reflectance through white and dark references, on small
// ENVI cubes the tests write: known raw, white and dark give known
// reflectance; saturated and dead pixels are counted; references that do
// not fit the cubes, and bad white reflectances, are refused by name.
#include <gtest/gtest.h>

#include <fstream>

#include "io/cube/cube.h"
#include "process/reflectance.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::process {
namespace {
namespace fs = std::filesystem;
using test::contains;
using test::error_of;

constexpr int64_t kH = 3, kW = 4, kB = 2;
const std::vector<double> kWavelengths = {550, 650};

// uint16 counts as an ENVI cube (int16 bits, unsigned type).
void write_counts(const fs::path& hdr, const torch::Tensor& counts,
                  const std::vector<double>& wavelengths = kWavelengths) {
  io::write_envi(hdr, counts.to(torch::kInt32).to(torch::kInt16).contiguous(), wavelengths,
                 io::EnviInterleave::BSQ, io::SampleType::U16);
}

double raw_count(int64_t y, int64_t x, int64_t b) {
  return 150 + 40 * double(y) + 60 * double(x) + 25 * double(b);
}

// Dark: 100 (120 at column 1, band 0), one row. White: two rows, 1100 and
// 1300 + 10 per column in band 0 (mean 1200 + 10 x), 2100 in band 1; band
// 1 of column 3 equals the dark (dead). Raw: raw_count, saturated at two samples.
struct Files {
  fs::path dir, raw, white, dark;
};
Files write_files(const std::string& name) {
  Files f;
  f.dir = test::temp_dir(name);
  f.raw = f.dir / "cubes" / "v0.hdr";
  f.white = f.dir / "white.hdr";
  f.dark = f.dir / "dark.hdr";
  fs::create_directories(f.dir / "cubes");
  torch::Tensor dark = torch::full({1, kW, kB}, 100.0, torch::kFloat64);
  dark[0][1][0] = 120;
  torch::Tensor white = torch::zeros({2, kW, kB}, torch::kFloat64);
  for (int64_t x = 0; x < kW; ++x) {
    white[0][x][0] = 1100 + 10 * double(x);
    white[1][x][0] = 1300 + 10 * double(x);
    white[0][x][1] = white[1][x][1] = 2100;
  }
  white[0][3][1] = white[1][3][1] = 100;
  torch::Tensor raw = torch::zeros({kH, kW, kB}, torch::kFloat64);
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x)
      for (int64_t b = 0; b < kB; ++b) raw[y][x][b] = raw_count(y, x, b);
  raw[0][0][0] = 65535;
  raw[2][2][1] = 65535;
  write_counts(f.raw, raw);
  write_counts(f.white, white);
  write_counts(f.dark, dark);
  return f;
}

TEST(Reflectance, KnownCountsGiveKnownReflectanceAndCountsOfBadPixels) {
  const Files f = write_files("reflectance_known");
  std::ofstream(f.dir / "panel.csv") << "wavelength_nm,reflectance\n500,0.9\n700,0.99\n";
  const std::vector<double> rho =
      parse_white_reflectance((f.dir / "panel.csv").string(), kWavelengths);
  ASSERT_EQ(rho.size(), 2u);
  EXPECT_NEAR(rho[0], 0.9225, 1e-12);  // a quarter of the way from 500 to 700 nm
  EXPECT_NEAR(rho[1], 0.9675, 1e-12);

  const torch::Tensor white = read_reference(f.white, kW, kB);
  const torch::Tensor dark = read_reference(f.dark, kW, kB);
  EXPECT_DOUBLE_EQ(white[2][0].item<double>(), 1220);  // rows averaged
  // The same two lines as .npy, which the layout guess alone reads band-first.
  io::write_npy(f.dir / "white.npy", io::read_cube(f.white).data, io::SampleType::U16);
  EXPECT_TRUE(torch::equal(read_reference(f.dir / "white.npy", kW, kB), white));
  const io::Cube raw = io::read_cube(f.raw);
  ASSERT_EQ(top_count(raw.type), std::optional<double>(65535));
  ReflectanceCounts counts;
  const torch::Tensor got = to_reflectance(raw, white, dark, rho, top_count(raw.type), &counts);
  ASSERT_EQ(got.sizes(), (std::vector<int64_t>{kH, kW, kB}));
  EXPECT_EQ(counts.samples, kH * kW * kB);
  EXPECT_EQ(counts.saturated, 2);
  EXPECT_EQ(counts.dead, 1);  // column 3, band 1
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x)
      for (int64_t b = 0; b < kB; ++b) {
        if ((y == 0 && x == 0 && b == 0) || (y == 2 && x == 2 && b == 1)) continue;
        const double d = (x == 1 && b == 0) ? 120 : 100;
        const double w = b == 0 ? 1200 + 10 * double(x) : (x == 3 ? 100 : 2100);
        const double want = x == 3 && b == 1 ? 0 : (raw_count(y, x, b) - d) / (w - d) * rho[b];
        EXPECT_NEAR(got[y][x][b].item<double>(), want, 1e-6) << y << " " << x << " " << b;
      }
  // A saturated sample keeps its (lower-bound) reflectance.
  EXPECT_NEAR(got[0][0][0].item<double>(), (65535.0 - 100) / 1100 * rho[0], 1e-4);
  // A 12-bit sensor's top count: every sample at or above it is saturated.
  ReflectanceCounts twelve;
  to_reflectance(raw, white, dark, rho, 4095.0, &twelve);
  EXPECT_EQ(twelve.saturated, 2);
  to_reflectance(raw, white, dark, rho, 300.0, &twelve);
  EXPECT_GT(twelve.saturated, 2);
}

TEST(Reflectance, ReferencesThatDoNotFitTheCubesAreRefused) {
  const Files f = write_files("reflectance_mismatch");
  const CubeSet cubes = scan_cubes(f.dir / "cubes");
  ReflectanceOptions options;
  options.white = f.white;
  options.dark = f.dark;
  EXPECT_NO_THROW(plan_calibration(cubes, options));

  write_counts(f.dir / "white3.hdr", torch::full({2, kW, 3}, 2000.0), {550, 600, 650});
  options.white = f.dir / "white3.hdr";
  std::string e = error_of([&] { plan_calibration(cubes, options); });
  EXPECT_TRUE(contains(e, "white3.hdr: a reference of 3 bands for cubes of 2")) << e;

  write_counts(f.dir / "dark5.hdr", torch::full({1, kW + 1, kB}, 100.0));
  options.white = f.white;
  options.dark = f.dir / "dark5.hdr";
  e = error_of([&] { plan_calibration(cubes, options); });
  EXPECT_TRUE(contains(e, "dark5.hdr: a reference 5 pixels wide for cubes 4 wide")) << e;

  options.dark.clear();
  e = error_of([&] { plan_calibration(cubes, options); });
  EXPECT_TRUE(contains(e, "give both references")) << e;
}

TEST(Reflectance, WhiteReflectanceIsANumberOrAFileOfTheBands) {
  EXPECT_EQ(parse_white_reflectance("0.99", kWavelengths), (std::vector<double>{0.99, 0.99}));
  const fs::path dir = test::temp_dir("reflectance_white");
  std::ofstream(dir / "per_band.txt") << "0.95\n0.97\n";
  EXPECT_EQ(parse_white_reflectance((dir / "per_band.txt").string(), kWavelengths),
            (std::vector<double>{0.95, 0.97}));
  std::ofstream(dir / "three.txt") << "0.95\n0.97\n0.98\n";
  std::string e =
      error_of([&] { parse_white_reflectance((dir / "three.txt").string(), kWavelengths); });
  EXPECT_TRUE(contains(e, "three.txt: holds 3 values; the cubes have 2 bands")) << e;
  std::ofstream(dir / "short.csv") << "600,0.9\n700,0.9\n";
  e = error_of([&] { parse_white_reflectance((dir / "short.csv").string(), kWavelengths); });
  EXPECT_TRUE(contains(e, "short.csv: covers 600-700 nm, not the band at 550 nm")) << e;
  e = error_of([&] { parse_white_reflectance("-0.5", kWavelengths); });
  EXPECT_TRUE(contains(e, "(0, 2]")) << e;
  e = error_of([&] { parse_white_reflectance((dir / "missing.csv").string(), kWavelengths); });
  EXPECT_TRUE(contains(e, "neither a number nor a file")) << e;
}

}  // namespace
}  // namespace ddhgs::process
