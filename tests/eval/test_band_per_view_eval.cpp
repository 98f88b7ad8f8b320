// Pictures and figures of band-per-view scenes (each view holds one band, as
// a multispectral rig's band cameras do), on a scene written to disk whose
// clean views are the model's own renders: every expected value is known.
// Views of one capture share a camera (one cube split into its bands) or, as
// on a rig, each band camera looks along its own rotation.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include "core/colour.h"
#include "core/error.h"
#include "eval/evaluate.h"
#include "eval/render_frames.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/transforms/transforms.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::eval {
namespace {
namespace fs = std::filesystem;

constexpr int kWidth = 24, kHeight = 20, kCaptures = 4;
// MicaSense's green, red, red edge and NIR: NDVI's bands are among them.
const std::vector<double> kWavelengths = {560, 668, 717, 842};
constexpr int64_t kBands = 4;

model::Gaussians make_gaussians() {
  torch::manual_seed(5);
  const int64_t g = 40;
  model::Gaussians m;
  m.means = torch::rand({g, 3}) - 0.5;
  m.log_scales = torch::full({g, 3}, std::log(0.12f));
  m.quats = torch::tensor({1.0f, 0.0f, 0.0f, 0.0f}).repeat({g, 1});
  m.logit_opacities = torch::full({g, 1}, 1.5f);
  m.sh_dc = (torch::rand({g, kBands}) * 0.8 + 0.1 - 0.5) / model::kShC0;
  m.sh_rest = torch::zeros({g, kBands, 0});
  m.active_sh_degree = 0;
  return m;
}

// Capture i's camera for band b: one pose for all bands, or (rig) turned
// by a degree per band about the camera's y axis.
core::Camera camera(int i, int b, bool rig) {
  const double t = 2 * M_PI * i / kCaptures;
  core::Camera cam;
  cam.intrinsics = {30, 30, kWidth / 2.0, kHeight / 2.0, kWidth, kHeight};
  cam.world_to_camera =
      core::look_at({3 * std::cos(t), 3 * std::sin(t), 0.8}, {0, 0, 0}, {0, 0, 1});
  if (rig && b > 0) {
    const double a = b * M_PI / 180;
    core::Mat4 turn;
    turn(0, 0) = std::cos(a);
    turn(0, 2) = std::sin(a);
    turn(2, 0) = -std::sin(a);
    turn(2, 2) = std::cos(a);
    cam.world_to_camera = turn * cam.world_to_camera;
  }
  return cam;
}

// c<i>_b<b>.npy: band b of capture i as its camera sees it, stored with noise
// and clean; captures 1 and 3 are the test split.
fs::path write_band_scene(const model::Gaussians& gaussians, const torch::Tensor& background,
                          bool rig) {
  const fs::path dir = test::temp_dir(rig ? "bpv_eval_rig" : "bpv_eval_split");
  fs::create_directories(dir / "bands");
  fs::create_directories(dir / "clean");
  io::TransformsFile tf;
  tf.wavelengths_nm = kWavelengths;
  for (int i = 0; i < kCaptures; ++i)
    for (int b = 0; b < int(kBands); ++b) {
      const core::Camera cam = camera(i, b, rig);
      const torch::Tensor clean =
          model::render_gaussians(gaussians, cam, background).image.detach().narrow(2, b, 1);
      const torch::Tensor noisy = (clean + 0.02 * torch::randn_like(clean)).clamp(0, 1);
      const std::string name = "c" + std::to_string(i) + "_b" + std::to_string(b) + ".npy";
      io::write_npy(dir / "bands" / name, noisy.contiguous());
      io::write_npy(dir / "clean" / name, clean.contiguous());
      io::TransformsFrame frame;
      frame.hyperspectral_file_path = "bands/" + name;
      frame.bands = {b};
      frame.intrinsics = cam.intrinsics;
      frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(cam.world_to_camera);
      tf.frames.push_back(frame);
      (i % 2 ? tf.test_files : tf.train_files).push_back(frame.hyperspectral_file_path);
    }
  io::write_transforms(dir / "transforms.json", tf);
  return dir;
}

class BandPerView : public ::testing::Test {
 protected:
  void SetUp() override {
    gaussians = make_gaussians();
    background = torch::zeros({kBands});
  }
  std::unique_ptr<io::Scene> load(bool rig) {
    auto scene = io::load_scene(write_band_scene(gaussians, background, rig));
    EXPECT_TRUE(scene->band_per_view());
    EXPECT_EQ(scene->test.size(), size_t(2 * kBands));
    return scene;
  }
  model::Gaussians gaussians;
  torch::Tensor background;
};

size_t files_in(const fs::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++n;
  return n;
}

TEST_F(BandPerView, DiffComparesEachViewOnItsOwnBand) {
  const auto scene = load(true);
  RenderOptions options;
  options.diff = true;
  const fs::path out = test::temp_dir("bpv_eval_diff");
  const std::vector<Frame> frames = view_frames(*scene, scene->test);
  // Per frame: the pseudo-RGB picture, then the heatmap and the comparison;
  // and channels.json.
  EXPECT_EQ(render_frames(*scene, gaussians, background, frames, options, out),
            1 + int(3 * frames.size()));
  // Capture 1's red-edge view (band 2) against its clean truth, which the
  // model renders exactly: truth and render panels alike, error zero.
  const torch::Tensor compare = io::read_image(out / "c1_b2_band2_compare.png");
  ASSERT_EQ(compare.sizes(), (std::vector<int64_t>{kHeight + 4 + 12, 3 * kWidth + 8, 3}));
  const torch::Tensor truth_panel = compare.narrow(0, 0, kHeight).narrow(1, 0, kWidth);
  const torch::Tensor render_panel = compare.narrow(0, 0, kHeight).narrow(1, kWidth + 4, kWidth);
  EXPECT_TRUE(torch::equal(truth_panel, render_panel));
  // The truth panel is the view's own band through viridis, not a mean of
  // every band: it matches the band it holds and differs from another one.
  const int v = int(std::find_if(scene->views.begin(), scene->views.end(),
                                 [](const io::View& w) { return w.name == "c1_b2"; }) -
                    scene->views.begin());
  const torch::Tensor own =
      core::to_u8(apply_colormap(scene->clean_image(v).select(2, 0), Colormap::Viridis));
  EXPECT_TRUE(torch::equal(truth_panel, own));
  const torch::Tensor heat = io::read_image(out / "c1_b2_band2_diff_max0.1.png");
  EXPECT_EQ(heat[5][5][0].item<uint8_t>(), 68);  // viridis(0) = (0.267, 0.005, 0.329)

  // --band 3: only the NIR views are compared, under the selection's name.
  const fs::path nir = test::temp_dir("bpv_eval_band3");
  options.bands = select_bands("3", "", scene->wavelengths_nm);
  EXPECT_EQ(render_frames(*scene, gaussians, background, frames, options, nir),
            1 + int(frames.size() + 2 * 2));
  EXPECT_TRUE(fs::exists(nir / "c3_b3_band3_compare.png"));
  EXPECT_FALSE(fs::exists(nir / "c3_b1_band3_compare.png"));

  // Truth mapped to other wavelengths would need every band of a view.
  options.bands = BandSelection{};
  options.band_map = torch::eye(kBands, torch::kFloat64);
  options.wavelengths_nm = kWavelengths;
  const std::string e = test::error_of([&] {
    render_frames(*scene, gaussians, background, frames, options, test::temp_dir("bpv_mapped"));
  });
  EXPECT_TRUE(test::contains(e, "--wavelengths or --response")) << e;
}

TEST_F(BandPerView, IndexDiffGathersACapturesBandsAtOnePose) {
  const auto scene = load(false);
  RenderOptions options;
  options.diff = true;
  options.index = find_vegetation_index("ndvi", "--index");
  const fs::path out = test::temp_dir("bpv_eval_ndvi");
  const std::vector<Frame> frames = view_frames(*scene, scene->test);
  render_frames(*scene, gaussians, background, frames, options, out);
  // The truth's NDVI comes from the capture's red and NIR views, which the
  // model renders exactly.
  const auto summary = nlohmann::json::parse(io::read_file(out / "ndvi.json"));
  ASSERT_TRUE(summary["mean_absolute_error"].is_number()) << summary.dump(2);
  EXPECT_LT(summary["mean_absolute_error"].get<double>(), 1e-5) << summary.dump(2);
  EXPECT_EQ(summary["truth"], "clean");
  EXPECT_TRUE(fs::exists(out / "c1_b0_ndvi_compare.png"));
}

TEST_F(BandPerView, IndexDiffIsRefusedWhereNoPoseHoldsItsBands) {
  const auto scene = load(true);
  RenderOptions options;
  options.diff = true;
  options.index = find_vegetation_index("ndvi", "--index");
  const fs::path out = test::temp_dir("bpv_eval_ndvi_rig");
  const std::string e = test::error_of([&] {
    render_frames(*scene, gaussians, background, view_frames(*scene, scene->test), options, out);
  });
  EXPECT_TRUE(test::contains(e, "no view at the pose of c1_b0 holds the NIR band (842 nm)")) << e;
  EXPECT_EQ(files_in(out), 0u);  // refused before anything is written
  // Without --diff the index renders.
  options.diff = false;
  EXPECT_GT(
      render_frames(*scene, gaussians, background, view_frames(*scene, scene->test), options, out),
      0);
}

TEST_F(BandPerView, OneBandViewsHaveNoSpectralAngle) {
  const auto scene = load(true);
  EvalOptions options;
  options.fps_repeats = 0;
  options.backdrop = background;  // the renders' black backdrop: object rows too
  const EvalReport report = evaluate(*scene, gaussians, background, scene->test, "test", options);
  EXPECT_TRUE(std::isnan(report.mean.sam_rad));
  ASSERT_TRUE(report.mean_object.has_value());
  EXPECT_TRUE(std::isnan(report.mean_object->object.sam_rad));
  EXPECT_DOUBLE_EQ(report.mean_object_clean->object.psnr_db, kMaxPsnrDb);

  const std::string table = format_report(report);
  EXPECT_EQ(table.find("nan"), std::string::npos) << table;
  EXPECT_EQ(table.find("0.0000 "), std::string::npos) << table;
  EXPECT_TRUE(test::contains(table, "SAM -: every view holds one band")) << table;
  const fs::path dir = test::temp_dir("bpv_eval_json");
  write_metrics_json(dir / "metrics.json", report);
  write_per_view_csv(dir / "per_view.csv", report);
  const auto j = nlohmann::json::parse(io::read_file(dir / "metrics.json"));
  EXPECT_TRUE(j["sam"].is_null()) << j.dump(2);
  EXPECT_TRUE(j["clean"]["sam"].is_null()) << j.dump(2);
  EXPECT_TRUE(j["object"]["sam"].is_null()) << j.dump(2);
  EXPECT_TRUE(test::contains(j["notes"]["sam"].get<std::string>(), "one band")) << j.dump(2);
  std::ifstream csv(dir / "per_view.csv");
  std::string line;
  std::getline(csv, line);
  std::getline(csv, line);
  EXPECT_EQ(line.find("nan"), std::string::npos) << line;
  EXPECT_TRUE(test::contains(line, ",,")) << line;  // the empty SAM field
}

}  // namespace
}  // namespace ddhgs::eval
