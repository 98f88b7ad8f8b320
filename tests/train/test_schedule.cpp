// Schedules as fractions of the run's length: the iteration numbers they
// give; configs of format_version 1 (iteration numbers) are refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "support/error_text.h"
#include "support/test_support.h"
#include "train/config.h"
#include "train/run_config.h"
#include "train/run_folder.h"
#include "train/schedule.h"

using namespace ddhgs;
using nlohmann::json;

TEST(Schedule, BandPerViewFlightsTrainPerTrainingViewNeverLonger) {
  const json c = train::load_preset("default");
  train::RunConfig config = train::parse_run_config(c, "test");
  ASSERT_EQ(config.iterations, 30000);
  ASSERT_EQ(config.optim.iterations_per_band_view, 100);
  // A scene whose views hold every band keeps the preset's length.
  EXPECT_EQ(train::run_iterations(config, false, 35), 30000);
  // An 8-capture x 5-band strip less its held-out capture: 35 band images.
  EXPECT_EQ(train::run_iterations(config, true, 35), 3500);
  // Never longer than `iterations`: 400 band images would ask for 40,000.
  EXPECT_EQ(train::run_iterations(config, true, 400), 30000);
  config.iterations = 2000;
  EXPECT_EQ(train::run_iterations(config, true, 35), 2000);
  // 0 switches the limit off.
  config.optim.iterations_per_band_view = 0;
  config.iterations = 30000;
  EXPECT_EQ(train::run_iterations(config, true, 35), 30000);
}

TEST(Schedule, FractionsBecomeIterationNumbersOfTheRun) {
  json c = train::load_preset("demo");
  ASSERT_EQ(c["iterations"], 3000);
  train::Schedule s = train::schedule_of(train::parse_run_config(c, "test"));
  // The demo preset keeps the iteration numbers it had before fractions.
  EXPECT_EQ(s.sh_degree_every, 300);
  EXPECT_EQ(s.means_lr_decay_steps, 3000);
  EXPECT_EQ(s.densify_from, 200);
  EXPECT_EQ(s.densify_until, 2000);
  EXPECT_EQ(s.densify_every, 100);
  EXPECT_EQ(s.opacity_reset_every, 1000);
  // ... and scales with the run: 2/3 of 900 is 600, 1/15 of 900 is 60.
  c["iterations"] = 900;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_EQ(s.densify_until, 600);
  EXPECT_EQ(s.densify_from, 60);
  EXPECT_EQ(s.opacity_reset_every, 300);
  EXPECT_EQ(s.sh_degree_every, 90);
  EXPECT_TRUE(s.densifies(599));
  EXPECT_FALSE(s.densifies(600));
  // loss.bands_per_step draws bands for the first two thirds, 600 included.
  EXPECT_EQ(s.bands_drawn_until, 600);
  EXPECT_TRUE(s.draws_bands(600));
  EXPECT_FALSE(s.draws_bands(601));
  // The rates other than the positions' fall in the last tenth.
  EXPECT_EQ(s.lr_decay_from, 810);
  // Only a rig run's warm-up trains on the reference camera's views alone:
  // its first fifth; only a rig run aligns its band cameras.
  EXPECT_EQ(s.reference_views_until, 0);
  EXPECT_FALSE(s.reference_views_only(1));
  EXPECT_EQ(s.rig_align_until, 0);
  c["camera_refinement"]["rig"] = true;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_EQ(s.reference_views_until, 180);
  EXPECT_TRUE(s.reference_views_only(180));
  EXPECT_FALSE(s.reference_views_only(181));
  // Then, asked to, the band cameras align for the next two fifths.
  EXPECT_EQ(s.rig_align_until, 0);
  c["camera_refinement"]["rig_align_fraction"] = 0.4;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_EQ(s.rig_align_until, 540);
  EXPECT_FALSE(s.aligns_rig(180));
  EXPECT_TRUE(s.aligns_rig(181));
  EXPECT_TRUE(s.aligns_rig(540));
  EXPECT_FALSE(s.aligns_rig(541));
  c["camera_refinement"]["rig_warmup_fraction"] = 0.0;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_FALSE(s.reference_views_only(1));
  EXPECT_TRUE(s.aligns_rig(1));
  EXPECT_EQ(s.rig_align_until, 360);
  c["camera_refinement"]["rig_align_fraction"] = 0.0;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_EQ(s.rig_align_until, 0);
  EXPECT_FALSE(s.aligns_rig(1));
  // An interval that rounds to 0 still happens every iteration; a zero
  // fraction switches it off.
  c["iterations"] = 4;
  c["model"]["sh_degree_every_fraction"] = 0.1;
  c["densify"]["opacity_reset_every_fraction"] = 0.0;
  s = train::schedule_of(train::parse_run_config(c, "test"));
  EXPECT_EQ(s.sh_degree_every, 1);
  EXPECT_EQ(s.opacity_reset_every, 0);
}

TEST(Schedule, PresetsInIterationNumbersOfFormatVersion1AreRefused) {
  const auto dir = test::temp_dir("schedule_v1_preset");
  std::ofstream(dir / "old.json") << R"({"format_version": 1, "extends": "demo",
                                         "densify": {"until_iter": 1500}})";
  const std::string error =
      test::error_of([&] { train::load_preset((dir / "old.json").string()); });
  EXPECT_NE(error.find("old.json"), std::string::npos) << error;
  EXPECT_NE(error.find("format_version 1; this ddhgs reads format_version 2"), std::string::npos)
      << error;
}

TEST(Schedule, EachSlotComesOnceAnEpochInAnOrderOfItsOwn) {
  const int64_t slots = 11;
  std::vector<int64_t> first, second;
  for (int64_t i = 1; i <= 2 * slots; ++i)
    (i <= slots ? first : second).push_back(train::epoch_slot(i, slots, 5));
  for (const auto* epoch : {&first, &second}) {
    std::vector<int64_t> sorted = *epoch;
    std::sort(sorted.begin(), sorted.end());
    for (int64_t s = 0; s < slots; ++s) EXPECT_EQ(sorted[size_t(s)], s);
  }
  EXPECT_NE(first, second);  // a fresh permutation each epoch
  EXPECT_NE(first, [&] {     // and another for another seed
    std::vector<int64_t> other;
    for (int64_t i = 1; i <= slots; ++i) other.push_back(train::epoch_slot(i, slots, 6));
    return other;
  }());
  // A block of 4 views in a flight of 11 renders on 4 steps of each epoch of 11.
  int rendered = 0;
  for (int64_t i = 1; i <= 3 * slots; ++i) rendered += train::epoch_slot(i, slots, 5) < 4;
  EXPECT_EQ(rendered, 3 * 4);
}
