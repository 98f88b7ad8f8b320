// The program away from its source tree: a binary copied into an empty
// folder trains with the presets built into it; `cmake --install` lays out
// the program and its presets where it finds them; an unknown preset names
// every place looked in; --version names the commit the program was built
// from (cmake/version.cmake).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "io/files/atomic_file.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

// `PROGRAM ARGS` without $DDHGS_CONFIG_DIR, so only the program's own places count.
int run(const fs::path& program, const std::string& args, std::string* out) {
  return test::run_command("env -u DDHGS_CONFIG_DIR " + program.string() + " " + args, out);
}

// A tiny scene written by `program`, then `program train` on it; the run's config.json.
json train_tiny(const fs::path& program, const fs::path& dir, const std::string& train_args) {
  std::string out;
  EXPECT_EQ(run(program,
                "-q synth --preset demo --width 32 --height 24 --bands 3 --views 10 --out " +
                    (dir / "scene").string(),
                &out),
            0)
      << out;
  EXPECT_EQ(run(program,
                "-q train " + (dir / "scene").string() + " --out " + (dir / "run").string() +
                    " --checkpoint-every 0 " + train_args,
                &out),
            0)
      << out;
  return json::parse(io::read_file(dir / "run" / "config.json"));
}

// The places a program in `dir` looks for presets (train/preset_lookup.h).
std::vector<fs::path> preset_places(const fs::path& dir) {
  return {dir / "configs", (dir / ".." / "share" / "ddhgs" / "configs").lexically_normal(),
          (dir / ".." / "configs").lexically_normal()};
}

TEST(InstallCli, ACopiedBinaryTrainsWithItsBuiltInPresets) {
  const fs::path dir = test::temp_dir("install_copy");
  const fs::path program = dir / "ddhgs";
  fs::copy_file(test::ddhgs_binary(), program);
  for (const fs::path& place : preset_places(dir)) ASSERT_FALSE(fs::exists(place)) << place;

  const json config = train_tiny(program, dir, "--preset demo --iterations 5");
  EXPECT_EQ(config["iterations"], 5);
  // The built-in demo preset, as configs/demo.json sets it, over default.json.
  const json demo = json::parse(io::read_file(test::source_dir() / "configs" / "demo.json"));
  for (const auto& [key, value] : demo["model"].items())
    EXPECT_EQ(config["model"][key], value) << "model." << key;
}

TEST(InstallCli, AnUnknownPresetNamesEveryPlaceLookedIn) {
  const fs::path dir = test::temp_dir("install_unknown");
  const fs::path program = dir / "ddhgs";
  fs::copy_file(test::ddhgs_binary(), program);
  std::string out;
  ASSERT_EQ(test::run_command("DDHGS_CONFIG_DIR=" + (dir / "mine").string() + " " +
                                  program.string() + " train " + dir.string() + " --out " +
                                  (dir / "run").string() + " --preset no-such-thing",
                              &out),
            1)
      << out;
  EXPECT_NE(out.find("no such preset 'no-such-thing'"), std::string::npos) << out;
  EXPECT_NE(out.find((dir / "mine").string() + ", "), std::string::npos) << out;
  for (const fs::path& place : preset_places(dir))
    EXPECT_NE(out.find(place.string() + ", "), std::string::npos) << place << "\n" << out;
  EXPECT_NE(out.find("built into ddhgs (ablation, default, demo, paper)"), std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(dir / "run"));
}

TEST(InstallCli, AnInstalledProgramReadsThePresetsInstalledBesideIt) {
  const fs::path prefix = test::temp_dir("install_prefix") / "prefix";
  const fs::path build = fs::path(test::ddhgs_binary()).parent_path();
  std::string out;
  ASSERT_EQ(
      test::run_command("cmake --install " + build.string() + " --prefix " + prefix.string(), &out),
      0)
      << out;
  const fs::path program = prefix / "bin" / "ddhgs";
  const fs::path presets = prefix / "share" / "ddhgs" / "configs";
  ASSERT_TRUE(fs::exists(program)) << out;
  for (const char* name : {"default", "demo", "paper", "ablation"})
    EXPECT_EQ(io::read_file(presets / (std::string(name) + ".json")),
              io::read_file(test::source_dir() / "configs" / (std::string(name) + ".json")))
        << name;
  // An installed preset edited by its user wins over the built-in one.
  json demo = json::parse(io::read_file(presets / "demo.json"));
  demo["iterations"] = 4;
  io::write_file_atomically(presets / "demo.json", demo.dump(2));
  const json config = train_tiny(program, prefix.parent_path(), "--preset demo");
  EXPECT_EQ(config["iterations"], 4);
}

TEST(InstallCli, VersionNamesTheCommitBuiltFrom) {
  std::string out;
  ASSERT_EQ(run(test::ddhgs_binary(), "--version", &out), 0) << out;
  EXPECT_EQ(out.rfind("ddhgs ", 0), 0u) << out;
  // The source tree's commit, or "unknown" where it is not a git checkout
  // (the same test as cmake/version.cmake's).
  std::string top, head;
  const std::string git = "git -C " + test::source_dir().string();
  if (test::run_command(git + " rev-parse --show-toplevel", &top) == 0 &&
      fs::equivalent(top.substr(0, top.find('\n')), test::source_dir()) &&
      test::run_command(git + " rev-parse --short=12 HEAD", &head) == 0)
    EXPECT_NE(out.find("commit " + head.substr(0, head.find('\n'))), std::string::npos) << out;
  else
    EXPECT_NE(out.find("commit unknown"), std::string::npos) << out;
}

// cmake/version.cmake on its own: a git checkout's commit (and "-dirty" once
// a tracked file changes), "unknown" in a folder that is not one.
TEST(InstallCli, TheVersionScriptNamesTheCheckoutsCommit) {
  const fs::path dir = test::temp_dir("install_version");
  const fs::path checkout = dir / "checkout";
  fs::create_directories(checkout);
  io::write_file_atomically(checkout / "file.txt", "one\n");
  const std::string git = "git -C " + checkout.string() + " ";
  std::string out, head;
  ASSERT_EQ(test::run_command(git + "init -q && " + git + "add file.txt && " + git +
                                  "-c user.name=t -c user.email=t@example.org commit -q -m one",
                              &out),
            0)
      << out;
  ASSERT_EQ(test::run_command(git + "rev-parse --short=12 HEAD", &head), 0) << head;
  head = head.substr(0, head.find('\n'));
  auto generated = [&](const fs::path& source) {
    const fs::path file = dir / "build_info.cpp";
    fs::remove(file);
    std::string log;
    EXPECT_EQ(test::run_command("cmake -DSOURCE_DIR=" + source.string() +
                                    " -DGIT=git -DOUT=" + file.string() + " -P " +
                                    (test::source_dir() / "cmake" / "version.cmake").string(),
                                &log),
              0)
        << log;
    return io::read_file(file);
  };
  std::string text = generated(checkout);
  EXPECT_NE(text.find("return \"" + head + "\";"), std::string::npos) << text;
  io::write_file_atomically(checkout / "file.txt", "two\n");
  text = generated(checkout);
  EXPECT_NE(text.find("return \"" + head + "-dirty\";"), std::string::npos) << text;
  // A folder inside the checkout is not a checkout of its own.
  fs::create_directories(checkout / "inner");
  text = generated(checkout / "inner");
  EXPECT_NE(text.find("return \"unknown\";"), std::string::npos) << text;
  text = generated(dir);
  EXPECT_NE(text.find("return \"unknown\";"), std::string::npos) << text;
}

}  // namespace
}  // namespace ddhgs
