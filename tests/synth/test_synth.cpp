#include <gtest/gtest.h>

#include <algorithm>

#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/threads.h"
#include "io/scene/scene.h"
#include "support/test_support.h"
#include "synth/generate.h"
#include "synth/render.h"
#include "synth/spectra.h"

namespace ddhgs::synth {
namespace {

namespace fs = std::filesystem;

std::vector<double> grid(double first_nm, double last_nm, int count) {
  std::vector<double> out;
  for (int i = 0; i < count; ++i) out.push_back(first_nm + (last_nm - first_nm) * i / (count - 1));
  return out;
}

RigOptions small_rig(int width = 48, int height = 36) {
  RigOptions rig;
  rig.views = 12;
  rig.width = width;
  rig.height = height;
  return rig;
}

TEST(SynthSpectra, LeafHasChlorophyllTroughsRedEdgeAndWaterDip) {
  LeafTraits leaf;
  double red_min = 1, red_min_nm = 0;
  for (double nm = 600; nm <= 700; nm += 1) {
    double r = leaf_reflectance(nm, leaf);
    if (r < red_min) red_min = r, red_min_nm = nm;
  }
  EXPECT_NEAR(red_min_nm, 665, 15);
  EXPECT_LT(red_min, leaf_reflectance(550, leaf));
  EXPECT_LT(leaf_reflectance(435, leaf), leaf_reflectance(550, leaf));
  // Green peak near 550 nm.
  double peak_nm = 500, peak = 0;
  for (double nm = 500; nm <= 600; nm += 1)
    if (leaf_reflectance(nm, leaf) > peak) peak = leaf_reflectance(nm, leaf), peak_nm = nm;
  EXPECT_NEAR(peak_nm, 550, 10);
  // Red edge and NIR plateau.
  double plateau = leaf_reflectance(850, leaf);
  EXPECT_GT(plateau, 3 * red_min);
  EXPECT_GT(leaf_reflectance(760, leaf), 0.8 * plateau);
  EXPECT_LT(leaf_reflectance(690, leaf), 0.3 * plateau);
  // Water: a dip near 970 nm below both shoulders.
  EXPECT_LT(leaf_reflectance(975, leaf), leaf_reflectance(920, leaf));
  EXPECT_LT(leaf_reflectance(975, leaf), leaf_reflectance(1030, leaf));
  // More chlorophyll: darker green, red edge further right.
  LeafTraits rich = leaf;
  rich.chlorophyll = 1.4;
  EXPECT_LT(leaf_reflectance(550, rich), leaf_reflectance(550, leaf));
  EXPECT_LT(leaf_reflectance(715, rich), leaf_reflectance(715, leaf));
}

TEST(SynthSpectra, OtherMaterialsLampAndSensor) {
  EXPECT_LT(terracotta_reflectance(450, 0), terracotta_reflectance(650, 0));
  EXPECT_LT(terracotta_reflectance(650, 0), terracotta_reflectance(1000, 0));
  EXPECT_LT(terracotta_reflectance(650, 1), terracotta_reflectance(650, 0));
  EXPECT_LT(soil_reflectance(700, 1), soil_reflectance(700, 0));
  EXPECT_NEAR(background_reflectance(700), 0.33, 1e-9);
  EXPECT_NEAR(sensor_response(680), 1.0, 1e-9);
  EXPECT_GT(sensor_response(400), 0.1);
  EXPECT_LT(sensor_response(400), 0.2);
  EXPECT_GT(sensor_response(1100), 0.1);
  EXPECT_LT(sensor_response(1100), 0.2);
  EXPECT_LT(lamp_power(400), lamp_power(700));  // halogen: dim blue
  EXPECT_GT(lamp_power(400), 0.35);
}

TEST(SynthNoise, EdgeBandsAreMuchNoisierOnAFlatPatch) {
  PlantScene scene = PlantScene::build(1, true);
  auto wl = grid(400, 1000, 40);
  auto clean = torch::full({64, 64, 40}, 0.3f);
  auto band_std = [&](const NoiseModel& model) {
    SpectralSetup setup = make_spectral_setup(scene, wl, model);
    std::mt19937_64 rng(7);
    auto noisy = add_noise(clean, setup, rng);
    auto stds = (noisy - clean).reshape({-1, 40}).std(0);
    // Measured std matches the model where clamping at 0 and 1 cannot bite.
    for (int b : {10, 20, 30})
      EXPECT_NEAR(stds[b].item<double>(), noise_std(0.3, setup.response[b], model),
                  0.05 * noise_std(0.3, setup.response[b], model));
    double middle = stds[20].item<double>();  // ~708 nm, response ~1
    return std::make_pair(stds[0].item<double>() / middle, stds[39].item<double>() / middle);
  };
  auto [blue, nir] = band_std(NoiseModel{});
  EXPECT_GT(blue, 2.3);
  EXPECT_GT(nir, 1.5);
  NoiseModel edges;
  edges.edge_power = 2;
  auto [blue2, nir2] = band_std(edges);
  EXPECT_GT(blue2, 2 * blue);
  EXPECT_GT(nir2, 1.5 * nir);
}

TEST(SynthRender, CamerasLookAtThePlant) {
  PlantScene scene = PlantScene::build(0, false);
  auto cameras = turntable_rig(scene, small_rig());
  ASSERT_EQ(cameras.size(), 12u);
  double distance = (cameras[0].center() - scene.centre()).norm();
  int hits = 0, rays = 0;
  for (const auto& cam : cameras) {
    EXPECT_NEAR((cam.center() - scene.centre()).norm(), distance, 1e-9);
    EXPECT_GT(cam.forward().dot((scene.centre() - cam.center()).normalized()), 0.9999);
    EXPECT_GT(cam.center().z, scene.centre().z);  // looking down a little
    // Rays through the central 9 x 9 pixels hit plant or pot.
    for (int dy = -4; dy <= 4; ++dy)
      for (int dx = -4; dx <= 4; ++dx) {
        SurfaceHit hit;
        hits += scene.intersect(camera_ray(cam, 24 + dx, 18 + dy), &hit);
        ++rays;
      }
  }
  EXPECT_GT(hits, rays / 3);
}

TEST(SynthRender, PlantCoversASensibleFractionAndBackgroundElsewhere) {
  PlantScene scene = PlantScene::build(0, false);
  auto rig = small_rig();
  auto cameras = turntable_rig(scene, rig);
  auto wl = grid(400, 1000, 12);
  SpectralSetup setup = make_spectral_setup(scene, wl, NoiseModel{});
  auto clean = render_clean(scene, setup, cameras[0], 1);
  ASSERT_EQ(clean.sizes(), (std::vector<int64_t>{36, 48, 12}));
  // Background pixels carry exactly the backdrop spectrum.
  std::vector<float> backdrop(12);
  for (int b = 0; b < 12; ++b)
    backdrop[b] = setup.reflectance[kBackground * 12 + b] * float(setup.lighting.backdrop) *
                  setup.band_gain[b];
  auto bg = torch::tensor(backdrop);
  auto is_bg = ((clean - bg).abs().amax(2) < 1e-6);
  double covered = 1.0 - is_bg.to(torch::kFloat32).mean().item<double>();
  EXPECT_GT(covered, 0.05);
  EXPECT_LT(covered, 0.7);
  // The plant spans most of the image height (the rig frames it tightly).
  auto rows = (~is_bg).any(1).nonzero();
  double span = (rows.max().item<int64_t>() - rows.min().item<int64_t>() + 1) / 36.0;
  EXPECT_GT(span, 0.6);
  EXPECT_LT(span, 1.0);
  for (auto [y, x] : {std::pair{0, 0}, {0, 47}, {35, 0}, {35, 47}})
    EXPECT_TRUE(is_bg[y][x].item<bool>()) << y << "," << x;
  EXPECT_LE(clean.max().item<float>(), 1.0f);
  EXPECT_GE(clean.min().item<float>(), 0.0f);
  EXPECT_GT(clean.max().item<float>(), 0.4f);  // normalised to use the range
}

TEST(SynthRender, ViewDependenceFromSpecular) {
  // Specular highlights make a surface point's value depend on the viewer:
  // with the specular terms removed the render must change somewhere.
  PlantScene scene = PlantScene::build(2, true);
  auto cameras = turntable_rig(scene, small_rig());
  SpectralSetup setup = make_spectral_setup(scene, grid(500, 900, 6), NoiseModel{});
  auto with = render_clean(scene, setup, cameras[3], 1);
  SpectralSetup no_light = setup;
  no_light.lighting.sun = 0;
  auto ambient_only = render_clean(scene, no_light, cameras[3], 1);
  EXPECT_GT((with - ambient_only).abs().max().item<float>(), 0.05f);
}

TEST(SynthRender, RenderIsIndependentOfThreadCount) {
  PlantScene scene = PlantScene::build(5, true);
  auto cameras = turntable_rig(scene, small_rig());
  SpectralSetup setup = make_spectral_setup(scene, grid(400, 1000, 8), NoiseModel{});
  // The renderer runs on ddhgs's own pool (core/parallel.h), sized here.
  const int before = core::thread_count();
  core::configure_threads(1);
  auto one = render_clean(scene, setup, cameras[1], 2);
  core::configure_threads(3);
  auto two = render_clean(scene, setup, cameras[1], 2);
  core::configure_threads(before);
  EXPECT_TRUE(torch::equal(one, two));
}

SynthConfig tiny(uint64_t seed) {
  SynthConfig c;
  c.seed = seed;
  c.width = 24;
  c.height = 18;
  c.bands = 8;
  c.views = 4;
  c.rings = 2;
  c.supersample = 1;
  c.points = 60;
  return c;
}

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(SynthDataset, SameSeedSameBytesOtherSeedOtherBytes) {
  auto dir = test::temp_dir("synth_determinism");
  write_synthetic_scene(tiny(3), dir / "a", false);
  write_synthetic_scene(tiny(3), dir / "b", false);
  write_synthetic_scene(tiny(4), dir / "c", false);
  int compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(dir / "a")) {
    if (!entry.is_regular_file()) continue;
    auto rel = fs::relative(entry.path(), dir / "a");
    ASSERT_TRUE(fs::exists(dir / "b" / rel)) << rel;
    EXPECT_EQ(slurp(entry.path()), slurp(dir / "b" / rel)) << rel;
    ++compared;
  }
  EXPECT_GE(compared, 4 * 3 + 3);  // 3 files per view + transforms, points, synth.json
  EXPECT_NE(slurp(dir / "a/hyperspectral/r_000.npy"), slurp(dir / "c/hyperspectral/r_000.npy"));
  EXPECT_NE(slurp(dir / "a/clean/r_000.npy"), slurp(dir / "c/clean/r_000.npy"));
  // No temporary folders left beside the outputs.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.is_directory();
  EXPECT_EQ(entries, 3);
}

TEST(SynthDataset, RoundTripsThroughLoadScene) {
  auto dir = test::temp_dir("synth_roundtrip");
  SynthConfig config = tiny(9);
  write_synthetic_scene(config, dir / "scene", false);
  auto scene = io::load_scene(dir / "scene");
  ASSERT_EQ(scene->views.size(), 4u);
  EXPECT_TRUE(scene->warnings.empty());
  ASSERT_EQ(scene->bands(), 8);
  for (int b = 0; b < 8; ++b) EXPECT_NEAR(scene->wavelengths_nm[b], 400 + 600.0 * b / 7, 1e-9);
  EXPECT_TRUE(scene->has_clean());
  EXPECT_EQ(scene->stored_type, io::SampleType::U16);

  // Cameras and clean cubes are what the renderer produced.
  PlantScene plant = PlantScene::build(9, true);
  RigOptions rig;
  rig.views = 4;
  rig.rings = 2;
  rig.width = 24;
  rig.height = 18;
  auto cameras = turntable_rig(plant, rig);
  SpectralSetup setup = make_spectral_setup(plant, config.wavelengths_nm(), NoiseModel{});
  for (int v = 0; v < 4; ++v) {
    const auto& loaded = scene->views[v].camera;
    EXPECT_NEAR(loaded.intrinsics.fx, cameras[v].intrinsics.fx, 1e-6);
    EXPECT_EQ(loaded.intrinsics.width, 24);
    for (int i = 0; i < 16; ++i)
      EXPECT_NEAR(loaded.world_to_camera.m[i], cameras[v].world_to_camera.m[i], 1e-5) << v;
    auto clean = render_clean(plant, setup, cameras[v], 1);
    EXPECT_LT((scene->clean_image(v) - clean).abs().max().item<float>(), 1.0f / 65535 + 1e-6);
    auto noisy = scene->image(v);
    double err = (noisy - clean).abs().mean().item<double>();
    EXPECT_GT(err, 1e-4);  // noisy indeed
    EXPECT_LT(err, 0.05);  // but the same scene
  }
  ASSERT_TRUE(scene->points.xyz.defined());
  EXPECT_GE(scene->points.xyz.size(0), 40);
  ASSERT_TRUE(scene->points.spectra.defined());
  EXPECT_EQ(scene->points.spectra.size(1), 8);
  EXPECT_TRUE(fs::exists(dir / "scene" / "images" / "r_003.png"));
  EXPECT_TRUE(fs::exists(dir / "scene" / "synth.json"));
}

TEST(SynthDataset, ReplacesOnlyItsOwnSceneAndOnlyWithForce) {
  auto dir = test::temp_dir("synth_force");
  fs::create_directories(dir / "out");
  std::ofstream(dir / "out" / "keep.txt") << "precious";
  // A folder ddhgs did not write is never replaced, --force or not.
  for (bool force : {false, true}) {
    try {
      write_synthetic_scene(tiny(1), dir / "out", force);
      FAIL() << "expected core::Error";
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find("did not write"), std::string::npos) << e.what();
    }
    EXPECT_EQ(slurp(dir / "out" / "keep.txt"), "precious");
  }
  // A scene ddhgs wrote needs --force, and is then replaced whole.
  write_synthetic_scene(tiny(1), dir / "scene", false);
  try {
    write_synthetic_scene(tiny(2), dir / "scene", false);
    FAIL() << "expected core::Error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("--force"), std::string::npos) << e.what();
  }
  write_synthetic_scene(tiny(2), dir / "scene", true);
  EXPECT_TRUE(fs::exists(dir / "scene" / "transforms.json"));
  // The marker names the kind and lists what the scene holds as ddhgs's.
  EXPECT_EQ(slurp(dir / "scene" / ".ddhgs-output"),
            "ddhgs scene\nmanifest\nwrote clean\nwrote hyperspectral\nwrote images\n"
            "wrote points.ply\nwrote synth.json\nwrote transforms.json\n");
  // An empty folder is fine without --force.
  fs::create_directories(dir / "empty");
  EXPECT_NO_THROW(write_synthetic_scene(tiny(1), dir / "empty", false));
  // Nothing is left beside the folders but the folders themselves.
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"empty", "out", "scene"}));
  EXPECT_THROW(preset_config("nope"), core::Error);
}

TEST(SynthDataset, CliRefusesFoldersItDidNotWriteEvenWithForce) {
  if (!fs::exists(test::ddhgs_binary())) GTEST_SKIP() << "ddhgs not built";
  auto dir = test::temp_dir("synth_cli");
  fs::create_directories(dir / "out");
  std::ofstream(dir / "out" / "keep.txt") << "x";
  auto command = [&](const fs::path& out) {
    return test::ddhgs_binary() +
           " -q synth --width 16 --height 12 --bands 4 --views 2 --supersample 1 --out " +
           out.string();
  };
  std::string output;
  EXPECT_EQ(test::run_command(command(dir / "out") + " --force 2>&1", &output), 1) << output;
  EXPECT_NE(output.find("did not write"), std::string::npos) << output;
  EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
  EXPECT_TRUE(fs::exists(dir / "out" / "keep.txt"));
  EXPECT_EQ(test::run_command(command(dir / "scene") + " 2>&1", &output), 0) << output;
  EXPECT_EQ(test::run_command(command(dir / "scene") + " 2>&1", &output), 1) << output;
  EXPECT_NE(output.find("--force"), std::string::npos) << output;
  EXPECT_EQ(test::run_command(command(dir / "scene") + " --force 2>&1", &output), 0) << output;
  EXPECT_TRUE(fs::exists(dir / "scene" / "hyperspectral" / "r_001.npy"));
}

}  // namespace
}  // namespace ddhgs::synth
