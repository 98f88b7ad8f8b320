// Multispectral rig captures end to end: `ddhgs synth --preset rig` writes
// raw band TIFFs of a five-camera rig with known rotations, radiometry and a
// panel; `ddhgs process --rig` turns them into a band-per-view scene of
// reflectance; its poses and reflectance are checked against the synthetic
// truth, and the scene trains, evaluates, renders NDVI, reports and exports.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>

#include "core/similarity.h"
#include "io/files/atomic_file.h"
#include "io/scene/scene.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args, out);
}

using test::read_json;

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? v : fallback;
}

double angle_deg(const core::Mat3& a, const core::Mat3& b) {
  const core::Mat3 d = a.transposed() * b;
  const double c = std::clamp((d(0, 0) + d(1, 1) + d(2, 2) - 1) / 2, -1.0, 1.0);
  return std::acos(c) * 180 / M_PI;
}

core::Vec3 centre(const core::Mat4& w2c) {
  return (w2c.rotation().transposed() * w2c.translation()) * -1.0;
}

// The processed scene's views against the truth's of the same name: the
// worst camera rotation error after a similarity alignment of the camera
// centres (identity when the poses share the truth's frame), and the worst
// view's mean relative reflectance error where the truth is above 0.05.
struct Comparison {
  double worst_rotation_deg = 0, median_rotation_deg = 0, worst_reflectance = 0;
  double median_reference_deg = 0;  // the views of the camera COLMAP posed (rig index 1)
  size_t views = 0;
};
Comparison compare(const io::Scene& processed, const io::Scene& truth) {
  std::map<std::string, int> by_name;
  for (size_t v = 0; v < truth.views.size(); ++v) by_name[truth.views[v].name] = int(v);
  std::vector<core::Vec3> from, to;
  std::vector<std::pair<int, int>> pairs;
  for (size_t v = 0; v < processed.views.size(); ++v) {
    const int t = by_name.at(processed.views[v].name);
    pairs.emplace_back(int(v), t);
    from.push_back(centre(processed.views[v].camera.world_to_camera));
    to.push_back(centre(truth.views[size_t(t)].camera.world_to_camera));
  }
  const core::Similarity align = core::fit_similarity(from, to);
  Comparison c;
  std::vector<double> errors, reference;
  for (const auto& [v, t] : pairs) {
    const core::Mat3 aligned =
        processed.views[size_t(v)].camera.world_to_camera.rotation() * align.rotation.transposed();
    errors.push_back(angle_deg(aligned, truth.views[size_t(t)].camera.world_to_camera.rotation()));
    const std::string& name = processed.views[size_t(v)].name;
    if (name.size() > 2 && name.substr(name.size() - 2) == "_1") reference.push_back(errors.back());
    // The calibration's bias: sensor noise averages out over the view.
    const torch::Tensor got = processed.image(v), want = truth.image(t);
    const torch::Tensor mask = want > 0.05;
    const double bias = got.masked_select(mask).mean().item<double>() /
                            want.masked_select(mask).mean().item<double>() -
                        1;
    c.worst_reflectance = std::max(c.worst_reflectance, std::abs(bias));
  }
  std::sort(reference.begin(), reference.end());
  if (!reference.empty()) c.median_reference_deg = reference[reference.size() / 2];
  std::sort(errors.begin(), errors.end());
  c.worst_rotation_deg = errors.back();
  c.median_rotation_deg = errors[errors.size() / 2];
  c.views = pairs.size();
  return c;
}

std::string albedo_of(const fs::path& rig) {
  std::string out;
  const json synth = read_json(rig / "synth.json");
  for (const json& a : synth["panel_albedo"])
    out += (out.empty() ? "" : ",") + std::to_string(a.get<double>());
  return out;
}

TEST(RigCli, CapturesBecomeAReflectanceSceneThatTrainsLikeTheTruth) {
  const fs::path root = test::temp_dir("rig_cli");
  const fs::path rig = root / "rig";
  std::string out;
  ASSERT_EQ(
      ddhgs("synth --preset rig --width 96 --height 72 --views 16 --out " + rig.string(), &out), 0)
      << out;
  const std::string albedo = albedo_of(rig);
  const std::string given_poses =
      " --skip-colmap --poses " + (rig / "truth" / "transforms.json").string();
  // Through the panel, with the reference camera's true poses: the other
  // band cameras are placed by their rig rotations.
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --panel " +
                      (rig / "panel").string() + " --panel-albedo " + albedo + given_poses +
                      " --out " + (root / "panel_scene").string(),
                  &out),
            0)
      << out;
  const auto truth = io::load_scene(rig / "truth");
  const auto by_panel = io::load_scene(root / "panel_scene");
  ASSERT_EQ(by_panel->views.size(), 80u);  // 16 captures x 5 band cameras
  EXPECT_TRUE(by_panel->band_per_view());
  EXPECT_EQ(by_panel->wavelengths_nm, (std::vector<double>{475, 560, 668, 717, 842}));
  const Comparison panel = compare(*by_panel, *truth);
  std::printf("panel path: worst rotation %.2g deg, worst reflectance bias %.2f %%\n",
              panel.worst_rotation_deg, 100 * panel.worst_reflectance);
  EXPECT_LT(panel.worst_rotation_deg, 0.01);
  EXPECT_LT(panel.worst_reflectance, 0.02);  // within 2 % through the panel
  const json summary = read_json(root / "panel_scene" / "process.json");
  EXPECT_EQ(summary["cameras"][0]["reflectance_from"], "panel");
  // The split keeps a capture's bands together.
  const json transforms = read_json(root / "panel_scene" / "transforms.json");
  ASSERT_FALSE(transforms["test_filenames"].empty());
  EXPECT_EQ(transforms["test_filenames"].size() % 5, 0u);

  // Through each capture's DLS: the same reflectance.
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig" + given_poses + " --out " +
                      (root / "dls_scene").string(),
                  &out),
            0)
      << out;
  const Comparison dls = compare(*io::load_scene(root / "dls_scene"), *truth);
  EXPECT_LT(dls.worst_reflectance, 0.02);
  EXPECT_EQ(read_json(root / "dls_scene" / "process.json")["cameras"][2]["reflectance_from"],
            "DLS");

  // Trained with the truth's clean reflectance beside it, against the same
  // scene trained from the truth itself (clean data, exact poses).
  fs::copy(rig / "truth" / "clean", root / "panel_scene" / "clean");
  const std::string train = " --preset demo --iterations 600 --set output.test_every=0";
  ASSERT_EQ(ddhgs("train " + (root / "panel_scene").string() + " --out " + (root / "run").string() +
                      train,
                  &out),
            0)
      << out;
  ASSERT_EQ(
      ddhgs("train " + (rig / "truth").string() + " --out " + (root / "truth_run").string() + train,
            &out),
      0)
      << out;
  // And the same captures as registered cubes, one cube per capture with
  // every band, at the same iteration count: the rig scene must come close.
  ASSERT_EQ(
      ddhgs("train " + (rig / "cubes").string() + " --out " + (root / "cube_run").string() + train,
            &out),
      0)
      << out;
  const double psnr = read_json(root / "run" / "train_summary.json")["test_psnr_clean"];
  const double truth_psnr = read_json(root / "truth_run" / "train_summary.json")["test_psnr_clean"];
  const double cube_psnr = read_json(root / "cube_run" / "train_summary.json")["test_psnr_clean"];
  std::printf(
      "test PSNR vs clean: processed captures %.2f dB, truth scene %.2f dB, registered cubes "
      "%.2f dB\n",
      psnr, truth_psnr, cube_psnr);
  EXPECT_GT(psnr, truth_psnr - 1.0);
  EXPECT_GT(psnr, cube_psnr - 1.0);  // within 1 dB of the registered cubes

  // Every command a user runs next works on the rig scene.
  const std::string run = (root / "run").string();
  EXPECT_EQ(ddhgs("info " + (root / "panel_scene").string(), &out), 0) << out;
  EXPECT_EQ(ddhgs("eval " + run, &out), 0) << out;
  ASSERT_EQ(ddhgs("render " + run + " --index ndvi --out " + (root / "ndvi").string(), &out), 0)
      << out;
  EXPECT_TRUE(fs::exists(root / "ndvi" / "ndvi.json")) << out;
  ASSERT_EQ(ddhgs("report " + run, &out), 0) << out;
  // The page builds in a browser: the 3D view draws and recolours, and the
  // spectral viewer, with no whole-spectrum view to show, says why.
  std::string chromium;
  if (test::run_command("command -v chromium", &chromium) == 0) {
    chromium.erase(chromium.find_last_not_of(" \n") + 1);
    const fs::path profile = root / "chromium_profile";
    ASSERT_EQ(test::run_command(
                  test::python() + " " +
                      (test::source_dir() / "tests/app/report_browser_check.py").string() + " " +
                      chromium + " " + (root / "run/report/index.html").string() + " " +
                      (root / "report.png").string() + " " + profile.string() + " --no-viewer 2>&1",
                  &out),
              0)
        << out;
    EXPECT_NE(out.find("band-per-view scene"), std::string::npos) << out;
  }
  EXPECT_EQ(ddhgs("export " + run + " --out " + (root / "export.ply").string(), &out), 0) << out;

  // Bad input: one line, no output folder.
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --panel " +
                      (rig / "panel").string() + " --panel-albedo 0.5,0.5" + given_poses +
                      " --out " + (root / "bad").string(),
                  &out),
            1);
  EXPECT_NE(out.find("5 band cameras but 2 panel albedo values"), std::string::npos) << out;
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --panel " +
                      (rig / "panel").string() + given_poses + " --out " + (root / "bad").string(),
                  &out),
            1);
  EXPECT_NE(out.find("--panel-albedo"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "bad"));
}

// The panel lies off-centre beside its QR label, as in a real panel capture:
// found in every band, shown in SCENE/panel/, described in process.json. Bad
// rig input stops before any work with one line and nothing left behind.
TEST(RigCli, PanelFoundWhereItLiesAndBadRigInputStopsFirst) {
  const fs::path root = test::temp_dir("rig_cli_panel");
  const fs::path rig = root / "rig";
  std::string out;
  ASSERT_EQ(
      ddhgs("synth --preset rig --width 160 --height 120 --views 4 --out " + rig.string(), &out), 0)
      << out;
  const std::string albedo = albedo_of(rig);
  const std::string poses =
      " --skip-colmap --poses " + (rig / "truth" / "transforms.json").string();
  const std::string process = "process " + (rig / "captures").string() + " --rig ";
  ASSERT_EQ(ddhgs(process + "--panel " + (rig / "panel").string() + " --panel-albedo " + albedo +
                      poses + " --out " + (root / "scene").string(),
                  &out),
            0)
      << out;
  const json summary = read_json(root / "scene" / "process.json");
  ASSERT_EQ(summary["cameras"].size(), 5u);
  for (const json& camera : summary["cameras"]) {
    const json& panel = camera["panel"];
    EXPECT_EQ(panel["region"], "found") << panel.dump();
    EXPECT_EQ(panel["saturated_pixels"], 0) << panel.dump();
    EXPECT_GT(panel["pixels"].get<int>(), 300) << panel.dump();
    // The synthetic panel: 36 px square at x 88 + shift, y 42 + shift / 2;
    // its middle two thirds lie inside it.
    for (const json& corner : panel["corners_xy"]) {
      EXPECT_GE(corner[0].get<double>(), 88) << panel.dump();
      EXPECT_LE(corner[0].get<double>(), 88 + 36 + 5) << panel.dump();
    }
    EXPECT_TRUE(fs::is_regular_file(root / "scene" / panel["picture"].get<std::string>()));
    EXPECT_NEAR(panel["irradiance"].get<double>() * camera["panel_albedo"].get<double>() / M_PI,
                camera["panel_radiance"].get<double>(), 1e-9);
  }
  // A region given instead, for one camera; the others still found.
  ASSERT_EQ(
      ddhgs(process + "--panel " + (rig / "panel").string() + " --panel-albedo " + albedo +
                " --panel-region 2:95,50,10,10" + poses + " --out " + (root / "given").string(),
            &out),
      0)
      << out;
  const json given = read_json(root / "given" / "process.json");
  EXPECT_EQ(given["cameras"][1]["panel"]["region"], "given (--panel-region)");
  EXPECT_EQ(given["cameras"][1]["panel"]["pixels"], 100);
  EXPECT_EQ(given["cameras"][0]["panel"]["region"], "found");

  auto refused = [&](const std::string& args, const std::string& said) {
    const fs::path bad = root / "bad";
    EXPECT_EQ(ddhgs(args + " --out " + bad.string(), &out), 1) << args << "\n" << out;
    EXPECT_NE(out.find(said), std::string::npos) << args << "\n" << out;
    EXPECT_FALSE(fs::exists(bad)) << args;
    for (const auto& entry : fs::directory_iterator(root))  // no temporary folder left
      EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
  };
  // The rig's own camera numbers (1 to 5 here); others are named and refused.
  refused(process + "--reference-camera -1" + poses, "its cameras: 1, 2, 3, 4, 5");
  refused(process + "--reference-camera 0" + poses, "0 is not a band camera of the rig");
  refused(process + "--panel " + (rig / "panel").string() + " --panel-albedo " + albedo +
              " --panel-region 9:1,1,5,5" + poses,
          "--panel-region: 9 is not a band camera");
  // One capture cannot be posed: refused before COLMAP runs.
  fs::create_directories(root / "one");
  for (int k = 1; k <= 5; ++k)
    fs::copy(rig / "captures" / ("IMG_0000_" + std::to_string(k) + ".tif"), root / "one");
  refused("process " + (root / "one").string() + " --rig", "at least 3 overlapping captures");
  // No panel in a flight capture given as the panel: the band image beside
  // the output to look at.
  fs::create_directories(root / "not_panel");
  for (int k = 1; k <= 5; ++k)
    fs::copy(rig / "panel" / ("PANL_0000_" + std::to_string(k) + ".tif"), root / "not_panel");
  for (int k = 1; k <= 5; ++k)
    fs::copy_file(rig / "captures" / ("IMG_0001_" + std::to_string(k) + ".tif"),
                  root / "not_panel" / ("PANL_0000_" + std::to_string(k) + ".tif"),
                  fs::copy_options::overwrite_existing);
  refused(
      process + "--panel " + (root / "not_panel").string() + " --panel-albedo " + albedo + poses,
      "no calibration panel found");
  EXPECT_NE(out.find("bad.panel.png"), std::string::npos) << out;
  EXPECT_TRUE(fs::is_regular_file(root / "bad.panel.png"));
}

// A strip of 8 consecutive nadir captures at 70 % overlap trains
// with default settings (the middle capture held out). The default's extra
// random points are left out for such a one-sided capture; with them this
// scene reached 26.4 dB instead of 31.7 (docs/benchmarks.md).
TEST(RigCli, NadirStripTrainsWithDefaultSettings) {
  const fs::path root = test::temp_dir("rig_cli_nadir");
  const fs::path rig = root / "rig";
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --out " + rig.string(), &out), 0) << out;
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --panel " +
                      (rig / "panel").string() + " --panel-albedo " + albedo_of(rig) +
                      " --skip-colmap --poses " + (rig / "truth" / "transforms.json").string() +
                      " --out " + (root / "scene").string(),
                  &out),
            0)
      << out;
  const json transforms = read_json(root / "scene" / "transforms.json");
  ASSERT_EQ(transforms["test_filenames"].size(), 5u) << transforms.dump();  // one capture
  EXPECT_NE(transforms["test_filenames"][0].get<std::string>().find("IMG_0004"), std::string::npos);
  fs::copy(rig / "truth" / "clean", root / "scene" / "clean");
  // The mat under the plant fills the frame: within the tolerance of the
  // grey backdrop's colour on most of the border, but no backdrop. info,
  // training and eval agree.
  ASSERT_EQ(ddhgs("info " + (root / "scene").string(), &out), 0) << out;
  EXPECT_NE(out.find("backdrop    none (the border's colour fills the middle of"),
            std::string::npos)
      << out;
  ASSERT_EQ(ddhgs("train " + (root / "scene").string() + " --out " + (root / "run").string() +
                      " --iterations 1500 --set output.test_every=0",
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("a one-sided capture): no extra random points"), std::string::npos) << out;
  EXPECT_NE(out.find("background starts from model.background"), std::string::npos) << out;
  const double psnr = read_json(root / "run" / "train_summary.json")["test_psnr_clean"];
  std::printf("nadir strip, held-out capture: %.2f dB against clean truth\n", psnr);
  EXPECT_GT(psnr, 29.0);
  ASSERT_EQ(ddhgs("eval " + (root / "run").string() + " --fps-repeats 0", &out), 0) << out;
  EXPECT_EQ(out.find("object"), std::string::npos) << out;
  EXPECT_FALSE(read_json(root / "run" / "eval" / "metrics.json").contains("backdrop"));
}

// Poses in a unit of their own (here half a metre, as COLMAP's frame has an
// arbitrary one): the GPS fit's scale gives the scene its metres per unit,
// so the rig's corrections and lever arms read in cm.
TEST(RigCli, PosesInAnUnknownUnitTakeTheGeoreferencesScale) {
  const fs::path root = test::temp_dir("rig_cli_unit");
  const fs::path rig = root / "rig";
  std::string out;
  ASSERT_EQ(ddhgs("synth --preset rig-nadir --out " + rig.string(), &out), 0) << out;
  json poses = read_json(rig / "truth" / "transforms.json");
  ASSERT_EQ(poses["rig"]["unit_m"].get<double>(), 1.0);
  poses["rig"].erase("unit_m");
  poses.erase("ply_file_path");
  for (json& frame : poses["frames"])
    for (int r = 0; r < 3; ++r)
      frame["transform_matrix"][r][3] = 2 * frame["transform_matrix"][r][3].get<double>();
  io::write_file_atomically(rig / "truth" / "half_metres.json", poses.dump());
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --skip-colmap --poses " +
                      (rig / "truth" / "half_metres.json").string() + " --out " +
                      (root / "scene").string(),
                  &out),
            0)
      << out;
  const double scale = read_json(root / "scene" / "georef.json")["scene_to_crs"]["scale"];
  EXPECT_NEAR(scale, 0.5, 1e-6);
  EXPECT_EQ(read_json(root / "scene" / "transforms.json")["rig"]["unit_m"].get<double>(), scale);
  ASSERT_EQ(ddhgs("info " + (root / "scene").string(), &out), 0) << out;
  EXPECT_NE(out.find("rig         5 band cameras, posed from camera "), std::string::npos) << out;
  EXPECT_NE(out.find("; 0.5 m per scene unit (corrections and lever arms in cm)"),
            std::string::npos)
      << out;
}

// COLMAP poses the reference camera's images; every band camera follows by
// its rig rotation. Sized by the environment like the cube process test.
TEST(RigCli, ColmapPosesEveryBandCamera) {
  std::string out;
  if (test::run_command("command -v colmap", &out) != 0)
    GTEST_SKIP() << "colmap is not installed (scripts/setup.sh installs it)";
  const fs::path root = test::temp_dir("rig_cli_colmap");
  const fs::path rig = root / "rig";
  ASSERT_EQ(ddhgs("synth --preset rig " +
                      env_or("DDHGS_RIG_SYNTH", "--width 320 --height 240 --views 36") + " --out " +
                      rig.string(),
                  &out),
            0)
      << out;
  ASSERT_EQ(ddhgs("process " + (rig / "captures").string() + " --rig --panel " +
                      (rig / "panel").string() + " --panel-albedo " + albedo_of(rig) + " " +
                      env_or("DDHGS_RIG_PROCESS_ARGS",
                             "--colmap-set Mapper.tri_min_angle=3 "
                             "--colmap-set Mapper.filter_max_reproj_error=1") +
                      " --out " + (root / "scene").string(),
                  &out),
            0)
      << out;
  const json summary = read_json(root / "scene" / "process.json");
  const auto scene = io::load_scene(root / "scene");
  const Comparison c = compare(*scene, *io::load_scene(rig / "truth"));
  std::printf(
      "COLMAP: %zu of %d band images posed; rotation error median %.3f (reference camera "
      "%.3f), worst %.3f deg; worst reflectance bias %.2f %%\n",
      c.views, summary["band_images"].get<int>(), c.median_rotation_deg, c.median_reference_deg,
      c.worst_rotation_deg, 100 * c.worst_reflectance);
  EXPECT_EQ(summary["posed_band_images"], summary["band_images"]);
  // Measured 0.09 / 0.24 degrees at this size (docs/benchmarks.md); the
  // 0.1-degree bar for every camera holds at 640x480
  // (scripts/rig_pose_benchmark.sh).
  EXPECT_LT(c.median_rotation_deg, std::stod(env_or("DDHGS_RIG_MEDIAN_ROTATION_DEG", "0.2")));
  EXPECT_LT(c.worst_rotation_deg, std::stod(env_or("DDHGS_RIG_WORST_ROTATION_DEG", "0.5")));
  EXPECT_LT(c.worst_reflectance, 0.02);
}

}  // namespace
}  // namespace ddhgs
