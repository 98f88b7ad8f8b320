// End to end: `ddhgs render-ply` on a PLY with known Gaussians, checked
// against hand-computed spectra, and its errors for bad cameras.
#include <gtest/gtest.h>

#include <fstream>

#include "io/cube/cube.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

constexpr double C0 = 0.28209479177387814;  // SH basis constants (3DGS)
constexpr double C1 = 0.4886025119029199;
const float kDc[3] = {0.4f, -0.2f, 1.0f};
const float kRestZ[3] = {0.1f, 0.3f, -0.2f};  // coefficient of Y_1^0 = C1 z, per band

// Two large Gaussians straight ahead at depth 5 with alphas 0.99 and about
// 0.975 at the centre pixel: its transmittance ends near 2.5e-4, above the
// 1e-4 cut-off that would drop the second one, so the pixel is the SH colour
// to within 3e-4. SH degree 1 with x and y coefficients that must not matter
// along the optical axis.
void write_scene(const fs::path& path) {
  io::GaussianPly ply;
  ply.means = torch::tensor({{0.f, 0.f, 5.f}, {0.f, 0.f, 5.f}});
  ply.log_scales = torch::full({2, 3}, std::log(0.5f));
  ply.quats = torch::tensor({{1.f, 0.f, 0.f, 0.f}, {1.f, 0.f, 0.f, 0.f}});
  ply.logit_opacities = torch::tensor({{10.f}, {4.f}});
  ply.sh_dc = torch::tensor({{kDc[0], kDc[1], kDc[2]}, {kDc[0], kDc[1], kDc[2]}});
  ply.sh_rest = torch::full({2, 3, 3}, 0.7f);
  for (int b = 0; b < 3; ++b) ply.sh_rest.select(1, b).select(1, 1).fill_(kRestZ[b]);
  ply.wavelengths_nm = {450, 550, 650};
  io::write_gaussian_ply(path, ply);
}

void write_camera(const fs::path& path, const std::string& matrix) {
  std::ofstream(path) << R"({"width": 64, "height": 64, "fx": 64, "fy": 64, "cx": 32, "cy": 32,)"
                      << R"("world_to_camera": )" << matrix << "}";
}
const char* kIdentity = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]";

int render(const std::string& arguments, std::string* output) {
  return test::run_command(test::ddhgs_binary() + " render-ply " + arguments, output);
}

TEST(RenderPlyCli, CentrePixelHasTheShColourAndCornersTheBackground) {
  auto dir = test::temp_dir("render_ply_cli");
  write_scene(dir / "scene.ply");
  write_camera(dir / "cam.json", kIdentity);
  std::string output;
  ASSERT_EQ(render((dir / "scene.ply").string() + " --camera " + (dir / "cam.json").string() +
                       " --out " + (dir / "image.npy").string() + " --background 0.25,0.5,0.75" +
                       " --preview " + (dir / "preview.png").string(),
                   &output),
            0)
      << output;
  auto cube = io::read_cube(dir / "image.npy");
  ASSERT_EQ(cube.type, io::SampleType::F32);
  ASSERT_EQ(cube.data.sizes(), (std::vector<int64_t>{64, 64, 3}));
  const float background[3] = {0.25f, 0.5f, 0.75f};
  for (int b = 0; b < 3; ++b) {
    const double expected = 0.5 + C0 * kDc[b] + C1 * kRestZ[b];
    EXPECT_NEAR(cube.data[32][32][b].item<float>(), expected, 1e-3) << "band " << b;
    EXPECT_NEAR(cube.data[31][31][b].item<float>(), expected, 1e-3) << "band " << b;
    for (auto [y, x] : {std::pair{0, 0}, {0, 63}, {63, 0}, {63, 63}})
      EXPECT_EQ(cube.data[y][x][b].item<float>(), background[b]) << "band " << b;
  }
  auto preview = io::read_image(dir / "preview.png");
  EXPECT_EQ(preview.sizes(), (std::vector<int64_t>{64, 64, 3}));

  // Degree 0 on request: the view-dependent term disappears; one background value.
  ASSERT_EQ(render((dir / "scene.ply").string() + " --camera " + (dir / "cam.json").string() +
                       " --out " + (dir / "dc.npy").string() + " --sh-degree 0 --background 0.1",
                   &output),
            0)
      << output;
  auto dc = io::read_cube(dir / "dc.npy");
  for (int b = 0; b < 3; ++b) {
    EXPECT_NEAR(dc.data[32][32][b].item<float>(), 0.5 + C0 * kDc[b], 1e-3);
    EXPECT_EQ(dc.data[0][0][b].item<float>(), 0.1f);
  }
}

TEST(RenderPlyCli, BadInputsFailWithOneLineNamingTheProblem) {
  auto dir = test::temp_dir("render_ply_cli_bad");
  write_scene(dir / "scene.ply");
  const std::string scene = (dir / "scene.ply").string();
  const std::string out = (dir / "image.npy").string();
  struct Case {
    std::string camera_json, extra, expected;
  };
  const std::vector<Case> cases = {
      {R"({"width": 64, "height": 64, "fx": 64, "fy": 64, "cx": 32})", "", "missing key \"cy\""},
      {R"({"width": 64, "height": 64, "fx": "64", "fy": 64, "cx": 32, "cy": 32})", "",
       "\"fx\" must be a number"},
      {"not json", "", "not valid JSON"},
      {"", "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]", "not invertible"},
      {"", std::string(kIdentity) + " --sh-degree 2", "only has coefficients up to degree 1"},
      {"", std::string(kIdentity) + " --background 1,2", "2 values for a scene with 3 bands"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const fs::path camera = dir / ("cam" + std::to_string(i) + ".json");
    std::string extra;
    if (cases[i].camera_json.empty()) {
      const std::string& spec = cases[i].extra;
      const size_t end = spec.find("]]") + 2;
      write_camera(camera, spec.substr(0, end));
      extra = spec.substr(end);
    } else {
      std::ofstream(camera) << cases[i].camera_json;
    }
    std::string output;
    EXPECT_EQ(render(scene + " --camera " + camera.string() + " --out " + out + extra, &output), 1)
        << output;
    EXPECT_NE(output.find(cases[i].expected), std::string::npos) << output;
    if (i < 4) {
      EXPECT_NE(output.find(camera.string()), std::string::npos) << output;
    }
    EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
    EXPECT_FALSE(fs::exists(out)) << "case " << i;
  }
}

}  // namespace
}  // namespace ddhgs
