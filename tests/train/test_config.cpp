#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "support/error_text.h"
#include "support/test_support.h"
#include "train/config.h"
#include "train/run_config.h"
#include "train/run_folder.h"

using namespace ddhgs;

namespace {

void write(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

using test::error_of;

}  // namespace

TEST(Config, PresetsResolveEveryKeyThroughExtends) {
  auto base = train::load_preset("default");
  auto paper = train::load_preset("paper");
  auto demo = train::load_preset("demo");
  EXPECT_EQ(base["iterations"], 30000);
  EXPECT_EQ(paper["iterations"], 60000);
  EXPECT_DOUBLE_EQ(paper["loss"]["l1"].get<double>(), 0.4);
  EXPECT_DOUBLE_EQ(paper["loss"]["dssim"].get<double>(), 0.2);
  // Keys the child does not set come from the parent.
  EXPECT_DOUBLE_EQ(paper["optim"]["sh_dc_lr"].get<double>(), 2.5e-3);
  EXPECT_DOUBLE_EQ(base["optim"]["adam_eps"].get<double>(), 1e-15);
  EXPECT_FALSE(paper.contains("extends"));
  EXPECT_LT(demo["iterations"].get<int>(), 30000);
  train::validate_config(demo, "demo");
}

TEST(Config, UnknownKeysAndWrongTypesNameTheFileAndKey) {
  auto dir = test::temp_dir("config_errors");
  write(dir / "typo.json",
        R"({"format_version": 2, "extends": "default", "densify": {"grad_treshold": 1}})");
  EXPECT_NE(error_of([&] {
              train::load_preset((dir / "typo.json").string());
            }).find("typo.json: unknown key 'densify.grad_treshold'"),
            std::string::npos);
  write(dir / "type.json", R"({"format_version": 2, "iterations": "many"})");
  EXPECT_NE(error_of([&] {
              train::load_preset((dir / "type.json").string());
            }).find("key 'iterations' must be an integer, got a string"),
            std::string::npos);
  write(dir / "float.json", R"({"format_version": 2, "iterations": 1.5})");
  EXPECT_NE(error_of([&] { train::load_preset((dir / "float.json").string()); }).find("iterations"),
            std::string::npos);
  write(dir / "old.json", R"({"format_version": 0})");
  EXPECT_NE(
      error_of([&] { train::load_preset((dir / "old.json").string()); }).find("format_version 0"),
      std::string::npos);
  write(dir / "bad.json", R"({"format_version": 2,)");
  EXPECT_NE(
      error_of([&] { train::load_preset((dir / "bad.json").string()); }).find("not valid JSON"),
      std::string::npos);
  // A number no double holds is nlohmann's out_of_range, not a parse error.
  write(dir / "huge.json", R"({"format_version": 2, "iterations": 1e999})");
  const std::string huge = error_of([&] { train::load_preset((dir / "huge.json").string()); });
  EXPECT_NE(huge.find("huge.json: not valid JSON"), std::string::npos) << huge;
  EXPECT_NE(error_of([&] { train::load_preset("no-such-preset"); }).find("no such preset"),
            std::string::npos);
}

TEST(Config, PresetFilesCanExtendEachOtherByPath) {
  auto dir = test::temp_dir("config_chain");
  write(dir / "a.json", R"({"format_version": 2, "extends": "demo", "seed": 7})");
  write(dir / "b.json", R"({"format_version": 2, "extends": "a.json", "loss": {"l1": 0.5}})");
  auto c = train::load_preset((dir / "b.json").string());
  EXPECT_EQ(c["seed"], 7);
  EXPECT_DOUBLE_EQ(c["loss"]["l1"].get<double>(), 0.5);
  EXPECT_EQ(c["iterations"], train::load_preset("demo")["iterations"]);
  write(dir / "loop.json", R"({"format_version": 2, "extends": "loop.json"})");
  EXPECT_NE(error_of([&] { train::load_preset((dir / "loop.json").string()); }).find("cycle"),
            std::string::npos);
}

TEST(Config, SetOverridesOneKeyWithTypeChecks) {
  auto c = train::load_preset("default");
  train::apply_assignment(c, "densify.grad_threshold=0.001");
  EXPECT_DOUBLE_EQ(c["densify"]["grad_threshold"].get<double>(), 0.001);
  train::apply_assignment(c, "optim.sh_dc_lr=1");  // an integer is a valid number
  EXPECT_DOUBLE_EQ(c["optim"]["sh_dc_lr"].get<double>(), 1.0);
  train::apply_assignment(c, "model.background=[0.1, 0.2, 0.3]");
  const train::ModelConfig model = train::parse_run_config(c, "test").model;
  EXPECT_TRUE(torch::allclose(train::background(model, 3), torch::tensor({0.1f, 0.2f, 0.3f})));
  EXPECT_THROW(train::background(model, 4), core::Error);
  // One number is every band's; a list of one is one band's.
  train::apply_assignment(c, "model.background=0.5");
  EXPECT_TRUE(torch::equal(train::background(train::parse_run_config(c, "test").model, 3),
                           torch::full({3}, 0.5f)));
  train::apply_assignment(c, "model.background=[0.5]");
  EXPECT_THROW(train::background(train::parse_run_config(c, "test").model, 3), core::Error);
  train::apply_assignment(c, "model.background=[0.1, 0.2, 0.3]");
  train::apply_assignment(c, "data.rgb=true");
  EXPECT_TRUE(c["data"]["rgb"].get<bool>());
  EXPECT_THROW(train::apply_assignment(c, "densify.nope=1"), core::Error);
  EXPECT_THROW(train::apply_assignment(c, "densify=1"), core::Error);
  EXPECT_THROW(train::apply_assignment(c, "iterations=abc"), core::Error);
  EXPECT_THROW(train::apply_assignment(c, "data.rgb=1"), core::Error);
  EXPECT_THROW(train::apply_assignment(c, "no_equals_sign"), core::Error);
  train::validate_config(c, "overrides");
}

TEST(Config, LoadOptionsMirrorTheDataSection) {
  auto c = train::load_preset("default");
  train::apply_assignment(c, "data.downscale=4");
  train::apply_assignment(c, "data.band_min_nm=450");
  train::apply_assignment(c, "data.bin=2");
  auto o = train::parse_run_config(c, "test").data.load;
  EXPECT_EQ(o.downscale, 4);
  EXPECT_DOUBLE_EQ(o.band_min_nm, 450);
  EXPECT_EQ(o.bin, 2);
  EXPECT_THROW(train::apply_assignment(c, "data.downscale=0"), core::Error);
  c["data"]["downscale"] = 0;  // a config that skipped validation
  EXPECT_THROW(train::parse_run_config(c, "test"), core::Error);
}

// Every section reaches its typed struct (a key parsed into the wrong field
// shows as a mismatch), and the key lists that ablation leaves out of its
// run comparison name keys of the schema.
TEST(Config, RunConfigIsTheResolvedJsonTyped) {
  auto c = train::load_preset("default");
  for (const char* a : {"seed=11",
                        "iterations=1234",
                        "data.path=\"scenes/x\"",
                        "data.downscale=3",
                        "data.band_max_nm=900",
                        "model.sh_degree=2",
                        "model.learn_background=false",
                        "init.random_points=777",
                        "init.colour_views=5",
                        "optim.means_lr_init=0.25",
                        "optim.sh_rest_lr_divisor=7",
                        "optim.adam_eps=1e-9",
                        "loss.l1=0.6",
                        "loss.dssim=0.4",
                        "loss.spectral_temperature=0.75",
                        "wavelength_encoder.hidden=33",
                        "wavelength_encoder.lr=0.125",
                        "camera_refinement.translation_lr=0.5",
                        "diffusion.crop=48",
                        "diffusion.sampler_steps=3",
                        "densify.every=77",
                        "densify.max_screen_px=31",
                        "densify.max_gaussians=5000",
                        "output.log_every=13",
                        "output.checkpoint_every=222"})
    train::apply_assignment(c, a);
  const train::RunConfig r = train::parse_run_config(c, "test");
  EXPECT_EQ(r.resolved, c);
  EXPECT_EQ(r.seed, 11u);
  EXPECT_EQ(r.iterations, 1234);
  EXPECT_EQ(r.data.path, "scenes/x");
  EXPECT_EQ(r.data.load.downscale, 3);
  EXPECT_EQ(r.data.load.band_max_nm, 900);
  EXPECT_EQ(r.model.sh_degree, 2);
  EXPECT_FALSE(r.model.learn_background);
  EXPECT_TRUE(r.model.background_from_views);
  EXPECT_EQ(r.init.random_points, 777);
  EXPECT_EQ(r.init.colour_views, 5);
  EXPECT_EQ(r.init.sh_degree, 2);
  EXPECT_EQ(r.init.seed, 11u);
  EXPECT_EQ(r.optim.means_lr_init, 0.25);
  EXPECT_EQ(r.optim.sh_rest_lr_divisor, 7);
  EXPECT_EQ(r.optim.adam_eps, 1e-9);
  EXPECT_EQ(r.loss.l1, 0.6);
  EXPECT_EQ(r.loss.dssim, 0.4);
  EXPECT_EQ(r.loss.spectral_options.temperature, 0.75);
  EXPECT_EQ(r.wavelength_encoder.network.hidden, 33);
  EXPECT_EQ(r.wavelength_encoder.network.sh_coeffs, 9);
  EXPECT_EQ(r.wavelength_encoder.lr, 0.125);
  EXPECT_EQ(r.camera_refinement.translation_lr, 0.5);
  EXPECT_EQ(r.diffusion.crop_px, 48);
  EXPECT_EQ(r.diffusion.sampler.steps, 3);
  EXPECT_EQ(r.diffusion.sampler.seed, 11u);
  EXPECT_EQ(r.densify.every, 77);
  EXPECT_EQ(r.densify.thresholds.max_screen_px, 31);
  EXPECT_EQ(r.densify.thresholds.max_gaussians, 5000);
  EXPECT_EQ(r.output.log_every, 13);
  EXPECT_EQ(r.output.checkpoint_every, 222);
  for (const auto* keys : {&train::sampler_keys(), &train::finetune_keys()})
    for (const std::string& key : *keys) EXPECT_TRUE(c["diffusion"].contains(key)) << key;
}

TEST(Config, ResolvedConfigMustBeComplete) {
  auto c = train::load_preset("default");
  c["densify"].erase("every");
  EXPECT_NE(error_of([&] {
              train::validate_config(c, "run/config.json");
            }).find("missing key 'densify.every'"),
            std::string::npos);
}

TEST(Config, RunConfigsOfAnotherVersionOrMissingAKeyAreRefused) {
  // A run folder of another format_version, or lacking a key that format
  // always had, gets one line naming what it lacks or its version.
  auto c = train::load_preset("default");
  auto dir = test::temp_dir("old_run_config");
  std::ofstream(dir / "config.json") << c.dump(2);
  EXPECT_EQ(train::read_run_config({dir}), c);
  c["densify"].erase("every");
  std::ofstream(dir / "config.json") << c.dump(2);
  const std::string missing = error_of([&] { train::read_run_config({dir}); });
  EXPECT_NE(missing.find("config.json"), std::string::npos) << missing;
  EXPECT_NE(missing.find("missing key 'densify.every'"), std::string::npos) << missing;
  c = train::load_preset("default");
  c["format_version"] = 1;
  std::ofstream(dir / "config.json") << c.dump(2);
  const std::string version = error_of([&] { train::read_run_config({dir}); });
  EXPECT_NE(version.find("format_version 1; this ddhgs reads format_version 2"), std::string::npos)
      << version;
  // Keys that are there keep being checked.
  c = train::load_preset("default");
  c["iterations"] = "many";
  std::ofstream(dir / "config.json") << c.dump(2);
  EXPECT_NE(error_of([&] { train::read_run_config({dir}); }).find("'iterations' must be"),
            std::string::npos);
}

// A run made by an earlier ddhgs of format_version 2 lacks the keys added
// since; it reads with the values that reproduce how it trained, not with
// today's defaults (which would, say, start cropping its views on --resume).
TEST(Config, RunConfigsFromEarlierVersionsReadWithTheValuesTheyTrainedWith) {
  // configs/default.json as the first format_version 2 wrote it (7616d39).
  const auto first = test::source_dir() / "tests/train/data/config_format2_first.json";
  auto dir = test::temp_dir("earlier_run_config");
  std::filesystem::copy_file(first, dir / "config.json");
  const nlohmann::json original = nlohmann::json::parse(std::ifstream(first));
  const nlohmann::json read = train::read_run_config({dir});
  // Every key it had keeps its value...
  for (const auto& [section, keys] : original.items()) {
    if (!keys.is_object()) {
      EXPECT_EQ(read.at(section), keys) << section;
      continue;
    }
    for (const auto& [key, value] : keys.items())
      EXPECT_EQ(read.at(section).at(key), value) << section << "." << key;
  }
  // ...and the added ones behave as that version did.
  const train::RunConfig c = train::parse_run_config(read, "config.json");
  EXPECT_EQ(c.model.spectral_rank, 0);  // per band
  EXPECT_FALSE(c.model.background_from_views);
  EXPECT_FALSE(c.camera_refinement.enabled);
  EXPECT_EQ(c.data.load.band_step, 1);
  EXPECT_EQ(c.optim.latent_sh_lr_scale, 1.0);
  EXPECT_EQ(c.output.test_every, 0);
  EXPECT_EQ(c.loss.bands_per_step, 0);
  EXPECT_EQ(c.loss.view_fraction, 1.0);
  EXPECT_EQ(read["diffusion"]["pairs"], "training");
  EXPECT_EQ(read["diffusion"]["joint"], true);
  EXPECT_EQ(read["diffusion"]["validation_every"], 0);
  EXPECT_EQ(read["diffusion"]["distill_steps"], 0);
  // The file itself is left as it was: reading never writes.
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(dir / "config.json")), original);

  // A run of last week (crops opt-in, no threshold) cropped every view.
  auto week = train::load_preset("default");
  week["loss"]["view_fraction"] = 0.5;
  week["loss"].erase("view_fraction_from_pixels");
  week["loss"].erase("bands_per_step_until_fraction");  // before it: drawn all run
  week["loss"]["bands_per_step"] = 24;
  std::ofstream(dir / "config.json") << week.dump(2);
  const train::RunConfig w = train::parse_run_config(train::read_run_config({dir}), "config.json");
  EXPECT_EQ(w.loss.view_fraction, 0.5);
  EXPECT_EQ(w.loss.view_fraction_from_pixels, 0);
  EXPECT_EQ(w.loss.bands_per_step, 24);
  EXPECT_EQ(w.loss.bands_per_step_until_fraction, 1.0);

  // Removed keys: dropped where they cannot act, refused where they would.
  auto removed = train::load_preset("default");
  removed["init"]["extra_random_points"] = 20000;
  removed["diffusion"]["perturb_degrees"] = 1.0;
  std::ofstream(dir / "config.json") << removed.dump(2);
  EXPECT_FALSE(train::read_run_config({dir})["init"].contains("extra_random_points"));
  removed["diffusion"]["pairs"] = "perturbed";
  std::ofstream(dir / "config.json") << removed.dump(2);
  const std::string turned = error_of([&] { train::read_run_config({dir}); });
  EXPECT_NE(turned.find("config.json"), std::string::npos) << turned;
  EXPECT_NE(turned.find("diffusion.perturb_px"), std::string::npos) << turned;
  // A section the file lacks altogether is not an earlier version's.
  auto no_loss = train::load_preset("default");
  no_loss.erase("loss");
  std::ofstream(dir / "config.json") << no_loss.dump(2);
  EXPECT_NE(error_of([&] { train::read_run_config({dir}); }).find("missing key 'loss'"),
            std::string::npos);
}

// Values a run cannot use end the command before any work, naming
// the key (each of these was accepted and failed only after training, or
// trained on NaN).
TEST(Config, ValuesOutsideTheirRangeNameTheKey) {
  auto c = train::load_preset("demo");
  EXPECT_NE(error_of([&] {
              train::apply_assignment(c, "optim.sh_rest_lr_divisor=0");
            }).find("--set: key 'optim.sh_rest_lr_divisor' is 0, expected a number > 0"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              train::apply_assignment(c, "model.sh_degree=4");
            }).find("key 'model.sh_degree' is 4, expected an integer >= 0 and <= 3"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              train::set_key(c, "iterations", "-5", "--iterations");
            }).find("--iterations: key 'iterations' is -5, expected an integer >= 1"),
            std::string::npos);
  EXPECT_NE(error_of([&] { train::apply_assignment(c, "optim.sh_dc_lr=1e999"); }).find("sh_dc_lr"),
            std::string::npos);
  // In range: accepted, and every preset passes.
  train::apply_assignment(c, "model.sh_degree=0");
  train::apply_assignment(c, "optim.sh_rest_lr_divisor=0.5");
  for (const char* preset : {"default", "demo", "paper"})
    train::check_config_values(train::load_preset(preset), preset);
  c["densify"]["min_opacity"] = 1.5;  // a run folder's config.json edited by hand
  EXPECT_NE(error_of([&] {
              train::validate_config(c, "RUN/config.json");
            }).find("RUN/config.json: key 'densify.min_opacity' is 1.5"),
            std::string::npos);
}

namespace {

// Every number default.json holds (the schema) has a range, so no key takes
// NaN, a negative rate or a count that runs until killed.
void expect_ranges(const nlohmann::json& node, const std::string& prefix) {
  for (const auto& [key, value] : node.items()) {
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    if (value.is_object()) {
      expect_ranges(value, path);
    } else if (path != "format_version" &&
               (value.is_number() ||
                (value.is_array() && !value.empty() && value[0].is_number()))) {
      EXPECT_TRUE(train::has_range(path)) << path << " has no range in config_values.cpp";
    }
  }
}

}  // namespace

TEST(Config, EveryNumberHasARange) {
  expect_ranges(train::load_preset("default"), "");
}

TEST(Config, NonsenseValuesNameTheKey) {
  auto c = train::load_preset("demo");
  for (const char* bad :
       {"densify.until_fraction=-1", "model.sh_degree_every_fraction=-1",
        "camera_refinement.rotation_lr=-1", "loss.spectral_alpha=-1", "init.opacity=1",
        "wavelength_encoder.frequencies=100000", "wavelength_encoder.frequencies=-1",
        "optim.means_lr_init=1e38", "iterations=2000000000", "diffusion.sampler_samples=1000000"}) {
    const std::string key = std::string(bad).substr(0, std::string(bad).find('='));
    EXPECT_NE(error_of([&] { train::apply_assignment(c, bad); }).find("'" + key + "'"),
              std::string::npos)
        << bad;
  }
  // Arrays: each element.
  EXPECT_NE(error_of([&] {
              train::apply_assignment(c, "diffusion.channel_multipliers=[1,0,2]");
            }).find("diffusion.channel_multipliers"),
            std::string::npos);
  // Across keys: no loss at all, a band range that keeps nothing.
  auto none = train::load_preset("demo");
  none["loss"]["l1"] = 0;
  none["loss"]["dssim"] = 0;
  EXPECT_NE(error_of([&] { train::validate_config(none, "X"); }).find("'loss.l1' and 'loss.dssim'"),
            std::string::npos);
  auto bands = train::load_preset("demo");
  bands["data"]["band_min_nm"] = 900;
  bands["data"]["band_max_nm"] = 400;
  EXPECT_NE(error_of([&] { train::validate_config(bands, "X"); }).find("data.band_min_nm"),
            std::string::npos);
  // Edges that are fine: one of the two losses.
  auto dssim_only = train::load_preset("demo");
  dssim_only["loss"]["l1"] = 0;
  train::validate_config(dssim_only, "X");
}
