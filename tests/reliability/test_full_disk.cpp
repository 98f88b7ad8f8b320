// A full disk, without filling one: the full_disk_shim preloaded
// into ddhgs makes writes below one temporary folder fail with ENOSPC, as a
// filesystem out of space does. Each case was first seen failing: the
// checkpoint write ended the process through std::terminate (exit 134, a
// LibTorch stack trace, a 5 MB temporary left behind).
#include <gtest/gtest.h>

#include "cli_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

using test::ddhgs;
using test::error_lines;
using test::temporaries;
using test::tiny_scene;

// ddhgs ARGS with the disk "full" below dir: nothing fits when match is
// empty, else only files whose name contains match fail.
int ddhgs_on_full_disk(const fs::path& dir, const std::string& match, const std::string& args,
                       std::string* out) {
  return test::run_command(
      "DDHGS_FULL_DISK_DIR=" + dir.string() + " DDHGS_FULL_DISK_MATCH=" + match +
          " LD_PRELOAD=" DDHGS_FULL_DISK_SHIM " " + test::ddhgs_binary() + " " + args,
      out);
}

// One "error:" line naming the file and the cause; no crash, no trace.
void expect_full_disk_error(const std::string& out, const std::string& file) {
  const auto errors = error_lines(out);
  ASSERT_EQ(errors.size(), 1u) << out;
  EXPECT_NE(errors[0].find(file), std::string::npos) << out;
  EXPECT_NE(errors[0].find("no space left on device"), std::string::npos) << out;
  EXPECT_EQ(out.find("terminate"), std::string::npos) << out;
  EXPECT_EQ(out.find("frame #"), std::string::npos) << out;
}

// A finished 20-iteration run with checkpoints at 10 and 20.
fs::path trained_run(const std::string& name) {
  const fs::path run = test::temp_dir(name) / "run";
  std::string out;
  EXPECT_EQ(ddhgs("-q train " + tiny_scene().string() + " --out " + run.string() +
                      " --preset demo --iterations 20 --checkpoint-every 10",
                  &out),
            0)
      << out;
  return run;
}

TEST(FullDisk, ACheckpointThatDoesNotFitEndsCleanlyAndKeepsThePreviousOne) {
  const fs::path run = trained_run("full_disk_checkpoint");
  const std::string before = io::read_file(run / "checkpoint.pt");
  std::string out;
  EXPECT_EQ(ddhgs_on_full_disk(run, "checkpoint",
                               "-q train --resume " + run.string() + " --iterations 40", &out),
            1)
      << out;
  expect_full_disk_error(out, (run / "checkpoint.pt").string());
  EXPECT_TRUE(temporaries(run).empty()) << out;
  EXPECT_EQ(io::read_file(run / "checkpoint.pt"), before);
  // Space again: the run continues from the checkpoint that was kept.
  EXPECT_EQ(ddhgs("-q train --resume " + run.string() + " --iterations 40", &out), 0) << out;
}

// A resume that fails before its first new checkpoint leaves config.json
// (which --iterations rewrote) and metrics.jsonl (which logged the lost
// iterations) as they were: the run is the one its checkpoint holds.
TEST(FullDisk, AFailedResumeLeavesConfigAndMetricsAsTheyWere) {
  const fs::path run = trained_run("full_disk_resume_config");
  const std::string config = io::read_file(run / "config.json");
  const std::string metrics = io::read_file(run / "metrics.jsonl");
  std::string out;
  EXPECT_EQ(ddhgs_on_full_disk(run, "checkpoint",
                               "-q train --resume " + run.string() + " --iterations 40", &out),
            1)
      << out;
  EXPECT_EQ(io::read_file(run / "config.json"), config);
  EXPECT_EQ(io::read_file(run / "metrics.jsonl"), metrics);
}

// export and render on a full disk: one error line, and no empty export/ or
// renders/ folder left in the run.
TEST(FullDisk, ExportAndRenderLeaveNoEmptyFolder) {
  const fs::path run = trained_run("full_disk_folders");
  for (const auto& [command, folder] :
       {std::pair<std::string, std::string>{"export", "export"}, {"render", "renders"}}) {
    std::string out;
    EXPECT_EQ(ddhgs_on_full_disk(run, "", "-q " + command + " " + run.string(), &out), 1) << out;
    EXPECT_EQ(error_lines(out).size(), 1u) << out;
    EXPECT_FALSE(fs::exists(run / folder)) << command << "\n" << out;
  }
}

// The run's files; its lock file names whoever locked it last.
std::vector<std::pair<std::string, std::string>> run_files(const fs::path& run) {
  auto files = test::snapshot(run);
  files.erase(std::remove_if(files.begin(), files.end(),
                             [](const auto& file) { return file.first == ".ddhgs-lock"; }),
              files.end());
  return files;
}

TEST(FullDisk, ResumingOnAFullDiskChangesNothing) {
  const fs::path run = trained_run("full_disk_resume");
  const auto before = run_files(run);
  std::string out;
  EXPECT_EQ(
      ddhgs_on_full_disk(run, "", "-q train --resume " + run.string() + " --iterations 40", &out),
      1)
      << out;
  expect_full_disk_error(out, run.string());
  EXPECT_TRUE(temporaries(run).empty()) << out;
  EXPECT_EQ(run_files(run), before);
}

TEST(FullDisk, ANewRunOnAFullDiskLeavesNothing) {
  const fs::path dir = test::temp_dir("full_disk_new");
  std::string out;
  EXPECT_EQ(ddhgs_on_full_disk(dir, "",
                               "-q train " + tiny_scene().string() + " --out " +
                                   (dir / "run").string() + test::kQuickTrain,
                               &out),
            1)
      << out;
  expect_full_disk_error(out, (dir / "run").string());
  EXPECT_TRUE(fs::is_empty(dir)) << out;
}

TEST(FullDisk, TheFinalModelThatDoesNotFitKeepsTheRunResumable) {
  const fs::path dir = test::temp_dir("full_disk_ply");
  const fs::path run = dir / "run";
  std::string out;
  EXPECT_EQ(
      ddhgs_on_full_disk(
          dir, "gaussians.ply",
          "-q train " + tiny_scene().string() + " --out " + run.string() + test::kQuickTrain, &out),
      1)
      << out;
  expect_full_disk_error(out, (run / "gaussians.ply").string());
  EXPECT_TRUE(temporaries(run).empty()) << out;
  EXPECT_TRUE(fs::exists(run / "checkpoint.pt"));
  EXPECT_EQ(ddhgs("-q train --resume " + run.string(), &out), 0) << out;
  EXPECT_TRUE(fs::exists(run / "gaussians.ply"));
}

TEST(FullDisk, EvalOutputsAppearTogetherOrNotAtAll) {
  const fs::path run = trained_run("full_disk_eval");
  std::string out;
  ASSERT_EQ(ddhgs("-q eval " + run.string(), &out), 0) << out;
  const auto before = test::snapshot(run / "eval");
  EXPECT_EQ(ddhgs_on_full_disk(run, "per_view", "-q eval " + run.string(), &out), 1) << out;
  expect_full_disk_error(out, "per_view");
  EXPECT_EQ(test::snapshot(run / "eval"), before);
  EXPECT_TRUE(temporaries(run).empty()) << out;
}

}  // namespace
}  // namespace ddhgs
