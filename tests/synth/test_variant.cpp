// `ddhgs synth --vary`: randomised variants of the ring presets.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "support/test_support.h"
#include "synth/generate.h"
#include "synth/render.h"
#include "synth/variant.h"

namespace ddhgs::synth {
namespace {

namespace fs = std::filesystem;

nlohmann::json read_json(const fs::path& path) {
  return nlohmann::json::parse(io::read_file(path));
}

// Per-band mean of a uint16 cube (value / 65535) that synth wrote.
std::vector<double> band_means(const fs::path& path) {
  torch::Tensor v = io::read_cube(path).data.to(torch::kInt32);
  v = torch::where(v < 0, v + 65536, v).to(torch::kFloat64) / 65535.0;
  torch::Tensor mean = v.reshape({-1, v.size(2)}).mean(0);
  return {mean.data_ptr<double>(), mean.data_ptr<double>() + mean.numel()};
}

SynthConfig tiny_varied(uint64_t seed) {
  SynthConfig c;
  c.seed = seed;
  c.width = 24;
  c.height = 18;
  c.bands = 8;
  c.views = 4;
  c.supersample = 1;
  c.points = 60;
  c.vary = true;
  vary_framing(c);
  return c;
}

// Low and high of every value seen.
struct Spread {
  std::map<std::string, std::pair<double, double>> seen;
  void add(const std::string& name, double value) {
    auto it = seen.find(name);
    if (it == seen.end()) {
      seen[name] = {value, value};
      return;
    }
    it->second.first = std::min(it->second.first, value);
    it->second.second = std::max(it->second.second, value);
  }
};

TEST(SynthVariant, DrawsStayWithinTheirDocumentedRangesAndSpanThem) {
  // name -> documented [lo, hi] (synth/variant.h, docs/commands.md).
  const std::map<std::string, std::pair<double, double>> documented = {
      {"min_leaves", {5, 14}},
      {"extra_leaves", {0, 8}},
      {"size", {0.7, 1.3}},
      {"leaf_aspect", {0.75, 1.3}},
      {"height", {0.75, 1.4}},
      {"droop", {0.4, 1.6}},
      {"lean", {0, 0.2}},
      {"chlorophyll_centre", {0.5, 1.5}},
      {"water_centre", {0.6, 1.4}},
      {"nir_centre", {0.32, 0.62}},
      {"yellowed_leaves", {0, 5}},
      {"yellowed_senescence", {0.2, 0.8}},
      {"pot_gain", {0.55, 1.4}},
      {"pot_shift", {-60, 60}},
      {"soil_gain", {0.6, 1.5}},
      {"soil_shift", {-50, 50}},
      {"ground_gain", {0.4, 1.8}},
      {"ground_shift", {-150, 150}},
      {"backdrop_gain", {0.3, 2.0}},
      {"light_elevation_deg", {25, 80}},
      {"sun", {0.4, 1.2}},
      {"ambient", {0.08, 0.45}},
      {"lit_backdrop", {0.3, 1.0}},
      {"lamp_k", {2400, 6500}},
      {"exposure", {0.45, 1.0}},
      {"fill", {0.6, 0.98}},
      {"fov_factor", {0.8, 1.25}},
      {"rings", {2, 4}},  // demo: 3 - 1 .. 3 + 1
      {"elevation_min", {7, 22}},
      {"elevation_max", {40, 65}},
  };
  Spread spread;
  int no_backdrop = 0;
  const int seeds = 400;
  const SynthConfig demo = preset_config("demo");
  for (uint64_t seed = 0; seed < uint64_t(seeds); ++seed) {
    const SceneVariant v = draw_variant(seed);
    const PlantStyle& p = v.plant;
    spread.add("min_leaves", p.min_leaves);
    spread.add("extra_leaves", p.max_leaves - p.min_leaves);
    spread.add("size", p.size);
    spread.add("leaf_aspect", p.leaf_aspect);
    spread.add("height", p.height);
    spread.add("droop", p.droop);
    spread.add("lean", p.lean);
    EXPECT_NEAR(p.chlorophyll_hi - p.chlorophyll_lo, 0.5, 1e-12);
    EXPECT_NEAR(p.water_hi - p.water_lo, 0.4, 1e-12);
    EXPECT_NEAR(p.nir_plateau_hi - p.nir_plateau_lo, 0.14, 1e-12);
    spread.add("chlorophyll_centre", 0.5 * (p.chlorophyll_lo + p.chlorophyll_hi));
    spread.add("water_centre", 0.5 * (p.water_lo + p.water_hi));
    spread.add("nir_centre", 0.5 * (p.nir_plateau_lo + p.nir_plateau_hi));
    spread.add("yellowed_leaves", p.yellowed_leaves);
    spread.add("yellowed_senescence", p.yellowed_senescence);
    spread.add("pot_gain", p.pot.gain);
    spread.add("pot_shift", p.pot.shift_nm);
    spread.add("soil_gain", p.soil.gain);
    spread.add("soil_shift", p.soil.shift_nm);
    spread.add("ground_gain", p.ground.gain);
    spread.add("ground_shift", p.ground.shift_nm);
    spread.add("backdrop_gain", p.backdrop.gain);
    EXPECT_EQ(p.backdrop.shift_nm, 0.0);
    const Lighting& l = v.lighting;
    EXPECT_NEAR(l.to_light.norm(), 1.0, 1e-12);
    spread.add("light_elevation_deg", std::asin(l.to_light.z) * 180 / M_PI);
    spread.add("sun", l.sun);
    spread.add("ambient", l.ambient);
    if (l.backdrop == 0)
      ++no_backdrop;
    else
      spread.add("lit_backdrop", l.backdrop);
    spread.add("lamp_k", l.lamp_temperature_k);
    spread.add("exposure", l.exposure);

    SynthConfig c = demo;
    c.seed = seed;
    vary_framing(c);
    spread.add("fill", c.fill);
    spread.add("fov_factor", c.fov_deg / demo.fov_deg);
    spread.add("rings", c.rings);
    spread.add("elevation_min", c.min_elevation_deg);
    spread.add("elevation_max", c.max_elevation_deg);
    EXPECT_GE(c.max_elevation_deg, c.min_elevation_deg + 5);
    EXPECT_NO_THROW(validate(c));
  }
  ASSERT_EQ(spread.seen.size(), documented.size());
  for (const auto& [name, range] : documented) {
    const auto [lo, hi] = spread.seen.at(name);
    EXPECT_GE(lo, range.first - 1e-12) << name;
    EXPECT_LE(hi, range.second + 1e-12) << name;
    // 400 draws cover nearly all of each range: a constant would fail.
    EXPECT_GT(hi - lo, 0.9 * (range.second - range.first)) << name;
  }
  // One time in four without a backdrop.
  EXPECT_GT(no_backdrop, seeds / 4 - 30);
  EXPECT_LT(no_backdrop, seeds / 4 + 30);
}

TEST(SynthVariant, PlantsOfOtherSeedsDifferInShapeAndSpectra) {
  std::set<size_t> leaf_counts;
  Spread spread;
  const std::vector<double> grid{450, 550, 668, 750, 850, 975};
  const int n = int(grid.size());
  for (uint64_t seed = 1000; seed < 1020; ++seed) {
    const SceneVariant v = draw_variant(seed);
    const PlantScene plant = PlantScene::build(seed, true, v.plant);
    ASSERT_GE(int(plant.leaves.size()), v.plant.min_leaves);
    ASSERT_LE(int(plant.leaves.size()), v.plant.max_leaves);
    leaf_counts.insert(plant.leaves.size());
    spread.add("top", plant.box_max.z);
    // The lamp's colour tilts the gain across bands.
    const SpectralSetup setup = make_spectral_setup(plant, grid, NoiseModel{}, v.lighting);
    spread.add("blue_to_nir_gain", setup.band_gain[0] / setup.band_gain[n - 1]);
  }
  EXPECT_GE(leaf_counts.size(), 6u);
  const auto [lowest_top, highest_top] = spread.seen.at("top");
  EXPECT_GT(highest_top - lowest_top, 0.3);  // scene units: a plant is about 1 high
  const auto [least_blue, most_blue] = spread.seen.at("blue_to_nir_gain");
  EXPECT_GT(most_blue, 1.5 * least_blue);

  // Two seeds: each material's spectrum and the light's differ.
  const SceneVariant a = draw_variant(1000), b = draw_variant(1001);
  const PlantScene plant_a = PlantScene::build(1000, true, a.plant);
  const PlantScene plant_b = PlantScene::build(1001, true, b.plant);
  const SpectralSetup sa = make_spectral_setup(plant_a, grid, NoiseModel{}, a.lighting);
  const SpectralSetup sb = make_spectral_setup(plant_b, grid, NoiseModel{}, b.lighting);
  for (int slot :
       {int(kBackground), int(kMatLight), int(kPotLight), int(kSoilDry), int(kLeafMaterials)}) {
    double largest = 0;
    for (int band = 0; band < n; ++band)
      largest = std::max(largest, double(std::abs(sa.reflectance[size_t(slot * n + band)] -
                                                  sb.reflectance[size_t(slot * n + band)])));
    EXPECT_GT(largest, 0.01) << "material slot " << slot;
  }
  // Every reflectance stays a reflectance.
  for (float r : sa.reflectance) {
    EXPECT_GE(r, 0.0f);
    EXPECT_LE(r, 1.0f);
  }
}

TEST(SynthVariant, SameSeedSameBytesOtherSeedOtherScene) {
  const fs::path dir = test::temp_dir("synth_variant");
  write_synthetic_scene(tiny_varied(1000), dir / "a", false);
  write_synthetic_scene(tiny_varied(1000), dir / "b", false);
  write_synthetic_scene(tiny_varied(1001), dir / "c", false);
  SynthConfig plain = tiny_varied(1000);
  plain.vary = false;
  write_synthetic_scene(plain, dir / "plain", false);
  int compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(dir / "a")) {
    if (!entry.is_regular_file()) continue;
    const fs::path rel = fs::relative(entry.path(), dir / "a");
    EXPECT_EQ(io::read_file(entry.path()), io::read_file(dir / "b" / rel)) << rel;
    ++compared;
  }
  EXPECT_GE(compared, 4 * 3 + 3);
  EXPECT_NE(io::read_file(dir / "a/clean/r_000.npy"), io::read_file(dir / "c/clean/r_000.npy"));
  // The variant changes the plant and light, not only the framing.
  EXPECT_NE(io::read_file(dir / "a/clean/r_000.npy"), io::read_file(dir / "plain/clean/r_000.npy"));

  const nlohmann::json a = read_json(dir / "a/synth.json"), c = read_json(dir / "c/synth.json");
  ASSERT_TRUE(a.contains("variant"));
  EXPECT_NE(a["variant"], c["variant"]);
  EXPECT_FALSE(read_json(dir / "plain/synth.json").contains("variant"));
  // What synth.json records is what was drawn.
  const SceneVariant drawn = draw_variant(1000);
  EXPECT_EQ(a["variant"]["leaves"][0], drawn.plant.min_leaves);
  EXPECT_DOUBLE_EQ(a["variant"]["lamp_temperature_k"].get<double>(),
                   drawn.lighting.lamp_temperature_k);
  EXPECT_DOUBLE_EQ(a["lighting"]["sun"].get<double>(), drawn.lighting.sun);
  EXPECT_DOUBLE_EQ(a["fill"].get<double>(), tiny_varied(1000).fill);
  EXPECT_GE(a["leaves"].get<int>(), drawn.plant.min_leaves);
  EXPECT_LE(a["leaves"].get<int>(), drawn.plant.max_leaves);
}

// Values written by the build before --vary existed (demo, 48x36, 5 views,
// 7 bands, seed 3): without --vary a scene is what it was.
TEST(SynthVariant, WithoutVaryTheSceneIsThatOfEarlierVersions) {
  const fs::path dir = test::temp_dir("synth_variant_before");
  SynthConfig c = preset_config("demo");
  c.seed = 3;
  c.width = 48;
  c.height = 36;
  c.views = 5;
  c.bands = 7;
  write_synthetic_scene(c, dir / "scene", false);
  const nlohmann::json j = read_json(dir / "scene/synth.json");
  EXPECT_EQ(j["leaves"], 15);
  const std::vector<double> gain{0.11295652389526367, 0.4285588562488556, 1.0317240953445435,
                                 1.4194151163101196,  1.3354241847991943, 0.960832417011261,
                                 0.5445609092712402};
  const std::vector<double> clean{0.023435094, 0.092696068, 0.239491965, 0.352688405,
                                  0.359757703, 0.261956106, 0.149219476};
  const std::vector<double> noisy{0.022850730, 0.091126464, 0.235374280, 0.346132818,
                                  0.352937185, 0.257099375, 0.146167018};
  const std::vector<double> clean_now = band_means(dir / "scene/clean/r_000.npy");
  const std::vector<double> noisy_now = band_means(dir / "scene/hyperspectral/r_002.npy");
  for (size_t b = 0; b < gain.size(); ++b) {
    EXPECT_NEAR(j["band_gain"][b].get<double>(), gain[b], 1e-7) << b;
    // One count of 65535 in one of 1728 pixels moves a mean by 1e-8.
    EXPECT_NEAR(clean_now[b], clean[b], 2e-8) << b;
    EXPECT_NEAR(noisy_now[b], noisy[b], 2e-8) << b;
  }
}

TEST(SynthVariant, CliFlagsOverrideTheDrawnFramingAndRigPresetsAreRefused) {
  if (!fs::exists(test::ddhgs_binary())) GTEST_SKIP() << "ddhgs not built";
  const fs::path dir = test::temp_dir("synth_variant_cli");
  auto synth = [&](const std::string& args, const fs::path& out, std::string* output) {
    return test::run_command(test::ddhgs_binary() +
                                 " -q synth --width 16 --height 12 --bands 4 --views 2 "
                                 "--supersample 1 --points 20 --seed 1003 " +
                                 args + " --out " + out.string() + " 2>&1",
                             output);
  };
  std::string output;
  ASSERT_EQ(synth("--vary", dir / "drawn", &output), 0) << output;
  ASSERT_EQ(synth("--vary --fill 0.5", dir / "filled", &output), 0) << output;
  const nlohmann::json drawn = read_json(dir / "drawn/synth.json");
  const nlohmann::json filled = read_json(dir / "filled/synth.json");
  EXPECT_EQ(filled["fill"].get<double>(), 0.5);
  EXPECT_NE(drawn["fill"].get<double>(), 0.5);
  SynthConfig expected = preset_config("demo");
  expected.seed = 1003;
  vary_framing(expected);
  EXPECT_DOUBLE_EQ(drawn["fill"].get<double>(), expected.fill);
  EXPECT_DOUBLE_EQ(drawn["fov_deg"].get<double>(), expected.fov_deg);
  EXPECT_EQ(filled["fov_deg"], drawn["fov_deg"]);
  EXPECT_EQ(filled["variant"], drawn["variant"]);

  EXPECT_EQ(synth("--preset rig --vary", dir / "rig", &output), 1) << output;
  EXPECT_NE(output.find("--vary is for the ring presets"), std::string::npos) << output;
  EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
  EXPECT_FALSE(fs::exists(dir / "rig"));
}

}  // namespace
}  // namespace ddhgs::synth
