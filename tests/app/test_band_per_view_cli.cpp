// A band-per-view scene end to end (each view holds one band, as a
// multispectral rig's band cameras do): the demo scene's cubes split into one
// file per band per view, trained, evaluated and reported as a user would,
// and compared with the same scene trained from its registered cubes.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kBands = 4;

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args, out);
}

using test::read_json;

// `cubes` rewritten as bands/<view>_b<band>.npy (and clean/ likewise), one
// frame per band per view at the view's pose, the split kept.
void split_into_band_views(const fs::path& cubes, const fs::path& out) {
  const auto scene = io::load_scene(cubes);
  const io::TransformsFile original = io::read_transforms(cubes / "transforms.json");
  io::TransformsFile split;
  split.wavelengths_nm = scene->wavelengths_nm;
  split.ply_file_path = original.ply_file_path;
  fs::create_directories(out / "bands");
  fs::create_directories(out / "clean");
  fs::copy_file(cubes / original.ply_file_path, out / original.ply_file_path);
  std::vector<bool> is_test(scene->views.size(), false);
  for (int v : scene->test) is_test[size_t(v)] = true;
  for (size_t v = 0; v < scene->views.size(); ++v) {
    const io::View& view = scene->views[v];
    const io::Cube cube = io::read_cube(view.data_path);
    const io::Cube clean = io::read_cube(view.clean_path);
    const io::TransformsFrame* frame = nullptr;
    for (const auto& f : original.frames)
      if (fs::path(f.hyperspectral_file_path).stem() == view.name) frame = &f;
    ASSERT_NE(frame, nullptr);
    for (int b = 0; b < kBands; ++b) {
      const std::string file = view.name + "_b" + std::to_string(b) + ".npy";
      const torch::Tensor band = torch::tensor({int64_t(b)});
      io::write_npy(out / "bands" / file, cube.data.index_select(2, band).contiguous(), cube.type);
      io::write_npy(out / "clean" / file, clean.data.index_select(2, band).contiguous(),
                    clean.type);
      io::TransformsFrame f = *frame;
      f.file_path.clear();
      f.hyperspectral_file_path = "bands/" + file;
      f.bands = {b};
      split.frames.push_back(f);
      (is_test[v] ? split.test_files : split.train_files).push_back("bands/" + file);
    }
  }
  io::write_transforms(out / "transforms.json", split);
}

TEST(BandPerViewCli, TrainsEvaluatesAndReportsLikeRegisteredCubes) {
  const fs::path root = test::temp_dir("band_per_view_cli");
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset demo --width 48 --height 36 --bands " + std::to_string(kBands) +
                      " --views 12 --points 800 --out " + (root / "cubes").string(),
                  &out),
            0)
      << out;
  split_into_band_views(root / "cubes", root / "bands");

  ASSERT_EQ(ddhgs("info " + (root / "bands").string(), &out), 0) << out;
  EXPECT_NE(out.find("no view holds whole spectra"), std::string::npos) << out;

  // Each band view supervises one band: four times the iterations give both
  // runs the same number of supervised band images.
  const std::string common = " --preset demo --set output.test_every=0";
  ASSERT_EQ(ddhgs("train " + (root / "cubes").string() + " --out " + (root / "cube_run").string() +
                      " --iterations 150" + common,
                  &out),
            0)
      << out;
  ASSERT_EQ(ddhgs("train " + (root / "bands").string() + " --out " + (root / "band_run").string() +
                      " --iterations 600" + common,
                  &out),
            0)
      << out;
  const json cube_summary = read_json(root / "cube_run" / "train_summary.json");
  const json band_summary = read_json(root / "band_run" / "train_summary.json");
  EXPECT_EQ(band_summary["bands"], kBands);
  const double cube_psnr = cube_summary["test_psnr_clean"].get<double>();
  const double band_psnr = band_summary["test_psnr_clean"].get<double>();
  std::printf("test PSNR vs clean: registered cubes %.2f dB, band per view %.2f dB\n", cube_psnr,
              band_psnr);
  EXPECT_GT(band_psnr, 20.0);
  EXPECT_GT(band_psnr, cube_psnr - 1.5);

  // eval measures each view on its band and averages band by band; one band
  // has no spectral angle.
  ASSERT_EQ(ddhgs("eval " + (root / "band_run").string(), &out), 0) << out;
  EXPECT_NE(out.find("SAM -: every view holds one band"), std::string::npos) << out;
  const json metrics = read_json(root / "band_run" / "eval" / "metrics.json");
  const json per_band = metrics["clean"]["per_band_psnr"]["psnr"];
  ASSERT_EQ(per_band.size(), size_t(kBands)) << metrics.dump();
  double mean = 0;
  for (const json& v : per_band) {
    ASSERT_TRUE(v.is_number()) << metrics.dump();
    mean += v.get<double>() / kBands;
  }
  EXPECT_GT(mean, 20.0);
  EXPECT_NEAR(metrics["clean"]["psnr"].get<double>(), band_psnr, 1e-6) << metrics.dump();

  EXPECT_TRUE(metrics["sam"].is_null()) << metrics.dump();

  // A report is written; a --diff render compares each held-out view on its
  // own band (truth | render | error).
  ASSERT_EQ(ddhgs("report " + (root / "band_run").string(), &out), 0) << out;
  EXPECT_TRUE(fs::exists(root / "band_run" / "report" / "index.html")) << out;
  ASSERT_EQ(ddhgs("render " + (root / "band_run").string() + " --diff", &out), 0) << out;
  const auto scene = io::load_scene(root / "bands");
  ASSERT_FALSE(scene->test.empty());
  for (int v : scene->test) {
    const io::View& view = scene->views[size_t(v)];
    EXPECT_TRUE(
        fs::exists(root / "band_run" / "renders" / "test" /
                   (view.name + "_band" + std::to_string(view.bands.at(0)) + "_compare.png")))
        << view.name;
  }
  // The diffusion stage is refused with the setting that avoids it.
  ASSERT_EQ(ddhgs("train " + (root / "bands").string() + " --out " + (root / "diffusion").string() +
                      " --iterations 5 --set loss.diffusion=0.3",
                  &out),
            1)
      << out;
  EXPECT_NE(out.find("loss.diffusion=0"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "diffusion"));
}

// The default preset's 30,000 iterations would be hours on a real-size
// flight: a band-per-view scene trains for optim.iterations_per_band_view per
// training band image, written into the run's config so that a resume keeps
// it, unless the user gives the length.
TEST(BandPerViewCli, TrainsPerBandImageUnlessTheLengthIsGiven) {
  const fs::path root = test::temp_dir("band_per_view_length");
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset demo --width 32 --height 24 --bands " + std::to_string(kBands) +
                      " --views 6 --points 300 --out " + (root / "cubes").string(),
                  &out),
            0)
      << out;
  split_into_band_views(root / "cubes", root / "bands");
  const auto scene = io::load_scene(root / "bands");
  const int64_t training = int64_t(scene->train.size());
  ASSERT_GT(training, 10);
  const std::string common =
      " --set output.test_every=0 --set optim.iterations_per_band_view=2 --out ";
  ASSERT_EQ(ddhgs("train " + (root / "bands").string() + common + (root / "auto").string(), &out),
            0)
      << out;
  EXPECT_NE(out.find("training for " + std::to_string(2 * training) + " iterations"),
            std::string::npos)
      << out;
  EXPECT_EQ(read_json(root / "auto" / "train_summary.json")["iterations"], 2 * training);
  EXPECT_EQ(read_json(root / "auto" / "config.json")["iterations"], 2 * training);
  // --iterations, even above the per-image length, is the length; so is --set.
  ASSERT_EQ(ddhgs("train " + (root / "bands").string() + " --iterations " +
                      std::to_string(3 * training) + common + (root / "given").string(),
                  &out),
            0)
      << out;
  EXPECT_EQ(read_json(root / "given" / "train_summary.json")["iterations"], 3 * training);
  ASSERT_EQ(ddhgs("train " + (root / "bands").string() + " --set iterations=" +
                      std::to_string(3 * training) + common + (root / "set").string(),
                  &out),
            0)
      << out;
  EXPECT_EQ(read_json(root / "set" / "config.json")["iterations"], 3 * training);
  // The registered cubes hold every band per view: a preset's length stands
  // (50 iterations, more than 2 per cube view).
  io::write_file_atomically(root / "short.json",
                            R"({"format_version": 2, "extends": "demo", "iterations": 50})");
  ASSERT_EQ(ddhgs("train " + (root / "cubes").string() + " --preset " +
                      (root / "short.json").string() + common + (root / "cube_run").string(),
                  &out),
            0)
      << out;
  EXPECT_EQ(read_json(root / "cube_run" / "train_summary.json")["iterations"], 50);
}

}  // namespace
}  // namespace ddhgs
