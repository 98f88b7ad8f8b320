// Every command on runs of unusual band layouts, as a user would run them:
// an RGB run (the --rgb images of a scene), a dataset listing its
// wavelengths in decreasing order, and one repeating a wavelength. Each
// command must finish and print the dataset's warning once.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/scene/scene.h"
#include "io/transforms/camera_json.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

size_t count(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args + " 2>&1", out);
}

const fs::path& scene() {
  static const fs::path dir = [] {
    fs::path d = test::temp_dir("layouts_cli_scene") / "scene";
    std::string out;
    EXPECT_EQ(ddhgs("synth --preset demo --width 32 --height 24 --bands 6 --views 10 --points 300 "
                    "--supersample 1 --out " +
                        d.string(),
                    &out),
              0)
        << out;
    return d;
  }();
  return dir;
}

// A copy of the scene whose transforms.json lists `wavelengths_nm`.
fs::path relabelled_scene(const std::string& name, const std::vector<double>& wavelengths_nm) {
  fs::path dir = test::temp_dir(name) / "scene";
  fs::copy(scene(), dir, fs::copy_options::recursive);
  io::TransformsFile file = io::read_transforms(dir / "transforms.json");
  file.wavelengths_nm = wavelengths_nm;
  io::write_transforms(dir / "transforms.json", file);
  return dir;
}

fs::path train(const fs::path& data, const std::string& name, const std::string& extra,
               std::string* out) {
  fs::path run = test::temp_dir(name) / "run";
  EXPECT_EQ(ddhgs("train " + data.string() + " --out " + run.string() +
                      " --preset demo --iterations 40 " + extra,
                  out),
            0)
      << *out;
  return run;
}

// render (pictures, --diff, a band range), eval, report, export and
// render-ply on a run; `warning` (when given) is printed once by each
// command that loads the dataset.
void every_command(const fs::path& run, const std::string& band_range, const std::string& warning) {
  std::string out;
  for (const std::string& args :
       {"render " + run.string() + " --format npy --diff",
        "render " + run.string() + " --bands " + band_range,
        "eval " + run.string() + " --fps-repeats 0", "report " + run.string() + " --views 1"}) {
    ASSERT_EQ(ddhgs(args, &out), 0) << args << "\n" << out;
    if (!warning.empty()) {
      EXPECT_EQ(count(out, warning), 1u) << args << "\n" << out;
    }
  }
  EXPECT_TRUE(fs::exists(run / "report" / "index.html"));
  EXPECT_TRUE(fs::exists(run / "eval" / "metrics.json"));
  ASSERT_EQ(ddhgs("export " + run.string(), &out), 0) << out;
  EXPECT_TRUE(fs::exists(run / "export" / "gaussians_rgb.ply"));

  // render-ply from the first test view's camera.
  json config = json::parse(io::read_file(run / "config.json"));
  io::LoadOptions options;
  options.rgb = config["data"]["rgb"].get<bool>();
  auto loaded = io::load_scene(config["data"]["path"].get<std::string>(), options);
  io::write_camera_json(run / "cam.json", loaded->views[size_t(loaded->test.at(0))].camera);
  ASSERT_EQ(ddhgs("render-ply " + (run / "gaussians.ply").string() + " --camera " +
                      (run / "cam.json").string() + " --out " + (run / "view.npy").string() +
                      " --preview " + (run / "view.png").string(),
                  &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(run / "view.png"));
}

TEST(BandLayoutsCli, RgbRun) {
  std::string out;
  fs::path run = train(scene(), "layouts_cli_rgb", "--rgb", &out);
  EXPECT_EQ(io::read_gaussian_ply(run / "gaussians.ply").wavelengths_nm, io::rgb_wavelengths_nm());
  every_command(run, "540:620", "");
  // An RGB run's picture is its three channels as they are (no CIE mapping).
  fs::path renders = run / "renders" / "test";
  int checked = 0;
  for (const auto& entry : fs::directory_iterator(renders)) {
    if (entry.path().extension() != ".npy") continue;
    io::Cube cube = io::read_cube(entry.path());
    torch::Tensor expected = (cube.data.clamp(0, 1) * 255).round().to(torch::kUInt8);
    fs::path png = renders / (entry.path().stem().string() + "_rgb.png");
    io::Cube picture = io::read_cube(png);
    EXPECT_LE((picture.data.to(torch::kInt) - expected.to(torch::kInt)).abs().max().item<int>(), 1)
        << png;
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(BandLayoutsCli, DecreasingWavelengthsAreSorted) {
  // The synthetic cubes hold 400..1000 nm in increasing order; this file
  // claims the reverse, so band b of the files is taken as 1000 - 120 b nm.
  fs::path data = relabelled_scene("layouts_cli_desc", {1000, 880, 760, 640, 520, 400});
  std::string out;
  fs::path run = train(data, "layouts_cli_desc_run", "", &out);
  const std::string warning = "not in increasing order";
  EXPECT_EQ(count(out, warning), 1u) << out;
  EXPECT_EQ(io::read_gaussian_ply(run / "gaussians.ply").wavelengths_nm,
            (std::vector<double>{400, 520, 640, 760, 880, 1000}));
  every_command(run, "500:700", warning);
}

TEST(BandLayoutsCli, RepeatedWavelengthsUseTheBandIndex) {
  fs::path data = relabelled_scene("layouts_cli_repeat", {500, 500, 600, 700, 800, 900});
  std::string out;
  fs::path run = train(data, "layouts_cli_repeat_run", "", &out);
  const std::string warning = "using the band index";
  EXPECT_EQ(count(out, warning), 1u) << out;
  std::vector<double> nm = io::read_gaussian_ply(run / "gaussians.ply").wavelengths_nm;
  EXPECT_TRUE(std::is_sorted(nm.begin(), nm.end()) &&
              std::adjacent_find(nm.begin(), nm.end()) == nm.end());
  every_command(run, "400:800", warning);
}

}  // namespace
}  // namespace ddhgs
