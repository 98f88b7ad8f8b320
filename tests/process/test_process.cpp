// process_cubes end to end with a scripted stand-in for COLMAP (fast and
// deterministic; the real COLMAP runs in tests/app/test_process_cli.cpp):
// scene contents, unregistered views listed, failures leave no output.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include "io/files/atomic_file.h"
#include "io/scene/scene.h"
#include "process/process.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::process {
using namespace io;
namespace {
namespace fs = std::filesystem;
using test::contains;
using test::error_of;

struct Fixture {
  fs::path root, cubes, model, out;
};

// Four 8x6 cubes v0..v3 with 3 bands; a COLMAP text model posing the first
// `posed` of them, with one point seen at pixel (2, 1) of v0 and (4, 3) of v1.
Fixture make_fixture(const std::string& name, int posed) {
  Fixture f;
  f.root = test::temp_dir(name);
  f.cubes = f.root / "cubes";
  f.model = f.root / "model";
  f.out = f.root / "scene";
  fs::create_directories(f.cubes);
  for (int v = 0; v < 4; ++v) {
    torch::Tensor cube = torch::rand({6, 8, 3}, torch::TensorOptions().dtype(torch::kFloat32));
    cube.index_put_({1, 2}, torch::tensor({0.1f, 0.2f, 0.3f}));
    cube.index_put_({3, 4}, torch::tensor({0.3f, 0.4f, 0.5f}));
    write_npy(f.cubes / ("v" + std::to_string(v) + ".npy"), cube);
  }
  ColmapModel m;
  m.cameras[1] = {1, "PINHOLE", 8, 6, {7.0, 7.0, 4.0, 3.0}};
  for (int i = 0; i < posed; ++i) {
    ColmapImage image;
    image.image_id = i + 1;
    double a = 0.5 * i;
    image.qvec = {std::cos(a / 2), 0, std::sin(a / 2), 0};
    image.tvec = {0, 0, 3};
    image.camera_id = 1;
    image.name = "v" + std::to_string(i) + ".png";
    if (i < 2) {
      image.xys = {{i == 0 ? 2.5 : 4.5, i == 0 ? 1.5 : 3.5}};
      image.point3d_ids = {5};
    }
    m.images.push_back(image);
  }
  ColmapPoint p;
  p.point3d_id = 5;
  p.xyz = {0.1, 0.2, 0.3};
  p.rgb = {10, 20, 30};
  p.track = {{1, 0}};
  if (posed > 1) p.track.push_back({2, 0});
  m.points.push_back(p);
  write_colmap_text(f.model, m);
  return f;
}

// A stand-in COLMAP: logs its arguments, prints progress, and the mapper
// copies model_dir to <output_path>/0. fail_stage exits 3 with an error line.
fs::path fake_colmap(const fs::path& dir, const fs::path& model_dir,
                     const std::string& fail_stage = "") {
  fs::path script = dir / "fake-colmap";
  std::ofstream(script) << "#!/bin/sh\n"
                        << "cmd=$1; shift; echo \"fake $cmd $*\"\n"
                        << "if [ \"$cmd\" = '" << fail_stage << "' ]; then\n"
                        << "  echo 'ERROR: simulated failure'; exit 3; fi\n"
                        << "out=''\n"
                        << "while [ $# -gt 0 ]; do [ \"$1\" = --output_path ] && out=$2; shift; "
                           "done\n"
                        << "case $cmd in\n"
                        << "  feature_extractor) echo 'Processed file [1/4]'; "
                           "echo 'Processed file [4/4]';;\n"
                        << "  mapper) mkdir -p \"$out/0\" && cp '" << model_dir.string()
                        << "'/* \"$out/0/\";;\n"
                        << "esac\n";
  fs::permissions(script, fs::perms::owner_all);
  return script;
}

ProcessOptions options_for(const Fixture& f, const fs::path& colmap) {
  ProcessOptions o;
  o.cubes_dir = f.cubes;
  o.out = f.out;
  o.wavelengths = WavelengthRange{450, 650};
  o.colmap.binary = colmap.string();
  return o;
}

// Names in dir, sorted: what a failed run must leave untouched.
std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(SfmProcess, WritesATrainableSceneAndListsUnregisteredViews) {
  Fixture f = make_fixture("sfm_process_ok", 3);
  ProcessOptions o = options_for(f, fake_colmap(f.root, f.model));
  o.out = f.out.string() + "/";  // a trailing slash names the same folder
  o.colmap.settings = {"SiftExtraction.peak_threshold=0.004"};
  ProcessResult r = process_cubes(o);
  EXPECT_EQ(r.views, 4);
  EXPECT_EQ(r.registered, 3);
  EXPECT_EQ(r.unregistered, std::vector<std::string>{"v3"});
  EXPECT_EQ(r.points, 1);
  for (const char* file : {"transforms.json", "points.ply", "colmap.log", "process.json",
                           "images/v0.png", "images/v3.png", "sparse/0/cameras.bin"})
    EXPECT_TRUE(fs::exists(f.out / file)) << file;
  EXPECT_EQ(listing(f.root), (std::vector<std::string>{"cubes", "fake-colmap", "model", "scene"}));
  std::string log = read_file(f.out / "colmap.log");
  EXPECT_TRUE(contains(log, "fake feature_extractor")) << log;
  EXPECT_TRUE(contains(log, "--ImageReader.camera_model 'SIMPLE_PINHOLE'")) << log;
  EXPECT_TRUE(contains(log, "--SiftMatching.use_gpu '0'")) << log;
  // Defaults for small frames, each replaced (not repeated) by a user setting.
  EXPECT_TRUE(contains(log, "--SiftExtraction.domain_size_pooling '1'")) << log;
  EXPECT_TRUE(contains(log, "--SiftExtraction.peak_threshold '0.004'")) << log;
  EXPECT_FALSE(contains(log, "--SiftExtraction.peak_threshold '0.002'")) << log;
  auto summary = nlohmann::json::parse(read_file(f.out / "process.json"));
  EXPECT_EQ(summary["unregistered"], nlohmann::json::array({"v3"}));

  auto scene = load_scene(f.out);
  ASSERT_EQ(scene->views.size(), 3u);
  EXPECT_EQ(scene->wavelengths_nm, (std::vector<double>{450, 550, 650}));
  EXPECT_TRUE(scene->warnings.empty());
  // The cubes stay where they were: the scene refers to them.
  EXPECT_TRUE(
      torch::allclose(scene->image(1), cube_to_float(read_cube(f.cubes / "v1.npy")), 0, 1e-6));
  core::Vec3 c = scene->views[0].camera.center();
  EXPECT_NEAR(c.z, -3.0, 1e-9);
  ASSERT_TRUE(scene->points.spectra.defined());
  // Mean of (0.1, 0.2, 0.3) and (0.3, 0.4, 0.5).
  EXPECT_TRUE(torch::allclose(scene->points.spectra[0], torch::tensor({0.2f, 0.3f, 0.4f}), 0, 1e-6))
      << scene->points.spectra;
}

TEST(SfmProcess, FewerThanThreePosedViewsLeavesOnlyTheLog) {
  Fixture f = make_fixture("sfm_process_two", 2);
  std::string e = error_of([&] { process_cubes(options_for(f, fake_colmap(f.root, f.model))); });
  EXPECT_TRUE(contains(e, "scene.colmap.log: 2 of 4 views posed; at least 3 are needed")) << e;
  EXPECT_EQ(listing(f.root),
            (std::vector<std::string>{"cubes", "fake-colmap", "model", "scene.colmap.log"}));
}

TEST(SfmProcess, AFailingColmapStageIsNamedWithItsError) {
  Fixture f = make_fixture("sfm_process_fail", 3);
  std::string e = error_of(
      [&] { process_cubes(options_for(f, fake_colmap(f.root, f.model, "exhaustive_matcher"))); });
  EXPECT_TRUE(contains(e, "COLMAP exhaustive_matcher failed (ERROR: simulated failure)")) << e;
  EXPECT_FALSE(fs::exists(f.out));
  EXPECT_EQ(listing(f.root),
            (std::vector<std::string>{"cubes", "fake-colmap", "model", "scene.colmap.log"}));
}

TEST(SfmProcess, ReplacesOnlyItsOwnSceneAndNeverItsInput) {
  Fixture f = make_fixture("sfm_process_force", 3);
  fs::create_directories(f.out);
  std::ofstream(f.out / "keep.txt") << "old";
  ProcessOptions o = options_for(f, fake_colmap(f.root, f.model));
  o.force = true;
  std::string e = error_of([&] { process_cubes(o); });
  EXPECT_TRUE(contains(e, "did not write")) << e;
  EXPECT_TRUE(fs::exists(f.out / "keep.txt"));
  fs::remove_all(f.out);
  o.force = false;
  process_cubes(o);
  e = error_of([&] { process_cubes(o); });
  EXPECT_TRUE(contains(e, "pass --force")) << e;
  o.force = true;
  process_cubes(o);
  EXPECT_TRUE(fs::exists(f.out / "transforms.json"));
  // The cube folder as the output, or a folder holding it: refused, cubes intact.
  const size_t cubes = size_t(std::distance(fs::directory_iterator(f.cubes), {}));
  for (const fs::path& out : {f.cubes, f.root}) {
    o.out = out;
    e = error_of([&] { process_cubes(o); });
    EXPECT_TRUE(contains(e, "input")) << e;
    EXPECT_EQ(size_t(std::distance(fs::directory_iterator(f.cubes), {})), cubes);
  }
}

TEST(SfmProcess, MissingColmapOrBadCubesCreateNothing) {
  Fixture f = make_fixture("sfm_process_missing", 3);
  std::string e = error_of([&] { process_cubes(options_for(f, f.root / "no-colmap")); });
  EXPECT_TRUE(contains(e, "no-colmap: is not an executable COLMAP")) << e;
  std::ofstream(f.cubes / "v2.npy") << "truncated";
  e = error_of([&] { process_cubes(options_for(f, fake_colmap(f.root, f.model))); });
  EXPECT_TRUE(contains(e, "v2.npy")) << e;
  EXPECT_EQ(listing(f.root), (std::vector<std::string>{"cubes", "fake-colmap", "model"}));
}

TEST(SfmProcess, SkipColmapTakesPosesFromAModelOrTransformsJson) {
  Fixture f = make_fixture("sfm_process_skip", 4);
  ProcessOptions o = options_for(f, f.root / "unused");
  o.poses = f.model;
  ProcessResult r = process_cubes(o);
  EXPECT_EQ(r.registered, 4);
  EXPECT_FALSE(fs::exists(f.out / "colmap.log"));
  auto from_model = load_scene(f.out);

  // The transforms.json just written, as poses for a second scene.
  o.poses = f.out / "transforms.json";
  o.out = f.root / "scene2";
  process_cubes(o);
  auto from_json = load_scene(o.out);
  ASSERT_EQ(from_json->views.size(), 4u);
  EXPECT_FALSE(from_json->points.xyz.defined());  // a transforms.json has no tracks
  for (size_t v = 0; v < 4; ++v)
    for (size_t k = 0; k < 16; ++k)
      EXPECT_NEAR(from_json->views[v].camera.world_to_camera.m[k],
                  from_model->views[v].camera.world_to_camera.m[k], 1e-9);

  o.poses = f.root / "nothing-here";
  o.out = f.root / "scene3";
  EXPECT_TRUE(contains(error_of([&] { process_cubes(o); }), "nothing-here: does not exist"));
  EXPECT_FALSE(fs::exists(o.out));
}

// Specim IQ's layout: a folder per capture holding capture/ with the raw
// cube (counts) and its WHITEREF_* and DARKREF_* references. process finds
// it, takes each capture's own references, and the scene holds reflectance.
TEST(SfmProcess, SpecimIqCapturesBecomeReflectance) {
  Fixture f = make_fixture("sfm_process_specim", 4);
  const fs::path specim = f.root / "specim";
  const std::vector<double> wavelengths = {450, 550, 650};
  auto write_counts = [&](const fs::path& hdr, const torch::Tensor& counts) {
    write_envi(hdr, counts.round().to(torch::kInt32).to(torch::kInt16).contiguous(), wavelengths,
               EnviInterleave::BIL, SampleType::U16);
  };
  for (int v = 0; v < 4; ++v) {
    const std::string id = "v" + std::to_string(v);
    const fs::path capture = specim / id / "capture";
    fs::create_directories(capture);
    // Each capture its own dark (100 + 10 v) and white (dark + 1000) lines.
    const double dark = 100 + 10 * v;
    const torch::Tensor truth = cube_to_float(read_cube(f.cubes / (id + ".npy")));  // [6, 8, 3]
    torch::Tensor raw = dark + 1000 * truth.to(torch::kFloat64);
    if (v == 2) raw[0][0][0] = 65535;
    write_counts(capture / (id + ".hdr"), raw);
    write_counts(capture / ("WHITEREF_" + id + ".hdr"), torch::full({3, 8, 3}, dark + 1000));
    write_counts(capture / ("DARKREF_" + id + ".hdr"), torch::full({2, 8, 3}, dark));
  }
  ProcessOptions o = options_for(f, f.root / "unused");
  o.cubes_dir = specim;
  o.wavelengths.reset();
  o.poses = f.model;
  EXPECT_EQ(process_cubes(o).registered, 4);

  const auto scene = load_scene(f.out);
  ASSERT_EQ(scene->views.size(), 4u);
  for (size_t v = 0; v < 4; ++v) {
    EXPECT_TRUE(fs::equivalent(scene->views[v].data_path,
                               f.out / "reflectance" / ("v" + std::to_string(v) + ".npy")));
    torch::Tensor want = cube_to_float(read_cube(f.cubes / ("v" + std::to_string(v) + ".npy")));
    torch::Tensor got = scene->image(int(v));
    if (v == 2) got[0][0][0] = want[0][0][0];                       // the saturated sample
    EXPECT_LT((got - want).abs().max().item<double>(), 6e-4) << v;  // counts rounded
  }
  const auto summary = nlohmann::json::parse(read_file(f.out / "process.json"));
  const auto& r = summary["reflectance"];
  EXPECT_EQ(r["saturated_samples"], 1) << r.dump(2);
  EXPECT_EQ(r["dead_reference_pixels"], 0) << r.dump(2);
  EXPECT_EQ(r["saturation_count"], 65535.0) << r.dump(2);
  EXPECT_EQ(r["white"], "each capture's WHITEREF_*") << r.dump(2);
  EXPECT_EQ(r["cubes"][2]["saturated"], 1) << r.dump(2);

  // A capture folder without its dark reference is named.
  fs::remove(specim / "v3" / "capture" / "DARKREF_v3.hdr");
  o.out = f.root / "scene2";
  const std::string e = error_of([&] { process_cubes(o); });
  EXPECT_TRUE(contains(e, "needs the raw cube's .hdr, WHITEREF_*.hdr and DARKREF_*.hdr")) << e;
  EXPECT_FALSE(fs::exists(o.out));
}

}  // namespace
}  // namespace ddhgs::process
