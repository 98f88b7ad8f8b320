// Check at the start, not after the last iteration: input a run
// cannot use ends the command before any work with one line naming the file
// or flag; a scene without held-out views trains; a diverging run stops at
// once. Each case was first seen failing (an error after training, a NaN
// model written with exit 0, or nonsense accepted without a word).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>

#include "cli_support.h"
#include "io/cube/cube.h"
#include "io/transforms/camera_json.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

using test::ddhgs;
using test::error_lines;
using test::kQuickTrain;
using test::tiny_scene;

// A copy of the tiny scene that a test may damage.
fs::path scene_copy(const std::string& name) {
  const fs::path copy = test::temp_dir(name) / "scene";
  fs::copy(tiny_scene(), copy, fs::copy_options::recursive);
  return copy;
}

void truncate_file(const fs::path& path) {
  fs::resize_file(path, fs::file_size(path) / 2);
}

// Exit 1 with one error line holding every piece of `expected`.
void expect_refused(const std::string& args, const std::vector<std::string>& expected) {
  std::string out;
  EXPECT_EQ(ddhgs(args, &out), 1) << args << "\n" << out;
  const auto errors = error_lines(out);
  ASSERT_EQ(errors.size(), 1u) << args << "\n" << out;
  for (const auto& piece : expected) EXPECT_NE(errors[0].find(piece), std::string::npos) << out;
}

TEST(EarlyChecks, ASceneWithoutHeldOutViewsTrainsAndSaysSo) {
  const fs::path dir = test::temp_dir("early_no_test");
  std::string out;
  // 9 views: the Hyper-NeRF split holds none out.
  ASSERT_EQ(ddhgs("-q synth --preset demo --width 32 --height 24 --bands 4 --views 9 --out " +
                      (dir / "nine").string(),
                  &out),
            0)
      << out;
  // All views listed for training, test_filenames empty.
  const fs::path listed = scene_copy("early_no_test_listed");
  json transforms = json::parse(io::read_file(listed / "transforms.json"));
  transforms["train_filenames"] = json::array();
  for (const auto& frame : transforms["frames"])
    transforms["train_filenames"].push_back(frame["hyperspectral_file_path"]);
  transforms["test_filenames"] = json::array();
  io::write_file_atomically(listed / "transforms.json", transforms.dump(2));
  for (const fs::path& scene : {dir / "nine", listed}) {
    const fs::path run = scene.parent_path() / "run";
    EXPECT_EQ(ddhgs("-q train " + scene.string() + " --out " + run.string() + kQuickTrain, &out), 0)
        << out;
    EXPECT_NE(out.find("no held-out views"), std::string::npos) << out;
    const json summary = json::parse(io::read_file(run / "train_summary.json"));
    EXPECT_EQ(summary.at("iterations"), 20);
    EXPECT_FALSE(summary.contains("test_psnr"));
  }
  // An ablation needs them: refused before any row trains.
  expect_refused("-q ablate " + (dir / "nine").string() + " --out " + (dir / "ablation").string() +
                     " --preset demo --set iterations=20",
                 {(dir / "nine").string(), "no held-out views"});
  EXPECT_FALSE(fs::exists(dir / "ablation"));
}

TEST(EarlyChecks, ABadHeldOutViewOrCleanCubeFailsBeforeTheFirstIteration) {
  const fs::path scene = scene_copy("early_bad_views");
  const fs::path run = scene.parent_path() / "run";
  // r_010 is the held-out view of the 12-view scene.
  truncate_file(scene / "hyperspectral" / "r_010.npy");
  const auto start = std::chrono::steady_clock::now();
  expect_refused("-q train " + scene.string() + " --out " + run.string() +
                     " --preset demo --iterations 100000",
                 {"r_010.npy", "truncated"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(60));
  EXPECT_FALSE(fs::exists(run));
  fs::copy_file(tiny_scene() / "hyperspectral" / "r_010.npy", scene / "hyperspectral" / "r_010.npy",
                fs::copy_options::overwrite_existing);
  // A clean cube whose header is fine but whose samples are not.
  torch::Tensor nan = torch::zeros({24, 32, 4});
  nan[3][4][1] = std::nanf("");
  io::write_npy(scene / "clean" / "r_010.npy", nan);
  expect_refused("-q train " + scene.string() + " --out " + run.string() + kQuickTrain,
                 {"clean/r_010.npy", "NaN"});
  EXPECT_FALSE(fs::exists(run));
}

// A compressed training view is decoded once before the first iteration: a
// corrupt one fails at the start, naming the file, not when training first
// draws it (with one iteration it was never drawn at all).
TEST(EarlyChecks, ACorruptCompressedTrainingViewFailsBeforeTheFirstIteration) {
  const fs::path scene = scene_copy("early_corrupt_png");
  const fs::path run = scene.parent_path() / "run";
  const fs::path png = scene / "images" / "r_003.png";  // a training view
  std::string bytes = io::read_file(png);
  const size_t idat = bytes.find("IDAT");
  ASSERT_NE(idat, std::string::npos);
  for (size_t k = idat + 10; k < std::min(idat + 60, bytes.size() - 20); ++k) bytes[k] ^= 0x5A;
  io::write_file_atomically(png, bytes);
  expect_refused("-q train " + scene.string() + " --rgb --out " + run.string() +
                     " --preset demo --iterations 1",
                 {"r_003.png", "not a readable"});
  EXPECT_FALSE(fs::exists(run));
}

TEST(EarlyChecks, ConfigValuesARunCannotUseAreRefusedBeforeAnyWork) {
  const fs::path dir = test::temp_dir("early_config");
  const std::string train =
      "-q train " + tiny_scene().string() + " --out " + (dir / "run").string() + " --preset demo";
  expect_refused(train + " --set model.sh_degree=4", {"model.sh_degree", "<= 3"});
  expect_refused(train + " --set optim.sh_rest_lr_divisor=0", {"optim.sh_rest_lr_divisor", "> 0"});
  expect_refused(train + " --iterations -5", {"--iterations", "-5"});
  EXPECT_FALSE(fs::exists(dir / "run"));
  std::string out;
  ASSERT_EQ(ddhgs(train + " --iterations 10", &out), 0) << out;
  expect_refused("-q train --resume " + (dir / "run").string() + " --iterations -5",
                 {"--iterations", "-5"});
}

TEST(EarlyChecks, ADivergingRunStopsAtOnceAndKeepsItsLastGoodCheckpoint) {
  const fs::path run = test::temp_dir("early_diverge") / "run";
  std::string out;
  // A learning rate that throws the opacities to infinity within a few steps.
  EXPECT_EQ(ddhgs("-q train " + tiny_scene().string() + " --out " + run.string() +
                      " --preset demo --iterations 200 --checkpoint-every 1"
                      " --set optim.opacity_lr=100 --set optim.scaling_lr=100",
                  &out),
            1)
      << out;
  const auto errors = error_lines(out);
  ASSERT_EQ(errors.size(), 1u) << out;
  EXPECT_NE(errors[0].find("training diverged at iteration"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(run / "gaussians.ply"));
}

TEST(EarlyChecks, OutputsThatWouldOverwriteAnInputAreRefused) {
  const fs::path dir = test::temp_dir("early_outputs");
  const fs::path run = dir / "run";
  std::string out;
  ASSERT_EQ(
      ddhgs("-q train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain, &out), 0)
      << out;
  const fs::path ply = dir / "g.ply", camera = dir / "camera.json";
  fs::copy_file(run / "gaussians.ply", ply);
  core::Camera cam;
  cam.intrinsics = {40, 40, 16, 12, 32, 24};
  io::write_camera_json(camera, cam);
  const std::string model = io::read_file(ply);
  const std::string render = "-q render-ply " + ply.string() + " --camera " + camera.string();
  expect_refused(render + " --out " + ply.string(), {"--out", "g.ply", "the input PLY"});
  expect_refused(render + " --out " + (dir / "x.png").string(), {"--out", ".npy"});
  expect_refused(
      render + " --out " + (dir / "x.npy").string() + " --preview " + (dir / "x.npy").string(),
      {"--preview", "the --out file"});
  expect_refused(
      render + " --out " + (dir / "x.npy").string() + " --preview " + (dir / "x.jpg").string(),
      {"--preview", ".png"});
  expect_refused(render + " --out " + (dir / "x.npy").string() + " --preview " + camera.string(),
                 {"--preview"});
  EXPECT_EQ(io::read_file(ply), model);
  EXPECT_FALSE(fs::exists(dir / "x.npy"));
  ASSERT_EQ(ddhgs(render + " --out " + (dir / "x.npy").string() + " --preview " +
                      (dir / "x.png").string(),
                  &out),
            0)
      << out;

  const std::string trained = io::read_file(run / "gaussians.ply");
  expect_refused("-q export " + run.string() + " --out " + (run / "gaussians.ply").string(),
                 {"--out", "a file of the run"});
  expect_refused("-q export " + run.string() + " --out " + (dir / "rgb.txt").string(),
                 {"--out", ".ply"});
  EXPECT_EQ(io::read_file(run / "gaussians.ply"), trained);
  // The format follows the extension when --format is not given.
  ASSERT_EQ(ddhgs("-q export " + run.string() + " --out " + (dir / "rgb.splat").string(), &out), 0)
      << out;
  EXPECT_EQ(fs::file_size(dir / "rgb.splat") % 32, 0u);
}

// A downscale that leaves next to nothing of the views names the flag and
// the views' size (it was LibTorch's "max(): Expected reduction dim ...").
TEST(EarlyChecks, ADownscaleLargerThanTheViewsIsNamed) {
  const fs::path dir = test::temp_dir("early_downscale");
  const std::string scene = tiny_scene().string();
  for (const char* d : {"1000", "25"}) {  // the views are 32 x 24 px
    expect_refused("-q train " + scene + " --out " + (dir / "run").string() + " --downscale " + d,
                   {std::string("--downscale ") + d, "px", "at most"});
    expect_refused("info " + scene + " --downscale " + d, {std::string("--downscale ") + d});
  }
  EXPECT_FALSE(fs::exists(dir / "run"));
}

// A value the command line cannot parse is one error line and exit 1, like
// every other error (it was CLI11's two lines and its own exit codes 104-109).
TEST(EarlyChecks, CommandLineParseErrorsAreOneLineAndExit1) {
  const std::string train = "train " + tiny_scene().string() + " --out " +
                            (test::temp_dir("early_parse") / "run").string();
  expect_refused(train + " --iterations abc", {"--iterations", "abc"});
  expect_refused(train + " --no-such-flag", {"--no-such-flag"});
  expect_refused("info", {"dir"});
  std::string out;
  EXPECT_EQ(ddhgs("info --help", &out), 0) << out;
  EXPECT_EQ(ddhgs("--version", &out), 0) << out;
}

TEST(EarlyChecks, ThousandsOfThreadsAreCapped) {
  std::string out;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(ddhgs("--threads 2000 info " + tiny_scene().string(), &out), 0) << out;
  EXPECT_NE(out.find("threads per CPU"), std::string::npos) << out;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(60));
  expect_refused("--threads -3 info " + tiny_scene().string(), {"--threads"});
}

TEST(EarlyChecks, NonsenseInTransformsJsonIsNamed) {
  const fs::path scene = scene_copy("early_transforms");
  const fs::path file = scene / "transforms.json";
  const json good = json::parse(io::read_file(file));
  auto refused = [&](json edited, const std::vector<std::string>& expected) {
    io::write_file_atomically(file, edited.dump(2));
    std::vector<std::string> pieces = {file.string()};
    pieces.insert(pieces.end(), expected.begin(), expected.end());
    expect_refused("-q info " + scene.string(), pieces);
  };
  json mirrored = good;
  for (int row = 0; row < 3; ++row)
    mirrored["frames"][0]["transform_matrix"][row][0] =
        -mirrored["frames"][0]["transform_matrix"][row][0].get<double>();
  refused(mirrored, {"frames[0].transform_matrix", "reflection"});
  json duplicated = good;
  duplicated["frames"][5] = duplicated["frames"][2];
  refused(duplicated, {"frames[5]", "frames[2]"});
  json negative = good;
  negative["wavelengths"][0] = -400.0;
  refused(negative, {"wavelengths[0]", "> 0"});
}

TEST(EarlyChecks, SynthRefusesAFillOfZero) {
  const fs::path dir = test::temp_dir("early_synth");
  expect_refused("-q" + test::kTinyScene + " --fill 0 --out " + (dir / "s").string(), {"--fill"});
  EXPECT_FALSE(fs::exists(dir / "s"));
}

}  // namespace
}  // namespace ddhgs
