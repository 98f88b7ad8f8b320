// Light that changes between a flight's captures: `ddhgs synth` lights each
// rig capture by a factor its DLS does not see; `ddhgs process --rig` keeps
// that factor in the capture's reflectance; training learns it back as each
// view's gain (model.exposure_correction, on for band-per-view scenes), resumes
// bit for bit with it, and leaves it out of every render (eval measures the
// PLY as the trainer measured its held-out views).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <map>

#include "io/files/atomic_file.h"
#include "io/scene/scene.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

using test::ddhgs;

using test::read_json;

// Capture 4 is held out (the middle of 8).
const std::vector<double> kFactors = {0.85, 1.15, 0.9, 1.2, 1.05, 0.8, 1.1, 0.95};

std::string factor_list() {
  std::string out;
  for (double f : kFactors) out += (out.empty() ? "" : ",") + std::to_string(f);
  return out;
}

// A small nadir strip lit by kFactors, processed through each capture's DLS
// with the true poses, and the truth's clean views beside it.
const fs::path& strip() {
  static const fs::path scene = [] {
    const fs::path root = test::temp_dir("light_cli");
    std::string out;
    EXPECT_EQ(ddhgs("synth --preset rig-nadir --width 80 --height 60 --supersample 1 "
                    "--light-factors " +
                        factor_list() + " --out " + (root / "rig").string(),
                    &out),
              0)
        << out;
    EXPECT_EQ(test::process_with_true_poses(root / "rig", root / "scene", "", &out), 0) << out;
    fs::copy(root / "rig" / "truth" / "clean", root / "scene" / "clean");
    return root / "scene";
  }();
  return scene;
}

int capture_of(const std::string& view_name) {  // IMG_0003_2 -> 3
  return std::stoi(view_name.substr(4, 4));
}

TEST(LightCli, SynthLightsEachCaptureByItsFactorBehindTheDlsBack) {
  const fs::path rig = strip().parent_path() / "rig";
  const json synth = read_json(rig / "synth.json");
  ASSERT_EQ(synth["light_factors"].size(), kFactors.size());
  for (size_t c = 0; c < kFactors.size(); ++c)
    EXPECT_NEAR(synth["light_factors"][c].get<double>(), kFactors[c], 1e-12);
  // The DLS reflectance of each band view is the truth times its capture's factor.
  const auto processed = io::load_scene(strip());
  const auto truth = io::load_scene(rig / "truth");
  std::map<std::string, int> by_name;
  for (size_t v = 0; v < truth->views.size(); ++v) by_name[truth->views[v].name] = int(v);
  for (size_t v = 0; v < processed->views.size(); ++v) {
    const std::string& name = processed->views[v].name;
    const torch::Tensor got = processed->image(int(v)), want = truth->image(by_name.at(name));
    const torch::Tensor mask = want > 0.05;
    const double ratio = got.masked_select(mask).mean().item<double>() /
                         want.masked_select(mask).mean().item<double>();
    EXPECT_NEAR(ratio, kFactors[size_t(capture_of(name))], 0.01) << name;
  }
  // Drawn factors stay within the change asked for; refusals name the flag.
  std::string out;
  const fs::path drawn = strip().parent_path() / "drawn";
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --width 16 --height 12 --supersample 1 "
                  "--light-change 0.2 --out " +
                      drawn.string(),
                  &out),
            0)
      << out;
  const json factors = read_json(drawn / "synth.json")["light_factors"];
  ASSERT_EQ(factors.size(), 8u);
  bool changed = false;
  for (const json& f : factors) {
    EXPECT_GE(f.get<double>(), 0.8);
    EXPECT_LE(f.get<double>(), 1.2);
    changed = changed || f.get<double>() != 1.0;
  }
  EXPECT_TRUE(changed);
  const std::string refused = " --out " + (strip().parent_path() / "refused").string();
  EXPECT_EQ(ddhgs("synth --preset rig-nadir --light-factors 1,0.9" + refused, &out), 1);
  EXPECT_NE(out.find("--light-factors has 2 values"), std::string::npos) << out;
  EXPECT_EQ(ddhgs("synth --preset demo --light-change 0.2" + refused, &out), 1);
  EXPECT_NE(out.find("for the rig presets"), std::string::npos) << out;
  EXPECT_EQ(ddhgs("synth --preset rig-nadir --light-change 0.2 --light-factors " + factor_list() +
                      refused,
                  &out),
            1);
  EXPECT_NE(out.find("not both"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(strip().parent_path() / "refused"));
}

TEST(LightCli, TrainingLearnsEachCapturesGainResumesBitForBitAndRendersWithoutIt) {
  const fs::path runs = test::temp_dir("light_cli_runs");
  const fs::path straight = runs / "straight", split = runs / "split";
  std::string out;
  const std::string args = " --iterations 600 --checkpoint-every 300 --set output.test_every=0";
  ASSERT_EQ(ddhgs("train " + strip().string() + " --out " + straight.string() + args, &out), 0)
      << out;
  EXPECT_NE(out.find("exposure correction: each training view learns a gain"), std::string::npos)
      << out;
  EXPECT_NE(out.find("exposure correction: gains"), std::string::npos) << out;
  const json summary = read_json(straight / "train_summary.json");
  ASSERT_TRUE(summary.contains("exposure_gains")) << summary.dump();
  // The training captures' factors over their geometric mean (the level the
  // Gaussians keep: recentre()), against the gains learned.
  double log_mean = 0;
  for (size_t c = 0; c < kFactors.size(); ++c)
    if (c != 4) log_mean += std::log(kFactors[c]) / double(kFactors.size() - 1);
  size_t views = 0;
  double worst = 0, squares = 0;
  for (const auto& [name, gains] : summary["exposure_gains"].items()) {
    ASSERT_EQ(gains.size(), 1u) << name;
    const double expected = kFactors[size_t(capture_of(name))] / std::exp(log_mean);
    const double error = gains[0].get<double>() / expected - 1;
    worst = std::max(worst, std::abs(error));
    squares += error * error;
    ++views;
  }
  EXPECT_EQ(views, 35u);  // 7 training captures x 5 band cameras
  const double rms = std::sqrt(squares / double(views));
  std::printf("learned gains against the captures' light: %.2f %% rms, worst %.2f %% off\n",
              100 * rms, 100 * worst);
  // Roughly, in 600 iterations at 80x60 (measured 3.6 % rms, worst 9.4 %),
  // against factors 13 % rms from 1.
  EXPECT_LT(rms, 0.05);
  EXPECT_LT(worst, 0.12);

  // Resumed from iteration 300: the same model and gains.
  fs::copy(straight, split, fs::copy_options::recursive);
  fs::copy_file(split / "checkpoints" / "ckpt_300.pt", split / "checkpoint.pt",
                fs::copy_options::overwrite_existing);
  fs::remove(split / "gaussians.ply");
  ASSERT_EQ(ddhgs("train --resume " + split.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(split / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));
  EXPECT_EQ(read_json(split / "train_summary.json")["exposure_gains"], summary["exposure_gains"]);

  // eval renders the PLY alone and measures what the trainer measured on the
  // held-out capture, which no gain touched.
  ASSERT_EQ(ddhgs("eval " + straight.string(), &out), 0) << out;
  const json metrics = read_json(straight / "eval" / "metrics.json");
  EXPECT_NEAR(metrics["psnr"].get<double>(), summary["test_psnr"].get<double>(), 1e-4);

  // Off: no gains, and a different model.
  ASSERT_EQ(ddhgs("train " + strip().string() + " --out " + (runs / "off").string() + args +
                      " --set model.exposure_correction=off",
                  &out),
            0)
      << out;
  EXPECT_FALSE(read_json(runs / "off" / "train_summary.json").contains("exposure_gains"));
  EXPECT_EQ(out.find("exposure correction"), std::string::npos) << out;
  EXPECT_NE(io::read_file(runs / "off" / "gaussians.ply"),
            io::read_file(straight / "gaussians.ply"));
}

}  // namespace
}  // namespace ddhgs
