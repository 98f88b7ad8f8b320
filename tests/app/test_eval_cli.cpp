// `ddhgs eval` and `ddhgs render` run as a user would, on a synthesized scene
// and a run folder (config.json + gaussians.ply) laid out as `ddhgs train`
// leaves it; bad run folders give one clear line and exit 1.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/scene/scene.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr double kShC0 = 0.28209479177387814;
constexpr int kBands = 6;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args, out);
}

// One line ending the output: the error message.
std::string last_line(const std::string& out) {
  std::string s = out;
  while (!s.empty() && s.back() == '\n') s.pop_back();
  return s.substr(s.rfind('\n') == std::string::npos ? 0 : s.rfind('\n') + 1);
}

// Gaussians at the scene's sparse points, coloured by the points' spectra.
io::GaussianPly model_from_points(const io::Scene& scene) {
  torch::Tensor xyz = scene.points.xyz;
  int64_t g = xyz.size(0), n = scene.bands();
  io::GaussianPly ply;
  ply.means = xyz.to(torch::kFloat);
  ply.log_scales = torch::full({g, 3}, std::log(0.03f));
  ply.quats = torch::tensor({1.0f, 0.0f, 0.0f, 0.0f}).repeat({g, 1});
  ply.logit_opacities = torch::full({g, 1}, 2.0f);
  torch::Tensor colour = scene.points.spectra.defined() ? scene.points.spectra.to(torch::kFloat)
                                                        : torch::full({g, n}, 0.5f);
  ply.sh_dc = (colour - 0.5) / kShC0;
  ply.sh_rest = torch::zeros({g, n, 3});
  ply.wavelengths_nm = scene.wavelengths_nm;
  return ply;
}

// A float32 .npy of shape [H, W] with NaNs, which the cube readers refuse on
// purpose: version 1 header, little-endian data after it.
torch::Tensor read_float_npy(const fs::path& path, int64_t height, int64_t width) {
  const std::string bytes = io::read_file(path);
  const size_t header = 10 + (uint8_t(bytes[8]) | (uint8_t(bytes[9]) << 8));
  EXPECT_NE(bytes.find("'descr': '<f4'"), std::string::npos) << path;
  EXPECT_EQ(bytes.size(), header + size_t(height * width) * 4) << path;
  torch::Tensor out = torch::empty({height, width}, torch::kFloat);
  std::memcpy(out.data_ptr<float>(), bytes.data() + header, size_t(height * width) * 4);
  return out;
}

class EvalCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_dir_ = test::temp_dir("cli_eval_scene");
    std::string out;
    int rc = ddhgs("synth --preset demo --force --out " + scene_dir_.string() +
                       " --width 32 --height 24 --bands " + std::to_string(kBands) +
                       " --views 10 --points 300 --supersample 1",
                   &out);
    ASSERT_EQ(rc, 0) << out;
  }

  // A run folder: the default config pointing at the scene, and a model.
  fs::path make_run(const std::string& name) {
    fs::path run = test::temp_dir(name);
    json config = json::parse(io::read_file(test::source_dir() / "configs" / "default.json"));
    config["data"]["path"] = scene_dir_.string();
    // A fixed background: a run that learned one would also hold background.json.
    config["model"]["learn_background"] = false;
    config["model"]["background_from_views"] = false;
    io::write_file_atomically(run / "config.json", config.dump(2));
    auto scene = io::load_scene(scene_dir_);
    io::write_gaussian_ply(run / "gaussians.ply", model_from_points(*scene));
    return run;
  }

  static fs::path scene_dir_;
};
fs::path EvalCli::scene_dir_;

TEST_F(EvalCli, EvalWritesMetricsAgainstViewsAndCleanTruth) {
  fs::path run = make_run("cli_eval_run");
  std::string out;
  ASSERT_EQ(ddhgs("eval " + run.string() + " --fps-repeats 2", &out), 0) << out;
  EXPECT_TRUE(contains(out, "PSNR dB")) << out;
  EXPECT_TRUE(contains(out, "FPS")) << out;
  json m = json::parse(io::read_file(run / "eval" / "metrics.json"));
  EXPECT_EQ(m["split"], "test");
  EXPECT_EQ(m["bands"], kBands);
  for (const char* key : {"psnr", "ssim", "sam", "rmse", "fps"}) {
    ASSERT_TRUE(m.contains(key)) << key;
    EXPECT_TRUE(std::isfinite(m[key].get<double>())) << key;
  }
  EXPECT_GT(m["psnr"].get<double>(), 0);
  ASSERT_TRUE(m.contains("clean")) << "the synthetic scene has clean ground truth";
  EXPECT_EQ(m["per_band_psnr"]["psnr"].size(), size_t(kBands));
  std::string csv = io::read_file(run / "eval" / "per_view.csv");
  size_t rows = size_t(std::count(csv.begin(), csv.end(), '\n'));
  EXPECT_EQ(rows, 1 + 2 * size_t(m["views"].get<int>())) << csv;

  // --align-poses: a row and a block more, the plain figures unchanged.
  ASSERT_EQ(ddhgs("eval " + run.string() + " --fps-repeats 0 --align-poses --align-steps 20", &out),
            0)
      << out;
  EXPECT_TRUE(contains(out, "  aligned ")) << out;
  json aligned = json::parse(io::read_file(run / "eval" / "metrics.json"));
  EXPECT_DOUBLE_EQ(aligned["psnr"].get<double>(), m["psnr"].get<double>());
  ASSERT_TRUE(aligned.contains("aligned"));
  EXPECT_EQ(aligned["aligned"]["steps"], 20);
  EXPECT_GE(aligned["aligned"]["psnr"].get<double>(), m["psnr"].get<double>() - 0.05);
  EXPECT_TRUE(contains(io::read_file(run / "eval" / "per_view.csv"), ",aligned_motion_px\n"));

  ASSERT_EQ(ddhgs("eval " + run.string() + " --split train --fps-repeats 0", &out), 0) << out;
  json train = json::parse(io::read_file(run / "eval" / "metrics_train.json"));
  EXPECT_EQ(train["split"], "train");
  EXPECT_FALSE(train.contains("fps"));
}

TEST_F(EvalCli, RenderWritesCubesPicturesAndOrbit) {
  fs::path run = make_run("cli_render_run");
  std::string out;
  ASSERT_EQ(ddhgs("render " + run.string() + " --format npy --diff --diff-max 0.2", &out), 0)
      << out;
  fs::path dir = run / "renders" / "test";
  int cubes = 0, compares = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".npy") {
      ++cubes;
      EXPECT_EQ(io::probe_cube(entry.path()).bands, kBands);
    }
    if (contains(name, "_rgb_compare.png")) ++compares;
    EXPECT_FALSE(contains(name, ".tmp")) << name;
  }
  EXPECT_GT(cubes, 0);
  EXPECT_EQ(compares, cubes);

  // --index ndvi: (NIR - red) / (NIR + red) of the same renders. No band of
  // this 6-band scene lies in either window (842 +- 28.5, 668 +- 7 nm), so
  // each is the linear interpolation at the window's centre, computed here
  // by hand from the scene's wavelengths.
  ASSERT_EQ(ddhgs("render " + run.string() + " --index ndvi --format npy --diff", &out), 0) << out;
  const std::vector<double> wl = io::load_scene(scene_dir_)->wavelengths_nm;
  auto at = [&](const torch::Tensor& cube, double nm) {
    size_t hi = 1;
    while (wl[hi] < nm) ++hi;
    const double t = (nm - wl[hi - 1]) / (wl[hi] - wl[hi - 1]);
    return cube.select(2, int64_t(hi - 1)) * (1 - t) + cube.select(2, int64_t(hi)) * t;
  };
  const fs::path ndvi_dir = run / "renders" / "test_ndvi";
  const json summary = json::parse(io::read_file(ndvi_dir / "ndvi.json"));
  ASSERT_EQ(summary["frames"].size(), size_t(cubes));
  for (const json& frame : summary["frames"]) {
    const std::string name = frame["name"];
    const torch::Tensor cube = io::read_cube(dir / (name + ".npy")).data.to(torch::kDouble);
    const torch::Tensor nir = at(cube, 842), red = at(cube, 668);
    const torch::Tensor expected = (nir - red) / (nir + red);
    const torch::Tensor got =
        read_float_npy(ndvi_dir / (name + "_ndvi.npy"), cube.size(0), cube.size(1));
    ASSERT_EQ(got.sizes(), expected.sizes());
    const torch::Tensor signal = (nir + red) > 1e-3;
    EXPECT_TRUE(got.isfinite().eq(signal).all().item<bool>()) << name;  // NaN without signal
    EXPECT_LT((got.to(torch::kDouble) - expected).masked_select(signal).abs().max().item<double>(),
              1e-5)
        << name;
    EXPECT_TRUE(fs::exists(ndvi_dir / (name + "_ndvi_compare.png"))) << name;
    EXPECT_TRUE(std::isfinite(frame["mean_absolute_error"].get<double>())) << frame.dump();
  }
  EXPECT_EQ(summary["truth"], "clean");
  EXPECT_EQ(ddhgs("render " + run.string() + " --index evi", &out), 1);
  EXPECT_TRUE(contains(last_line(out), "--index: unknown index 'evi' (one of ndvi, ndre, gndvi)"))
      << out;
  EXPECT_NE(ddhgs("render " + run.string() + " --index ndvi --band 2", &out), 0);

  fs::path orbit = test::temp_dir("cli_orbit");
  ASSERT_EQ(ddhgs("render " + run.string() + " --orbit 4 --band 2 --colormap gray --out " +
                      orbit.string(),
                  &out),
            0)
      << out;
  for (int i = 0; i < 4; ++i) {
    fs::path pic = orbit / ("orbit_00" + std::to_string(i) + "_band2.png");
    ASSERT_TRUE(fs::exists(pic)) << pic;
    EXPECT_EQ(io::read_image(pic).size(1), 32);
  }
  // Flags that contradict each other are refused by the parser.
  EXPECT_NE(ddhgs("render " + run.string() + " --orbit 4 --split train", &out), 0);
  EXPECT_EQ(ddhgs("render " + run.string() + " --bands 2000:2100", &out), 1);
  EXPECT_TRUE(contains(last_line(out), "--bands")) << out;
}

TEST_F(EvalCli, BadRunFoldersGiveOneClearLine) {
  std::string out;
  fs::path missing_model = make_run("cli_bad_model");
  fs::remove(missing_model / "gaussians.ply");
  EXPECT_EQ(ddhgs("eval " + missing_model.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "gaussians.ply")) << out;

  fs::path old = make_run("cli_bad_version");
  json config = json::parse(io::read_file(old / "config.json"));
  config["format_version"] = 99;
  io::write_file_atomically(old / "config.json", config.dump());
  EXPECT_EQ(ddhgs("render " + old.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "format_version")) << out;

  fs::path moved = make_run("cli_bad_data");
  config = json::parse(io::read_file(moved / "config.json"));
  config["data"]["path"] = (moved / "no-such-scene").string();
  io::write_file_atomically(moved / "config.json", config.dump());
  EXPECT_EQ(ddhgs("eval " + moved.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "data.path")) << out;
  // --data points a moved run at its dataset.
  EXPECT_EQ(
      ddhgs("eval " + moved.string() + " --fps-repeats 0 --data " + scene_dir_.string(), &out), 0)
      << out;

  fs::path bands = make_run("cli_bad_bands");
  io::GaussianPly ply = io::read_gaussian_ply(bands / "gaussians.ply");
  ply.sh_dc = ply.sh_dc.narrow(1, 0, 3).contiguous();
  ply.sh_rest = ply.sh_rest.narrow(1, 0, 3).contiguous();
  ply.wavelengths_nm.resize(3);
  io::write_gaussian_ply(bands / "gaussians.ply", ply);
  EXPECT_EQ(ddhgs("eval " + bands.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "bands")) << out;

  EXPECT_EQ(ddhgs("eval " + (bands / "nothing").string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "run folder")) << out;
  EXPECT_FALSE(fs::exists(missing_model / "eval" / "metrics.json"));
}

}  // namespace
}  // namespace ddhgs
