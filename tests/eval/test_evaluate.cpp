// Evaluation and rendering of a model on a small scene written to disk: the
// stored views are the model's own renders plus noise, the clean views its
// exact renders, so every expected number is known.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "core/error.h"
#include "core/tensor.h"
#include "eval/evaluate.h"
#include "eval/render_frames.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"

namespace ddhgs::eval {
namespace {
namespace fs = std::filesystem;

constexpr int kWidth = 24, kHeight = 20, kViews = 4;
const std::vector<double> kWavelengths = {500, 550, 600, 650};

model::Gaussians make_gaussians() {
  torch::manual_seed(3);
  const int64_t g = 40, n = int64_t(kWavelengths.size());
  model::Gaussians m;
  m.means = torch::rand({g, 3}) - 0.5;
  m.log_scales = torch::full({g, 3}, std::log(0.12f));
  m.quats = torch::tensor({1.0f, 0.0f, 0.0f, 0.0f}).repeat({g, 1});
  m.logit_opacities = torch::full({g, 1}, 1.5f);
  m.sh_dc = (torch::rand({g, n}) * 0.8 + 0.1 - 0.5) / model::kShC0;
  m.sh_rest = torch::zeros({g, n, 0});
  m.active_sh_degree = 0;
  return m;
}

core::Camera ring_camera(int i) {
  double t = 2 * M_PI * i / kViews;
  core::Camera cam;
  cam.intrinsics = {30, 30, kWidth / 2.0, kHeight / 2.0, kWidth, kHeight};
  cam.world_to_camera =
      core::look_at({3 * std::cos(t), 3 * std::sin(t), 0.8}, {0, 0, 0}, {0, 0, 1});
  return cam;
}

std::string stem(int i) {
  return "v" + std::to_string(i);
}

// Writes the dataset; views 1 and 3 are the test split.
fs::path write_scene(const model::Gaussians& gaussians, const torch::Tensor& background) {
  fs::path dir = test::temp_dir("eval_scene");
  fs::create_directories(dir / "hyperspectral");
  fs::create_directories(dir / "clean");
  io::TransformsFile tf;
  tf.wavelengths_nm = kWavelengths;
  for (int i = 0; i < kViews; ++i) {
    core::Camera cam = ring_camera(i);
    torch::Tensor clean = model::render_gaussians(gaussians, cam, background).image.detach();
    torch::Tensor noisy = (clean + 0.02 * torch::randn_like(clean)).clamp(0, 1);
    io::write_npy(dir / "hyperspectral" / (stem(i) + ".npy"), noisy);
    io::write_npy(dir / "clean" / (stem(i) + ".npy"), clean);
    io::TransformsFrame frame;
    frame.file_path = "images/" + stem(i) + ".png";
    frame.hyperspectral_file_path = "hyperspectral/" + stem(i) + ".npy";
    frame.intrinsics = cam.intrinsics;
    frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(cam.world_to_camera);
    tf.frames.push_back(frame);
    (i % 2 ? tf.test_files : tf.train_files).push_back(frame.file_path);
  }
  io::write_transforms(dir / "transforms.json", tf);
  return dir;
}

class EvalScene : public ::testing::Test {
 protected:
  void SetUp() override {
    gaussians = make_gaussians();
    background = torch::zeros({int64_t(kWavelengths.size())});
    scene = io::load_scene(write_scene(gaussians, background));
  }
  model::Gaussians gaussians;
  torch::Tensor background;
  std::unique_ptr<io::Scene> scene;
};

TEST_F(EvalScene, MetricsAgainstStoredAndCleanViews) {
  ASSERT_EQ(scene->test, (std::vector<int>{1, 3}));
  ASSERT_TRUE(scene->has_clean());
  EvalOptions options;
  options.fps_repeats = 3;
  EvalReport report = evaluate(*scene, gaussians, background, scene->test, "test", options);
  ASSERT_EQ(report.per_view.size(), 4u);
  EXPECT_EQ(report.per_view[0].view, "v1");
  EXPECT_EQ(report.per_view[0].truth, "views");
  EXPECT_EQ(report.per_view[1].truth, "clean");
  EXPECT_EQ(report.width, kWidth);
  EXPECT_EQ(report.gaussians, 40);

  // Against the clean views the model is perfect.
  ASSERT_TRUE(report.mean_clean.has_value());
  EXPECT_DOUBLE_EQ(report.mean_clean->psnr_db, kMaxPsnrDb);
  EXPECT_NEAR(report.mean_clean->ssim, 1.0, 1e-9);
  // Against the noisy views: the mean of the per-view metrics, noise-limited.
  std::vector<ImageMetrics> direct;
  for (int v : scene->test)
    direct.push_back(compute_metrics(
        model::render_gaussians(gaussians, scene->views[size_t(v)].camera, background).image,
        scene->image(v)));
  ImageMetrics expected = mean_metrics(direct);
  EXPECT_NEAR(report.mean.psnr_db, expected.psnr_db, 1e-9);
  EXPECT_NEAR(report.mean.sam_rad, expected.sam_rad, 1e-12);
  EXPECT_GT(report.mean.psnr_db, 30);
  EXPECT_LT(report.mean.psnr_db, 40);
  ASSERT_EQ(report.mean.band_psnr_db.size(), kWavelengths.size());

  ASSERT_TRUE(report.timing.has_value());
  EXPECT_EQ(report.timing->repeats, 3);
  EXPECT_EQ(report.timing->views, 2);
  EXPECT_GT(report.timing->fps(), 0);
  std::string table = format_report(report);
  EXPECT_NE(table.find("clean"), std::string::npos);
  EXPECT_NE(table.find("FPS"), std::string::npos);
}

TEST_F(EvalScene, MeasureViewClampsToTheReflectanceRangeAndGivesBandRmse) {
  const int v = scene->test.front();
  // A render with values outside [0, 1] is measured as its clamped picture.
  const torch::Tensor over = render_view(*scene, gaussians, background, v) * 3 - 1;  // [H, W, N]
  const torch::Tensor clamped = over.clamp(0, 1);
  const ViewMetrics m = measure_view(*scene, v, over);
  EXPECT_DOUBLE_EQ(m.stored.psnr_db, compute_metrics(clamped, scene->image(v)).psnr_db);
  EXPECT_DOUBLE_EQ(m.stored.ssim, compute_metrics(clamped, scene->image(v)).ssim);
  ASSERT_TRUE(m.clean.has_value());
  EXPECT_DOUBLE_EQ(m.clean->sam_rad, compute_metrics(clamped, scene->clean_image(v)).sam_rad);
  // Per-band RMSE, by hand.
  const torch::Tensor diff = clamped.to(torch::kDouble) - scene->image(v).to(torch::kDouble);
  ASSERT_EQ(m.stored.band_rmse.size(), kWavelengths.size());
  for (int64_t b = 0; b < int64_t(kWavelengths.size()); ++b)
    EXPECT_NEAR(m.stored.band_rmse[size_t(b)],
                diff.select(2, b).square().mean().sqrt().item<double>(), 1e-12);
}

TEST_F(EvalScene, WritesMetricsJsonAndCsv) {
  EvalOptions options;
  options.fps_repeats = 1;
  EvalReport report =
      evaluate(*scene, gaussians, background, split_views(*scene, "all"), "all", options);
  fs::path dir = test::temp_dir("eval_out");
  write_metrics_json(dir / "metrics.json", report);
  write_per_view_csv(dir / "per_view.csv", report);
  auto j = nlohmann::json::parse(io::read_file(dir / "metrics.json"));
  EXPECT_EQ(j["split"], "all");
  EXPECT_EQ(j["views"], kViews);
  EXPECT_NEAR(j["psnr"].get<double>(), report.mean.psnr_db, 1e-9);
  EXPECT_NEAR(j["clean"]["sam"].get<double>(), report.mean_clean->sam_rad, 1e-12);
  EXPECT_EQ(j["per_band_psnr"]["wavelengths_nm"].get<std::vector<double>>(), kWavelengths);
  EXPECT_EQ(j["per_band_psnr"]["psnr"].size(), kWavelengths.size());
  EXPECT_GT(j["fps"].get<double>(), 0);
  std::ifstream csv(dir / "per_view.csv");
  std::string line;
  int lines = 0;
  std::getline(csv, line);
  EXPECT_EQ(line, "view,truth,psnr_db,ssim,sam_rad,rmse");
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 2 * kViews);
}

TEST(MeasureObject, ObjectAndInteriorOfAMaskedView) {
  // A 6 x 7 two-band view on the backdrop (1.0, 0.5) with a 4 x 4 object.
  torch::Tensor truth = torch::empty({6, 7, 2});
  truth.select(2, 0).fill_(1.0);
  truth.select(2, 1).fill_(0.5);
  truth.slice(0, 1, 5).slice(1, 2, 6).fill_(0.2);
  torch::Tensor render = truth.clone();
  render[1][2][0] = 0.3f;  // the object's corner, on its outline: 0.1 off in one band
  render[0][0][0] = 1.5f;  // backdrop, clamped to 1 as measure_view clamps
  const auto m = measure_object(render, truth, torch::tensor({1.0f, 0.5f}));
  ASSERT_TRUE(m.has_value());
  EXPECT_NEAR(m->share, 16.0 / 42, 1e-12);
  // MSE over 16 pixels x 2 bands: 0.01 / 32 (float32 inputs: 0.3 - 0.2 to 1e-7).
  EXPECT_NEAR(m->object.psnr_db, 10 * std::log10(3200.0), 1e-4);
  ASSERT_TRUE(m->interior.has_value());
  EXPECT_DOUBLE_EQ(m->interior->psnr_db, kMaxPsnrDb);  // the error sits on the outline
  // A view of nothing but backdrop has no object to measure.
  const torch::Tensor blank = torch::tensor({1.0f, 0.5f}).repeat({6, 7, 1});
  EXPECT_FALSE(measure_object(blank, blank, torch::tensor({1.0f, 0.5f})).has_value());
}

TEST_F(EvalScene, MaskedScenesAlsoMeasureTheObject) {
  EvalOptions options;
  options.fps_repeats = 0;
  options.backdrop = background;  // the renders' black backdrop
  EvalReport report = evaluate(*scene, gaussians, background, scene->test, "test", options);
  ASSERT_TRUE(report.mean_object.has_value());
  ASSERT_TRUE(report.mean_object_clean.has_value());
  // The model is the clean truth, object and all.
  EXPECT_DOUBLE_EQ(report.mean_object_clean->object.psnr_db, kMaxPsnrDb);
  // Against the noisy views: the mean of measure_object over the views.
  std::vector<RegionMetrics> direct;
  for (int v : scene->test) {
    const torch::Tensor image =
        model::render_gaussians(gaussians, scene->views[size_t(v)].camera, background).image;
    direct.push_back(measure_object(image, scene->image(v), background)->object);
  }
  EXPECT_NEAR(report.mean_object->object.psnr_db, mean_region_metrics(direct).psnr_db, 1e-9);
  EXPECT_GT(report.mean_object->share, 0);
  EXPECT_LT(report.mean_object->share, 1);
  ASSERT_TRUE(report.per_view[0].object.has_value());

  const fs::path dir = test::temp_dir("eval_masked");
  write_metrics_json(dir / "metrics.json", report);
  write_per_view_csv(dir / "per_view.csv", report);
  const auto j = nlohmann::json::parse(io::read_file(dir / "metrics.json"));
  EXPECT_NEAR(j["object"]["psnr"].get<double>(), report.mean_object->object.psnr_db, 1e-9);
  EXPECT_EQ(j["backdrop"]["value"].get<std::vector<double>>(), std::vector<double>(4, 0.0));
  EXPECT_DOUBLE_EQ(j["clean"]["object"]["psnr"].get<double>(), kMaxPsnrDb);
  std::ifstream csv(dir / "per_view.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line,
            "view,truth,psnr_db,ssim,sam_rad,rmse,object_share,object_psnr_db,object_sam_rad,"
            "interior_psnr_db,interior_sam_rad");
  const std::string table = format_report(report);
  EXPECT_NE(table.find("   object "), std::string::npos) << table;
  EXPECT_NE(table.find("unlike the backdrop"), std::string::npos) << table;
}

TEST_F(EvalScene, AlignedPosesMeasureTheModelApartFromAPoseError) {
  EvalOptions options;
  options.fps_repeats = 0;
  const EvalReport right = evaluate(*scene, gaussians, background, scene->test, "test", options);
  // View 3's recorded pose turned by 0.05 rad (about 1.5 px here): its
  // stored views were taken from the pose before.
  core::Camera& camera = scene->views[3].camera;
  const core::Mat3 r = camera.world_to_camera.rotation();
  core::Mat3 turn;
  turn(0, 0) = std::cos(0.05), turn(0, 2) = std::sin(0.05);
  turn(2, 0) = -std::sin(0.05), turn(2, 2) = std::cos(0.05);
  const core::Vec3 centre = camera.center();
  camera.world_to_camera = core::Mat4::from(turn * r, (turn * r * centre) * -1.0);

  options.align = AlignOptions{200, 1.0};
  const EvalReport report = evaluate(*scene, gaussians, background, scene->test, "test", options);
  ASSERT_EQ(report.per_view.size(), 4u);
  const ViewResult &v1 = report.per_view[0], &v3 = report.per_view[2];
  ASSERT_EQ(v3.view, "v3");
  ASSERT_TRUE(v1.aligned && v3.aligned);
  EXPECT_FALSE(report.per_view[1].aligned) << "clean rows are not aligned";
  // View 1's pose is right: aligning cannot lose, and finds little.
  EXPECT_DOUBLE_EQ(v1.metrics.psnr_db, right.per_view[0].metrics.psnr_db);
  EXPECT_GE(v1.aligned->metrics.psnr_db, v1.metrics.psnr_db - 0.05);
  EXPECT_LT(v1.aligned->motion_px, 0.2);
  // View 3: the wrong pose costs, the aligned pose gets the model's figure back.
  EXPECT_LT(v3.metrics.psnr_db, right.per_view[2].metrics.psnr_db - 5);
  EXPECT_NEAR(v3.aligned->metrics.psnr_db, right.per_view[2].metrics.psnr_db, 1.0);
  EXPECT_TRUE(v3.aligned->moved);
  EXPECT_NEAR(v3.aligned->motion_px, 1.5, 0.4);
  ASSERT_TRUE(report.mean_aligned.has_value());
  EXPECT_NEAR(report.mean_aligned->psnr_db,
              0.5 * (v1.aligned->metrics.psnr_db + v3.aligned->metrics.psnr_db), 1e-9);

  const fs::path dir = test::temp_dir("eval_aligned");
  write_metrics_json(dir / "metrics.json", report);
  write_per_view_csv(dir / "per_view.csv", report);
  const auto j = nlohmann::json::parse(io::read_file(dir / "metrics.json"));
  EXPECT_NEAR(j["aligned"]["psnr"].get<double>(), report.mean_aligned->psnr_db, 1e-9);
  EXPECT_EQ(j["aligned"]["steps"], 200);
  EXPECT_GE(j["aligned"]["moved_views"].get<int>(), 1);
  std::ifstream csv(dir / "per_view.csv");
  std::string header, row1, row1_clean;
  std::getline(csv, header);
  std::getline(csv, row1);
  std::getline(csv, row1_clean);
  EXPECT_EQ(header,
            "view,truth,psnr_db,ssim,sam_rad,rmse,aligned_psnr_db,aligned_ssim,aligned_sam_rad,"
            "aligned_rmse,aligned_motion_px");
  EXPECT_EQ(std::count(row1.begin(), row1.end(), ','), 10) << row1;
  EXPECT_EQ(row1_clean.substr(row1_clean.size() - 5), ",,,,,") << row1_clean;
  const std::string table = format_report(report);
  EXPECT_NE(table.find("  aligned "), std::string::npos) << table;
  EXPECT_NE(table.find("poses aligned to the views"), std::string::npos) << table;
}

TEST_F(EvalScene, RejectsBandMismatchAndUnknownSplit) {
  model::Gaussians three = gaussians;
  three.sh_dc = gaussians.sh_dc.narrow(1, 0, 3);
  three.sh_rest = gaussians.sh_rest.narrow(1, 0, 3);
  EXPECT_THROW(evaluate(*scene, three, background.narrow(0, 0, 3), scene->test, "test"),
               core::Error);
  EXPECT_THROW(split_views(*scene, "val"), core::Error);
}

TEST_F(EvalScene, RendersCubesPicturesAndComparisons) {
  RenderOptions options;
  const fs::path out = test::temp_dir("eval_render");
  options.format = OutputFormat::Npy;
  options.diff = true;
  int files =
      render_frames(*scene, gaussians, background, view_frames(*scene, scene->test), options, out);
  EXPECT_EQ(files, 2 * 4 + 1);  // and channels.json: the scene's wavelengths
  EXPECT_EQ(nlohmann::json::parse(io::read_file(out / "channels.json"))["wavelengths_nm"],
            nlohmann::json(kWavelengths));
  io::Cube cube = io::read_cube(out / "v1.npy");
  torch::Tensor expected =
      model::render_gaussians(gaussians, scene->views[1].camera, background).image;
  EXPECT_TRUE(torch::allclose(cube_to_float(cube), expected));
  EXPECT_EQ(io::read_image(out / "v1_rgb.png").sizes(), (std::vector<int64_t>{kHeight, kWidth, 3}));
  // The model equals the clean truth: the error heatmap is the colour of 0.
  torch::Tensor heat = io::read_image(out / "v3_rgb_diff_max0.1.png");
  EXPECT_EQ(heat[5][5][0].item<uint8_t>(), 68);  // viridis(0) = (0.267, 0.005, 0.329)
  torch::Tensor compare = io::read_image(out / "v3_rgb_compare.png");
  EXPECT_EQ(compare.sizes(), (std::vector<int64_t>{kHeight + 4 + 12, 3 * kWidth + 8, 3}));
}

TEST_F(EvalScene, RendersEnviBandsAndOrbitFrames) {
  RenderOptions options;
  const fs::path out = test::temp_dir("eval_orbit");
  options.format = OutputFormat::Envi;
  options.bands = select_bands("", "540:610", scene->wavelengths_nm);
  options.colormap = Colormap::Gray;
  options.diff = true;  // orbit frames have no ground truth: no heatmaps
  std::vector<Frame> frames = orbit_frames(*scene, 3);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].name, "orbit_002");
  EXPECT_EQ(render_frames(*scene, gaussians, background, frames, options, out), 3 * 3 + 1);
  io::Cube cube = io::read_cube(out / "orbit_001.hdr");
  EXPECT_EQ(cube.bands(), 4);
  EXPECT_EQ(cube.wavelengths_nm, kWavelengths);
  // A grey picture of bands 550 and 600 nm: every channel equal.
  torch::Tensor pic = io::read_image(out / "orbit_001_540-610nm.png");
  EXPECT_TRUE(torch::equal(pic.select(2, 0), pic.select(2, 2)));
  EXPECT_FALSE(fs::exists(out / "orbit_001_540-610nm_compare.png"));
}

}  // namespace
}  // namespace ddhgs::eval
