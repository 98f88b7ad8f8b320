// Never lose a user's data: what --force and every other writer
// may touch, concurrent writers, SIGTERM. Every destructive command here is
// pointed at a folder inside this test's own temporary folder; the home
// folder is a temporary stand-in given through $HOME.
#include <gtest/gtest.h>

#include <fstream>

#include "cli_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

using test::ddhgs;
using test::kQuickTrain;
using test::kTinyScene;
using test::lines;
using test::snapshot;
using test::tiny_scene;

TEST(OutputSafety, ForceNeverReplacesAFolderDdhgsDidNotWrite) {
  const fs::path dir = test::temp_dir("safety_foreign");
  const fs::path mine = dir / "mine";
  fs::create_directories(mine / "sub");
  std::ofstream(mine / "thesis.tex") << "years of work";
  std::ofstream(mine / "sub" / "data.csv") << "1,2,3";
  const auto before = snapshot(mine);
  std::string out;
  for (const std::string& command :
       {"-q synth --preset demo --force --out " + mine.string(),
        "-q train " + tiny_scene().string() + " --force --out " + mine.string() + kQuickTrain}) {
    EXPECT_EQ(ddhgs(command, &out), 1) << command << "\n" << out;
    EXPECT_NE(out.find("did not write"), std::string::npos) << out;
    EXPECT_EQ(lines(out), 1u) << out;
    EXPECT_EQ(snapshot(mine), before) << command;
  }
}

TEST(OutputSafety, AnInputIsNeverAnOutput) {
  const fs::path dir = test::temp_dir("safety_inputs");
  const fs::path data = dir / "data";
  std::string out;
  ASSERT_EQ(ddhgs("-q" + kTinyScene + " --out " + data.string(), &out), 0) << out;
  const auto before = snapshot(data);
  // The dataset as the run folder (it is a ddhgs scene, so the kind differs
  // too), a folder holding it, and process writing over its own cubes.
  for (const std::string& command :
       {"train " + data.string() + " --force --out " + data.string() + kQuickTrain,
        "train " + data.string() + " --force --out " + dir.string() + kQuickTrain,
        "process " + (data / "hyperspectral").string() + " --force --skip-colmap --poses " +
            (data / "transforms.json").string() + " --wl-range 400:1000 --out " +
            (data / "hyperspectral").string()}) {
    EXPECT_EQ(ddhgs(command, &out), 1) << command << "\n" << out;
    EXPECT_NE(out.find("nothing was touched"), std::string::npos) << out;
    EXPECT_EQ(snapshot(data), before) << command;
  }
  EXPECT_FALSE(fs::exists(dir / "data.previous"));
}

TEST(OutputSafety, NeitherTheCurrentDirectoryNorHomeIsReplaced) {
  const fs::path dir = test::temp_dir("safety_cwd_home");
  std::string out;
  for (const char* name : {"here", "home"})
    ASSERT_EQ(ddhgs("-q" + kTinyScene + " --out " + (dir / name).string(), &out), 0) << out;
  const auto here = snapshot(dir / "here");
  const auto home = snapshot(dir / "home");
  EXPECT_EQ(test::run_command("cd " + (dir / "here").string() + " && " + test::ddhgs_binary() +
                                  kTinyScene + " --force --out .",
                              &out),
            1)
      << out;
  EXPECT_NE(out.find("is the current directory"), std::string::npos) << out;
  EXPECT_EQ(test::run_command("HOME=" + (dir / "home").string() + " " + test::ddhgs_binary() +
                                  kTinyScene + " --force --out " + (dir / "home").string(),
                              &out),
            1)
      << out;
  EXPECT_NE(out.find("is your home folder"), std::string::npos) << out;
  EXPECT_EQ(snapshot(dir / "here"), here);
  EXPECT_EQ(snapshot(dir / "home"), home);
}

TEST(OutputSafety, ASecondWriterOfARunFolderIsRefused) {
  const fs::path dir = test::temp_dir("safety_lock");
  const fs::path run = dir / "run";
  std::string out;
  // The first train holds the run folder; the second, started while it
  // runs, must neither replace it nor mix its config into it. The first runs
  // long enough (seconds) to be still running when the second has loaded
  // its scene.
  const std::string first = test::ddhgs_binary() + " -q train " + tiny_scene().string() +
                            " --out " + run.string() + " --preset demo --iterations 1500 --seed 1";
  const std::string second = test::ddhgs_binary() + " train " + tiny_scene().string() + " --out " +
                             run.string() + " --force --preset demo --iterations 20 --seed 2";
  const int rc = test::run_command(
      "(" + first + " > " + (dir / "first.log").string() + " 2>&1; echo $? > " +
          (dir / "first.rc").string() + ") & " + "for i in $(seq 600); do grep -qs train " +
          (run / ".ddhgs-lock").string() + " && break; sleep 0.05; done; " + second +
          " 2>&1; echo \"second rc $?\"; wait",
      &out);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("in use by ddhgs train (pid"), std::string::npos) << out;
  EXPECT_NE(out.find("second rc 1"), std::string::npos) << out;
  EXPECT_EQ(io::read_file(dir / "first.rc"), "0\n") << io::read_file(dir / "first.log");
  const std::string config = io::read_file(run / "config.json");
  EXPECT_NE(config.find("\"seed\": 1"), std::string::npos);
  EXPECT_TRUE(fs::exists(run / "gaussians.ply"));
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
}

TEST(OutputSafety, SigtermSavesACheckpointLikeCtrlC) {
  const fs::path dir = test::temp_dir("safety_sigterm");
  const fs::path run = dir / "run";
  std::string out;
  const std::string train = test::ddhgs_binary() + " -q train " + tiny_scene().string() +
                            " --out " + run.string() + " --preset demo --iterations 100000";
  // Wait for some logged iterations, then stop it as a batch scheduler would.
  const int rc = test::run_command(
      train + " & pid=$!; for i in $(seq 1200); do [ $(wc -l < " +
          (run / "metrics.jsonl").string() +
          " 2>/dev/null || echo 0) -ge 3 ] && break; sleep 0.05; done; kill -TERM $pid; wait $pid; "
          "echo \"rc $?\"",
      &out);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("rc 143"), std::string::npos) << out;
  ASSERT_TRUE(fs::exists(run / "checkpoint.pt")) << out;
  EXPECT_EQ(ddhgs("-q train --resume " + run.string() + " --iterations 40", &out), 0) << out;
  EXPECT_TRUE(fs::exists(run / "gaussians.ply"));
}

}  // namespace
}  // namespace ddhgs
