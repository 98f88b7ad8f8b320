// Schedules as fractions of the run's length: iteration numbers they give,
// and configs of format_version 1 (iteration numbers) read back to the same
// schedule.
#include <gtest/gtest.h>

#include <fstream>

#include "support/test_support.h"
#include "train/config.h"
#include "train/run_folder.h"
#include "train/schedule.h"

using namespace ddhgs;
using nlohmann::json;

namespace {

// What demo.json said in iteration numbers before fractions (format_version 1).
const json kDemoV1 = {
    {"model", {{"sh_degree_every", 300}}},
    {"optim", {{"means_lr_max_steps", 3000}}},
    {"densify", {{"from_iter", 200}, {"until_iter", 2000}, {"opacity_reset_every", 1000}}}};

}  // namespace

TEST(Schedule, FractionsBecomeIterationNumbersOfTheRun) {
  json c = train::load_preset("demo");
  ASSERT_EQ(c["iterations"], 3000);
  train::Schedule s = train::schedule_from_config(c);
  // The demo preset keeps the iteration numbers it had before fractions.
  EXPECT_EQ(s.sh_degree_every, 300);
  EXPECT_EQ(s.means_lr_decay_steps, 3000);
  EXPECT_EQ(s.densify_from, 200);
  EXPECT_EQ(s.densify_until, 2000);
  EXPECT_EQ(s.densify_every, 100);
  EXPECT_EQ(s.opacity_reset_every, 1000);
  // ... and scales with the run: 2/3 of 900 is 600, 1/15 of 900 is 60.
  c["iterations"] = 900;
  s = train::schedule_from_config(c);
  EXPECT_EQ(s.densify_until, 600);
  EXPECT_EQ(s.densify_from, 60);
  EXPECT_EQ(s.opacity_reset_every, 300);
  EXPECT_EQ(s.sh_degree_every, 90);
  EXPECT_TRUE(s.densifies(599));
  EXPECT_FALSE(s.densifies(600));
  // An interval that rounds to 0 still happens every iteration; a zero
  // fraction switches it off.
  c["iterations"] = 4;
  c["model"]["sh_degree_every_fraction"] = 0.1;
  c["densify"]["opacity_reset_every_fraction"] = 0.0;
  s = train::schedule_from_config(c);
  EXPECT_EQ(s.sh_degree_every, 1);
  EXPECT_EQ(s.opacity_reset_every, 0);
}

TEST(Schedule, IterationNumbersOfFormatVersion1BecomeTheSameFractions) {
  json old = kDemoV1;
  ASSERT_TRUE(train::upgrade_absolute_schedule(old, 3000));
  const json demo = train::load_preset("demo");
  for (const auto& [section, keys] : old.items())
    for (const auto& [key, value] : keys.items())
      EXPECT_EQ(value, demo[section][key]) << section << "." << key;
  EXPECT_FALSE(old["densify"].contains("until_iter"));
  json none = {{"densify", {{"every", 100}}}};
  EXPECT_FALSE(train::upgrade_absolute_schedule(none, 3000));
}

TEST(Schedule, OlderRunFoldersAndPresetsKeepTheirIterationNumbers) {
  // A run folder of format_version 1 trained for 1000 iterations with the
  // demo schedule in iteration numbers: read back, it has the same schedule.
  json c = train::load_preset("demo");
  for (const char* section : {"model", "optim", "densify"})
    for (const auto& [key, value] : kDemoV1[section].items()) c[section][key] = value;
  c["model"].erase("sh_degree_every_fraction");
  c["optim"].erase("means_lr_decay_fraction");
  for (const char* key : {"from_fraction", "until_fraction", "opacity_reset_every_fraction"})
    c["densify"].erase(key);
  c["format_version"] = 1;
  c["iterations"] = 1000;
  const auto dir = test::temp_dir("schedule_v1_run");
  std::ofstream(dir / "config.json") << c.dump(2);
  const json read = train::read_run_config({dir});
  EXPECT_EQ(read["format_version"], train::kConfigFormatVersion);
  const train::Schedule s = train::schedule_from_config(read);
  EXPECT_EQ(s.densify_from, 200);
  EXPECT_EQ(s.densify_until, 2000);  // beyond the run: densifies to the end, as before
  EXPECT_EQ(s.opacity_reset_every, 1000);
  EXPECT_EQ(s.sh_degree_every, 300);
  EXPECT_EQ(s.means_lr_decay_steps, 3000);

  // A preset file of format_version 1 that extends demo: its iteration
  // numbers refer to the 3000 iterations it inherits.
  std::ofstream(dir / "old.json") << R"({"format_version": 1, "extends": "demo",
                                         "densify": {"until_iter": 1500}})";
  const train::Schedule p =
      train::schedule_from_config(train::load_preset((dir / "old.json").string()));
  EXPECT_EQ(p.densify_until, 1500);
  EXPECT_EQ(p.densify_from, 200);
}
