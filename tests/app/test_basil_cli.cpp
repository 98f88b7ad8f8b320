// `ddhgs train` with its default settings on the real Basil capture (narrow
// field of view, white-masked backdrop, real pose error): a short run at
// --downscale 8 must stay well above a PSNR floor on the Hyper-NeRF test
// views, and `ddhgs eval` must find the white backdrop and measure the plant
// on its own. The capture is part of the repository (tests/data/basil, with
// its provenance and licence).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "io/files/atomic_file.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

fs::path basil() {
  return test::source_dir() / "tests" / "data" / "basil";
}

TEST(BasilCli, DefaultSettingsLearnTheRealCapture) {
  const fs::path data = basil();
  // Its COLMAP layout, through links: the folder also holds transforms.json,
  // which ddhgs would read first.
  const fs::path dir = test::temp_dir("basil_cli");
  const fs::path scene = dir / "basil";
  fs::create_directories(scene);
  for (const char* sub : {"images", "images_8", "colmap"})
    fs::create_directory_symlink(data / sub, scene / sub);

  std::string out;
  const fs::path run = dir / "run";
  ASSERT_EQ(test::run_command(test::ddhgs_binary() + " train " + scene.string() + " --out " +
                                  run.string() + " --downscale 8 --iterations 300",
                              &out),
            0)
      << out;
  // The capture's two turntable rings leave each test view a 14-degree stop
  // from the nearest training view; training says so before it starts.
  EXPECT_NE(out.find("held-out views are 13.3-14.9 degrees from the nearest training view"),
            std::string::npos)
      << out;
  const auto summary = nlohmann::json::parse(io::read_file(run / "train_summary.json"));
  // Measured 17.3-17.6 dB over three seeds (one thread, 3 s); the defaults before
  // the extra random points and learning rates gave 15.4 dB, and the black
  // background of the earlier default, which the Gaussians must paint white,
  // 9.8 dB on the same run.
  EXPECT_GT(summary["test_psnr"].get<double>(), 16.0) << summary.dump();

  // The views are masked to white: eval measures the plant on its own too,
  // and the plant scores below the whole view, whose white backdrop the
  // learned background matches almost exactly.
  ASSERT_EQ(
      test::run_command(test::ddhgs_binary() + " eval " + run.string() + " --fps-repeats 0", &out),
      0)
      << out;
  EXPECT_NE(out.find("the views are masked to a uniform backdrop ("), std::string::npos) << out;
  const auto metrics = nlohmann::json::parse(io::read_file(run / "eval" / "metrics.json"));
  for (double v : metrics["backdrop"]["value"].get<std::vector<double>>())
    EXPECT_GT(v, 0.98) << metrics.dump();  // white, to JPEG's precision
  const auto& object = metrics["object"];
  // About 40 % of each test view is plant, pot or turntable.
  EXPECT_GT(object["pixel_share"].get<double>(), 0.3) << metrics.dump();
  EXPECT_LT(object["pixel_share"].get<double>(), 0.5) << metrics.dump();
  EXPECT_LT(object["psnr"].get<double>(), metrics["psnr"].get<double>() - 1) << metrics.dump();
  EXPECT_GT(object["sam"].get<double>(), metrics["sam"].get<double>()) << metrics.dump();
}

TEST(BasilCli, InfoShowsTheNarrowFieldAndTheTurntableSpacing) {
  const fs::path data = basil();
  std::string out;
  ASSERT_EQ(test::run_command(test::ddhgs_binary() + " info " + data.string() + " --rgb", &out), 0)
      << out;
  // fx 4873 px over 696 px, fy 4563 px over 520 px.
  EXPECT_NE(out.find("field of view 8.2 x 6.5 deg"), std::string::npos) << out;
  // Two turntable rings of 25 stops, 14-15 degrees apart; frames 1, 25, 26
  // and 50 nearly coincide (1.7 degrees); each test view is a full stop from
  // its nearest training view.
  EXPECT_NE(out.find("spacing     training views 14.0 deg from their nearest neighbour (median; "
                     "1.7-15.2); test views 13.3-14.9 deg from the nearest training view"),
            std::string::npos)
      << out;
  // The white mask, on most of the border (the black turntable is the rest).
  EXPECT_NE(out.find("backdrop    masked to 1.000, 1.000, 1.000 on 82 % of the view borders"),
            std::string::npos)
      << out;
}

}  // namespace
}  // namespace ddhgs
