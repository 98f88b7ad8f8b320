// scripts/prior_corpus.sh: a corpus of varied synthetic scenes, each trained
// on a short schedule, listed in a manifest; resumable.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <set>

#include "io/scene/scene.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

std::string corpus_command(const fs::path& out, const std::string& count) {
  return test::prior_corpus_command(out, count, 6, 20);
}

size_t count_of(const std::string& text, const std::string& word) {
  size_t found = 0;
  for (size_t at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) ++found;
  return found;
}

TEST(CorpusScript, TwoVariedEntriesWithHeldOutCleanTruthThenARerunSkipsThem) {
  const fs::path root = test::temp_dir("corpus_script");
  const fs::path out = root / "corpus";
  std::string log;
  ASSERT_EQ(test::run_command(corpus_command(out, "2"), &log), 0) << log;
  const json manifest = test::read_json(out / "manifest.json");
  ASSERT_EQ(manifest["entries"].size(), 2u) << manifest.dump(1);
  std::set<std::string> folders, presets;
  for (const json& entry : manifest["entries"]) {
    const fs::path scene = out / entry["scene"].get<std::string>();
    const fs::path run = out / entry["run"].get<std::string>();
    folders.insert(scene.string());
    folders.insert(run.string());
    presets.insert(entry["preset"].get<std::string>());
    ASSERT_TRUE(fs::exists(run / "train_summary.json")) << run;
    EXPECT_EQ(test::read_json(run / "config.json")["iterations"], 20) << run;
    const json synth = test::read_json(scene / "synth.json");
    EXPECT_TRUE(synth.contains("variant")) << scene;
    EXPECT_EQ(synth["bands"], entry["bands"]);
    EXPECT_EQ(synth["views"], entry["views"]);
    EXPECT_EQ(synth["width"], entry["width"]);
    // The held-out views the scene lists are its split, each with clean truth.
    const auto loaded = io::load_scene(scene);
    const int held_out = entry["test_views"].get<int>();
    EXPECT_GE(held_out, 2);
    EXPECT_EQ(int(loaded->test.size()), held_out) << scene;
    EXPECT_EQ(int(loaded->train.size()), entry["train_views"].get<int>()) << scene;
    const json transforms = test::read_json(scene / "transforms.json");
    for (const json& name : transforms["test_filenames"]) {
      const std::string stem = fs::path(name.get<std::string>()).stem().string();
      EXPECT_TRUE(fs::exists(scene / "clean" / (stem + ".npy"))) << name;
    }
  }
  EXPECT_EQ(folders.size(), 4u);
  EXPECT_EQ(presets, (std::set<std::string>{"demo", "bayspec"}));

  // A rerun skips both; a run left half made is made again, alone.
  const fs::path first = out / "runs/000/train_summary.json";
  const fs::path second = out / "runs/001/train_summary.json";
  const auto first_time = fs::last_write_time(first);
  const auto first_scene = fs::last_write_time(out / "scenes/000/transforms.json");
  const auto second_time = fs::last_write_time(second);
  ASSERT_EQ(test::run_command(corpus_command(out, "2"), &log), 0) << log;
  EXPECT_EQ(count_of(log, "done before, skipped"), 2u) << log;
  EXPECT_EQ(fs::last_write_time(first), first_time);
  EXPECT_EQ(fs::last_write_time(second), second_time);
  EXPECT_EQ(fs::last_write_time(out / "scenes/000/transforms.json"), first_scene);
  fs::remove(second);
  ASSERT_EQ(test::run_command(corpus_command(out, "2"), &log), 0) << log;
  EXPECT_EQ(count_of(log, "done before, skipped"), 1u) << log;
  EXPECT_TRUE(fs::exists(second));
  EXPECT_EQ(fs::last_write_time(first), first_time);
  EXPECT_EQ(test::read_json(out / "manifest.json")["entries"].size(), 2u);

  EXPECT_EQ(test::run_command(corpus_command(root / "other", "two"), &log), 2) << log;
  EXPECT_NE(log.find("usage: prior_corpus.sh OUT COUNT"), std::string::npos) << log;
}

}  // namespace
}  // namespace ddhgs
