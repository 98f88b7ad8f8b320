// `ddhgs export` end to end: tiny runs trained through the binary (a 6-band
// one and an RGB one on the same synthesized scene), their exports rendered
// back by `ddhgs render-ply` from the test views and compared with the runs'
// own renders (`ddhgs render`), and the files read by an independent PLY and
// .splat reader (tests/app/export_reader_check.py).
#include <gtest/gtest.h>

#include <cmath>
#include <regex>

#include "core/colour.h"
#include "io/cube/cube.h"
#include "io/image/image.h"
#include "io/scene/scene.h"
#include "io/transforms/camera_json.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args + " 2>&1", out);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The "--background" value `ddhgs export` prints for render-ply.
std::string printed_background(const std::string& out) {
  std::smatch m;
  EXPECT_TRUE(std::regex_search(out, m, std::regex("render-ply --background\\): (\\S+)"))) << out;
  return m.size() > 1 ? m[1].str() : "0";
}

class ExportCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = new fs::path(test::temp_dir("export_cli"));
    const fs::path scene = *root_ / "scene";
    std::string out;
    ASSERT_EQ(ddhgs("synth --preset demo --force --out " + scene.string() +
                        " --width 40 --height 30 --bands 6 --views 10 --points 400 --supersample 1",
                    &out),
              0)
        << out;
    for (const char* kind : {"spectral", "rgb"})
      ASSERT_EQ(ddhgs("--threads 2 train " + scene.string() + " --out " + (*root_ / kind).string() +
                          // No opacity reset (a third of the run in the demo
                          // preset): the crop test needs opaque Gaussians.
                          " --preset demo --iterations 60 --checkpoint-every 1000" +
                          " --set densify.opacity_reset_every_fraction=0" +
                          (std::string(kind) == "rgb" ? " --rgb" : ""),
                      &out),
                0)
          << out;
  }
  static void TearDownTestSuite() { delete root_; }

  // Renders `ply` with render-ply from every test view of the scene, and the
  // run with `ddhgs render`: (export render float [H, W, 3], run render float
  // [H, W, N], run's pseudo-RGB picture uint8 [H, W, 3]) per view.
  struct Renders {
    torch::Tensor exported, run, run_rgb;
  };
  static std::vector<Renders> render_both(const fs::path& run, const fs::path& ply,
                                          const std::string& background, bool rgb) {
    io::LoadOptions options;
    options.rgb = rgb;
    auto scene = io::load_scene(*root_ / "scene", options);
    const fs::path renders = run / "renders_npy";
    std::string out;
    EXPECT_EQ(ddhgs("render " + run.string() + " --format npy --out " + renders.string(), &out), 0)
        << out;
    std::vector<Renders> result;
    for (int v : scene->test) {
      const auto& view = scene->views[size_t(v)];
      const fs::path camera = run / (view.name + "_camera.json");
      const fs::path npy = run / (view.name + "_export.npy");
      io::write_camera_json(camera, view.camera);
      EXPECT_EQ(ddhgs("render-ply " + ply.string() + " --camera " + camera.string() + " --out " +
                          npy.string() + " --background " + background,
                      &out),
                0)
          << out;
      result.push_back({io::cube_to_float(io::read_cube(npy)),
                        io::cube_to_float(io::read_cube(renders / (view.name + ".npy"))),
                        io::read_image(renders / (view.name + "_rgb.png"))});
    }
    EXPECT_FALSE(result.empty());
    return result;
  }

  static fs::path* root_;
};
fs::path* ExportCli::root_ = nullptr;

TEST_F(ExportCli, RgbRunExportRendersExactlyAsTheRun) {
  const fs::path run = *root_ / "rgb", ply = run / "export" / "gaussians_rgb.ply";
  std::string out;
  ASSERT_EQ(ddhgs("export " + run.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out, "RGB (the model's own three channels)")) << out;
  for (const Renders& r : render_both(run, ply, printed_background(out), true))
    EXPECT_LT((r.exported - r.run).abs().max().item<float>(), 1e-5);
}

TEST_F(ExportCli, CieExportRendersToTheRunsPseudoRgb) {
  const fs::path run = *root_ / "spectral";
  std::string out;
  // Linear light: the export renders to render's pseudo-RGB once the sRGB
  // curve is applied to the image, as render applies it.
  const fs::path linear = run / "linear.ply";
  ASSERT_EQ(ddhgs("export " + run.string() + " --linear --out " + linear.string(), &out), 0) << out;
  for (const Renders& r : render_both(run, linear, printed_background(out), false)) {
    torch::Tensor shown = core::to_u8(core::srgb_encode(r.exported.clamp(0, 1))).to(torch::kInt);
    torch::Tensor expected = r.run_rgb.to(torch::kInt);
    torch::Tensor steps = (shown - expected).abs();
    // Within 8-bit quantisation, except where a Gaussian's linear RGB is
    // negative: the renderer clamps per Gaussian colour, render per band.
    EXPECT_GT((steps <= 1).to(torch::kFloat).mean().item<float>(), 0.98) << steps.max();
    EXPECT_LT(steps.to(torch::kFloat).mean().item<float>(), 0.5);
  }

  // Default (sRGB curve per Gaussian, for viewers that blend display
  // values): close to render's pseudo-RGB, not equal, since blending after
  // the curve differs from applying the curve after blending; most where
  // translucent Gaussians overlap, as in this 60-iteration model (31.2 dB
  // measured; a wrong mapping gives under 20).
  const fs::path srgb = run / "srgb.ply";
  ASSERT_EQ(ddhgs("export " + run.string() + " --out " + srgb.string(), &out), 0) << out;
  EXPECT_TRUE(contains(out, "pseudo-RGB (CIE 1931, D65, sRGB curve per Gaussian)")) << out;
  for (const Renders& r : render_both(run, srgb, printed_background(out), false)) {
    torch::Tensor picture = r.run_rgb.to(torch::kDouble) / 255;
    double mse =
        (r.exported.to(torch::kDouble).clamp(0, 1) - picture).square().mean().item<double>();
    EXPECT_GT(-10 * std::log10(mse), 28.0);
  }
}

TEST_F(ExportCli, FilesOpenInAnIndependentReader) {
  const fs::path run = *root_ / "spectral";
  std::string out;
  // The synthetic scene's 6 bands are 400, 520, ..., 1000 nm.
  const fs::path ply = run / "bands.ply", splat = run / "bands.splat";
  ASSERT_EQ(ddhgs("export " + run.string() + " --bands 1000,640,400 --out " + ply.string(), &out),
            0)
      << out;
  ASSERT_EQ(ddhgs("export " + run.string() + " --bands 1000,640,400 --format splat --out " +
                      splat.string(),
                  &out),
            0)
      << out;
  int rc = test::run_command(
      test::python() + " " + (test::source_dir() / "tests/app/export_reader_check.py").string() +
          " " + (run / "gaussians.ply").string() + " " + ply.string() + " 5,2,0 " + splat.string() +
          " 2>&1",
      &out);
  EXPECT_EQ(rc, 0) << out;
}

TEST_F(ExportCli, CropsAndRejectsBadChoicesWithOneLine) {
  const fs::path run = *root_ / "spectral";
  std::string out;
  const fs::path cropped = run / "cropped.splat";
  ASSERT_EQ(ddhgs("export " + run.string() + " --format splat --min-opacity 0.5 --out " +
                      cropped.string(),
                  &out),
            0)
      << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex("exported (\\d+) of (\\d+) Gaussians"))) << out;
  const long kept = std::stol(m[1]), total = std::stol(m[2]);
  EXPECT_LT(kept, total);
  EXPECT_EQ(fs::file_size(cropped), size_t(kept) * 32);

  const fs::path nothing = run / "nothing.ply";
  EXPECT_EQ(
      ddhgs("export " + run.string() + " --crop 100,100,100,101,101,101 --out " + nothing.string(),
            &out),
      1);
  EXPECT_TRUE(contains(out, "--crop")) << out;
  EXPECT_EQ(ddhgs("export " + run.string() + " --crop 1,1,1,0,0,0 --out " + nothing.string(), &out),
            1);
  EXPECT_TRUE(contains(out, "minimum exceeds its maximum")) << out;
  EXPECT_EQ(ddhgs("export " + run.string() + " --band 2000 --out " + nothing.string(), &out), 1);
  EXPECT_TRUE(contains(out, "--band: no band near 2000 nm")) << out;
  EXPECT_FALSE(fs::exists(nothing));
  EXPECT_EQ(ddhgs("export " + (*root_ / "no-such-run").string(), &out), 1);
  EXPECT_TRUE(contains(out, "run folder")) << out;
}

}  // namespace
}  // namespace ddhgs
