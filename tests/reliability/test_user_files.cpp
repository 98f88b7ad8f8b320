// Six checks of a user's own files, as a user would meet them: nothing a user put in or
// beside a ddhgs output is lost, links are not followed, and a mistyped
// --downscale is named. Each works inside its own temporary folder.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

using test::ddhgs;
using test::error_lines;
using test::kQuickTrain;
using test::tiny_scene;

// A run trained on the tiny scene.
fs::path trained_run(const fs::path& dir) {
  const fs::path run = dir / "run";
  std::string out;
  if (ddhgs("-q train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain, &out) !=
      0)
    throw std::runtime_error(out);
  return run;
}

// Exit 1 and one error line holding every piece of `expected`.
void expect_one_error(const std::string& args, const std::vector<std::string>& expected) {
  std::string out;
  EXPECT_EQ(ddhgs(args, &out), 1) << args << "\n" << out;
  const auto errors = error_lines(out);
  ASSERT_EQ(errors.size(), 1u) << out;
  for (const auto& piece : expected) EXPECT_NE(errors[0].find(piece), std::string::npos) << out;
}

TEST(UserFiles, AUsersFileInARunSurvivesTrainForce) {
  const fs::path dir = test::temp_dir("user_files_notes");
  const fs::path run = trained_run(dir);
  io::write_file_atomically(run / "notes.txt", "what I changed\n");
  expect_one_error(
      "-q train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain + " --force",
      {"notes.txt", "did not write", "nothing was touched"});
  EXPECT_EQ(io::read_file(run / "notes.txt"), "what I changed\n");
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
  // Moved out, the run is replaced as asked.
  fs::remove(run / "notes.txt");
  std::string out;
  EXPECT_EQ(ddhgs("-q train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain +
                      " --force",
                  &out),
            0)
      << out;
}

// A scene whose transforms.json names cubes inside the run being replaced.
TEST(UserFiles, ADatasetsCubesInsideOutSurviveWithoutAMove) {
  const fs::path dir = test::temp_dir("user_files_cubes");
  const fs::path run = trained_run(dir);
  fs::copy(tiny_scene() / "hyperspectral", run / "cubes", fs::copy_options::recursive);
  const fs::path scene = dir / "scene";
  fs::create_directories(scene);
  nlohmann::json transforms =
      nlohmann::json::parse(io::read_file(tiny_scene() / "transforms.json"));
  for (auto& frame : transforms["frames"]) {
    const std::string name =
        fs::path(frame["hyperspectral_file_path"].get<std::string>()).filename();
    frame["hyperspectral_file_path"] = (run / "cubes" / name).string();
  }
  transforms.erase("train_filenames");
  transforms.erase("test_filenames");
  io::write_file_atomically(scene / "transforms.json", transforms.dump(2));
  const auto before = test::snapshot(run / "cubes");
  expect_one_error(
      "-q train " + scene.string() + " --out " + run.string() + kQuickTrain + " --force",
      {run.string(), "cubes"});
  EXPECT_EQ(test::snapshot(run / "cubes"), before);
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
}

TEST(UserFiles, APresetInsideOutSurvives) {
  const fs::path dir = test::temp_dir("user_files_preset");
  const fs::path run = trained_run(dir);
  io::write_file_atomically(run / "mine.json",
                            io::read_file(test::source_dir() / "configs" / "demo.json"));
  expect_one_error("-q train " + tiny_scene().string() + " --out " + run.string() + " --preset " +
                       (run / "mine.json").string() +
                       " --iterations 20 --checkpoint-every 0 --force",
                   {"mine.json"});
  EXPECT_TRUE(fs::exists(run / "mine.json"));
}

TEST(UserFiles, AFileNamedLikeATemporaryBesideANewOutputSurvives) {
  const fs::path dir = test::temp_dir("user_files_tmp_name");
  io::write_file_atomically(dir / ".notes.tmp-999999-1", "mine");
  std::string out;
  ASSERT_EQ(ddhgs("-q" + test::kTinyScene + " --out " + (dir / "scene").string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(dir / ".notes.tmp-999999-1"), "mine");
  EXPECT_NE(out.find("left alone"), std::string::npos) << out;
}

TEST(UserFiles, ALockLinkedToAUsersFileLeavesItUnchangedAfterEval) {
  const fs::path dir = test::temp_dir("user_files_lock");
  const fs::path run = trained_run(dir);
  io::write_file_atomically(dir / "victim.txt", "someone else's\n");
  fs::remove(run / ".ddhgs-lock");
  fs::create_symlink(dir / "victim.txt", run / ".ddhgs-lock");
  expect_one_error("-q eval " + run.string(), {".ddhgs-lock", "symbolic link"});
  EXPECT_EQ(io::read_file(dir / "victim.txt"), "someone else's\n");
}

TEST(UserFiles, ADownscaleOf1000IsNamed) {
  const fs::path dir = test::temp_dir("user_files_downscale");
  std::string out;
  expect_one_error("-q train " + tiny_scene().string() + " --out " + (dir / "run").string() +
                       " --downscale 1000",
                   {"--downscale 1000", "32 x 24 px", "no pixel"});
  EXPECT_FALSE(fs::exists(dir / "run"));
}

// `train --force` killed (kill -9) before its first checkpoint leaves
// RUN.previous, the earlier run, and an unstarted RUN. The next train brings
// the earlier run back before anything else: refused without --force (the
// earlier run is whole again), replaced with it.
TEST(UserFiles, ARunKilledWhileReplacingAnotherGivesTheEarlierOneBack) {
  const fs::path dir = test::temp_dir("user_files_killed_force");
  const fs::path run = trained_run(dir);
  const std::string earlier = io::read_file(run / "gaussians.ply");
  std::string out;
  // Killed 4 s in: past the scene's loading, long before its first checkpoint.
  test::run_command("timeout -s KILL 4 " + test::ddhgs_binary() + " -q train " +
                        tiny_scene().string() + " --out " + run.string() +
                        " --preset demo --iterations 1000000 --checkpoint-every 1000000 --force",
                    &out);
  ASSERT_TRUE(fs::exists(dir / "run.previous")) << out;
  ASSERT_FALSE(fs::exists(run / "gaussians.ply")) << out;

  expect_one_error("-q train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain,
                   {run.string(), "--force"});
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
  EXPECT_EQ(io::read_file(run / "gaussians.ply"), earlier);

  // Killed again, then replaced: the new run finishes and nothing is left aside.
  test::run_command("timeout -s KILL 4 " + test::ddhgs_binary() + " -q train " +
                        tiny_scene().string() + " --out " + run.string() +
                        " --preset demo --iterations 1000000 --checkpoint-every 1000000 --force",
                    &out);
  ASSERT_TRUE(fs::exists(dir / "run.previous")) << out;
  ASSERT_EQ(ddhgs("train " + tiny_scene().string() + " --out " + run.string() + kQuickTrain +
                      " --force --seed 7",
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("is back from"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
  EXPECT_NE(io::read_file(run / "gaussians.ply"), earlier);
}

}  // namespace
}  // namespace ddhgs
