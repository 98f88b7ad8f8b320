// `ddhgs report` end to end: a tiny synthesized scene, a short training run
// through the binary, the report folder's contents checked against the run
// (and `ddhgs eval`), then the page opened in headless Chromium, where a real
// slider move and pixel click must change the band image and the spectrum
// plot without console errors (tests/app/report_browser_check.py).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>

#include "io/files/atomic_file.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kBands = 6;

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args, out);
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string last_line(std::string s) {
  while (!s.empty() && s.back() == '\n') s.pop_back();
  size_t at = s.rfind('\n');
  return at == std::string::npos ? s : s.substr(at + 1);
}

// "window.NAME = {...};" -> the object.
json read_script_object(const fs::path& script, const std::string& prefix) {
  std::string js = io::read_file(script);
  EXPECT_EQ(js.rfind(prefix, 0), 0u);
  return json::parse(js.substr(prefix.size(), js.rfind(';') - prefix.size()));
}

json read_report_data(const fs::path& report) {
  return read_script_object(report / "assets" / "data.js", "window.DDHGS_REPORT = ");
}

// RFC 4648 base64 (with padding) back to bytes.
std::string base64_decode(const std::string& text) {
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  uint32_t bits = 0;
  int count = 0;
  for (char c : text) {
    if (c == '=') break;
    bits = (bits << 6) | uint32_t(alphabet.find(c));
    count += 6;
    if (count >= 8) {
      count -= 8;
      out += char((bits >> count) & 0xff);
    }
  }
  return out;
}

// Where the screenshot and a copy of the report stay after the test (the
// temp folders are removed at exit): ctest's working folder.
fs::path test_output() {
  fs::path dir = fs::current_path() / "test_output";
  fs::create_directories(dir);
  return dir;
}

class ReportCli : public ::testing::Test {
 protected:
  // 10 views: Hyper-NeRF's split keeps one test view, whose per-band PSNR and
  // RMSE then determine each other exactly.
  static void SetUpTestSuite() {
    fs::path root = test::temp_dir("report_cli");
    scene_ = new fs::path(root / "scene");
    run_ = new fs::path(root / "run");
    std::string out;
    ASSERT_EQ(ddhgs("synth --preset demo --force --out " + scene_->string() +
                        " --width 40 --height 30 --bands " + std::to_string(kBands) +
                        " --views 10 --points 400 --supersample 1",
                    &out),
              0)
        << out;
    ASSERT_EQ(ddhgs("--threads 2 train " + scene_->string() + " --out " + run_->string() +
                        " --preset demo --iterations 60 --checkpoint-every 1000"
                        " --set output.log_every=10 --set output.test_every=30",
                    &out),
              0)
        << out;
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete run_;
  }
  static fs::path* scene_;
  static fs::path* run_;
};
fs::path* ReportCli::scene_ = nullptr;
fs::path* ReportCli::run_ = nullptr;

TEST_F(ReportCli, WritesSelfContainedReportThatAgreesWithTheRun) {
  std::string out;
  ASSERT_EQ(ddhgs("eval " + run_->string() + " --fps-repeats 0", &out), 0) << out;
  ASSERT_EQ(ddhgs("report " + run_->string(), &out), 0) << out;
  const fs::path report = *run_ / "report";
  EXPECT_TRUE(contains(out, (report / "index.html").string())) << out;
  EXPECT_FALSE(fs::exists(run_->string() + "/report.tmp"));

  // The binary's copies of the page and of the libraries are those under
  // web/ (the build embeds them; a stale build fails here).
  const fs::path web = test::source_dir() / "web";
  for (auto [written, source] :
       {std::pair{"assets/report.js", "report/report.js"},
        {"assets/report.css", "report/report.css"},
        {"assets/splat_view.js", "report/splat_view.js"},
        {"assets/playcanvas.min.js", "vendor/playcanvas-2.23.3/playcanvas.min.js"},
        {"assets/playcanvas.LICENSE.txt", "vendor/playcanvas-2.23.3/LICENSE"},
        {"assets/uPlot.iife.min.js", "vendor/uplot-1.6.32/uPlot.iife.min.js"},
        {"assets/uPlot.min.css", "vendor/uplot-1.6.32/uPlot.min.css"},
        {"assets/uPlot.LICENSE.txt", "vendor/uplot-1.6.32/LICENSE"}})
    EXPECT_EQ(io::read_file(report / written), io::read_file(web / source)) << written;
  EXPECT_FALSE(contains(io::read_file(report / "index.html"), "<!-- viewer data -->"));

  json data = read_report_data(report);
  EXPECT_EQ(data["wavelengths_nm"].size(), size_t(kBands));
  // Rows against the captured and the clean views; the same numbers as `ddhgs eval`.
  // The synthetic scene's grey backdrop is uniform, so eval also measured the
  // object and its inside; the report shows those two rows after.
  json eval = json::parse(io::read_file(*run_ / "eval" / "metrics.json"));
  ASSERT_EQ(data["metrics"].size(), 4u) << data["metrics"].dump();
  EXPECT_TRUE(contains(data["metrics"][2]["label"].get<std::string>(), "unlike the backdrop"));
  EXPECT_NEAR(data["metrics"][2]["psnr"].get<double>(), eval["object"]["psnr"].get<double>(), 1e-9);
  EXPECT_TRUE(data["metrics"][2]["ssim"].is_null());
  EXPECT_NEAR(data["metrics"][3]["sam"].get<double>(), eval["object"]["interior_sam"].get<double>(),
              1e-9);
  EXPECT_NEAR(data["metrics"][0]["psnr"].get<double>(), eval["psnr"].get<double>(), 1e-6);
  EXPECT_NEAR(data["metrics"][0]["sam"].get<double>(), eval["sam"].get<double>(), 1e-6);
  EXPECT_NEAR(data["metrics"][1]["psnr"].get<double>(), eval["clean"]["psnr"].get<double>(), 1e-6);
  EXPECT_NEAR(data["metrics"][1]["ssim"].get<double>(), eval["clean"]["ssim"].get<double>(), 1e-6);

  // One test view: per-band PSNR = -20 log10(per-band RMSE), band by band.
  ASSERT_EQ(data["sam_per_view"]["views"].size(), 1u);
  const json& psnr = data["per_band"]["psnr"];
  const json& rmse = data["per_band"]["rmse"];
  ASSERT_EQ(psnr.size(), 2u);
  for (size_t t = 0; t < 2; ++t)
    for (int b = 0; b < kBands; ++b) {
      double r = rmse[t]["values"][b].get<double>();
      EXPECT_NEAR(psnr[t]["values"][b].get<double>(), -20 * std::log10(r), 1e-6) << t << " " << b;
    }

  // Curves: every logged iteration of metrics.jsonl (1, 10, ..., 60).
  EXPECT_EQ(data["curves"]["iter"].size(), 7u);
  EXPECT_EQ(data["curves"]["iter"].back(), 60);
  // Test-view PSNR against training time at iterations 30 and 60: the last
  // is the final model's, which the summary measured again.
  const json& test = data["curves"]["test"];
  ASSERT_EQ(test["minutes"].size(), 2u) << test.dump();
  EXPECT_GT(test["minutes"][1].get<double>(), test["minutes"][0].get<double>());
  EXPECT_LE(test["minutes"][1].get<double>(),
            data["train_summary"]["seconds"].get<double>() / 60 + 1e-9);
  EXPECT_EQ(test["test_psnr"][1], data["train_summary"]["test_psnr"]);
  EXPECT_EQ(test["test_psnr_clean"][1], data["train_summary"]["test_psnr_clean"]);
  EXPECT_NE(test["test_psnr"][0], test["test_psnr"][1]);
  EXPECT_EQ(data["train_summary"]["iterations"], 60);
  EXPECT_EQ(data["config"]["iterations"], 60);

  // Pictures: truth | render | error (+ colour bar) per selection; the
  // paper's 1082-1100 nm window moves inside this scene's 400-1000 nm.
  std::vector<std::string> labels;
  for (const json& s : data["figures"]["selections"]) labels.push_back(s["label"]);
  EXPECT_EQ(labels, (std::vector<std::string>{"rgb", "400-418nm", "750-768nm", "982-1000nm"}));
  for (const json& view : data["figures"]["views"])
    for (const std::string& label : labels) {
      torch::Tensor picture = io::read_image(report / view["files"][label].get<std::string>());
      EXPECT_EQ(picture.size(1), 3 * 40 + 2 * 4) << label;
    }
  // The viewer's band atlases: 6 bands in a 3 x 2 grid of 40 x 30 tiles.
  json viewer = data["viewer"]["views"][0];
  EXPECT_EQ(viewer["width"], 40);
  EXPECT_EQ(viewer["cols"], 3);
  EXPECT_EQ(viewer["rows"], 2);
  uintmax_t bytes = 0;  // all but the vendored libraries, the same for every report
  for (const auto& entry : fs::recursive_directory_iterator(report))
    if (entry.is_regular_file() && entry.path().filename() != "playcanvas.min.js" &&
        entry.path().filename() != "uPlot.iife.min.js")
      bytes += entry.file_size();
  EXPECT_LT(bytes, 1u << 20) << "a tiny run's report should stay small";

  // The 3D view's model: every Gaussian of the run, centres as they are,
  // band values from at most 6 basis vectors within 8-bit accuracy, one
  // frustum per training view.
  const json splats = read_script_object(report / "assets" / "splats.js", "window.DDHGS_SPLATS = ");
  const io::GaussianPly ply = io::read_gaussian_ply(*run_ / "gaussians.ply");
  ASSERT_EQ(splats["count"].get<int64_t>(), ply.means.size(0));
  const std::string means = base64_decode(splats["means"].get<std::string>());
  ASSERT_EQ(means.size(), size_t(ply.means.numel()) * 4);
  EXPECT_EQ(std::memcmp(means.data(), ply.means.contiguous().data_ptr<float>(), means.size()), 0);
  EXPECT_LE(splats["basis"]["vectors"].size(), size_t(kBands));
  EXPECT_LT(splats["basis"]["rmse"].get<double>(), 1.0 / 255);
  EXPECT_EQ(base64_decode(splats["basis"]["coefficients"].get<std::string>()).size(),
            size_t(ply.means.size(0)) * splats["basis"]["vectors"].size());
  EXPECT_EQ(splats["cameras"].size(), 9u);
  EXPECT_EQ(splats["pseudo_rgb"]["weights"].size(), size_t(kBands));

  // --viewer-px area-averages the viewer's bands down (40 x 30 -> 20 x 15);
  // rerunning replaces the earlier report.
  const fs::path small = *run_ / "small_report";
  for (int repeat = 0; repeat < 2; ++repeat)
    ASSERT_EQ(
        ddhgs("report " + run_->string() + " --out " + small.string() + " --viewer-px 20", &out), 0)
        << out;
  viewer = read_report_data(small)["viewer"]["views"][0];
  EXPECT_EQ(viewer["width"], 20);
  EXPECT_EQ(viewer["height"], 15);
}

TEST_F(ReportCli, OpensInHeadlessChromiumAndRespondsToSliderAndClick) {
  std::string chromium;
  test::run_command("command -v chromium", &chromium);
  while (!chromium.empty() && std::isspace(static_cast<unsigned char>(chromium.back())))
    chromium.pop_back();
  ASSERT_FALSE(chromium.empty())
      << "chromium is not installed: run scripts/setup.sh --with-tests (Debian package chromium)";

  const fs::path report = test_output() / "report_cli_report";
  std::string out;
  ASSERT_EQ(ddhgs("report " + run_->string() + " --out " + report.string(), &out), 0) << out;
  const fs::path screenshot = test_output() / "report_cli_screenshot.png";
  fs::remove(screenshot);
  fs::remove(test_output() / "report_cli_screenshot_3d.png");
  const fs::path profile = test::temp_dir("report_cli_chromium_profile");
  int rc = test::run_command(
      test::python() + " " + (test::source_dir() / "tests/app/report_browser_check.py").string() +
          " " + chromium + " " + (report / "index.html").string() + " " + screenshot.string() +
          " " + profile.string() + " 2>&1",
      &out);
  ASSERT_EQ(rc, 0) << out;
  json checks = json::parse(last_line(out));
  EXPECT_TRUE(checks["band_image_changed"].get<bool>()) << out;
  EXPECT_TRUE(checks["spectrum_plot_changed"].get<bool>()) << out;
  EXPECT_EQ(checks["spectrum_points_per_series"], json::array({kBands, kBands, kBands})) << out;
  EXPECT_TRUE(checks["console_errors"].empty()) << out;
  EXPECT_GT(io::read_image(screenshot).size(0), 500) << screenshot;
  // The 3D view: drawn, recoloured by its slider, a spectrum from a click.
  EXPECT_GT(checks["splat_drawn_fraction"].get<double>(), 0.01) << out;
  EXPECT_TRUE(checks["splat_recoloured"].get<bool>()) << out;
  EXPECT_GT(checks["splat_pick"]["gaussians"].get<int>(), 0) << out;
  EXPECT_EQ(checks["splat_spectrum_points"], json::array({kBands, kBands})) << out;
  const fs::path screenshot_3d = test_output() / "report_cli_screenshot_3d.png";
  EXPECT_GT(io::read_image(screenshot_3d).size(0), 300) << screenshot_3d;
  std::cout << "screenshots: " << screenshot.string() << ", " << screenshot_3d.string() << "\n";
}

TEST_F(ReportCli, BadInputsGiveOneClearLineAndTouchNothing) {
  std::string out;
  EXPECT_EQ(ddhgs("report " + (*run_ / "no-such-run").string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "run folder")) << out;

  // An --out folder that is not a report is never replaced.
  fs::path precious = test::temp_dir("report_cli_precious");
  io::write_file_atomically(precious / "notes.txt", "keep me");
  EXPECT_EQ(ddhgs("report " + run_->string() + " --out " + precious.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "did not write")) << out;
  EXPECT_EQ(io::read_file(precious / "notes.txt"), "keep me");

  // A broken metrics.jsonl is named with its line.
  fs::path broken = test::temp_dir("report_cli_broken_run");
  for (const char* f : {"config.json", "gaussians.ply", "train_summary.json", "background.json"})
    if (fs::exists(*run_ / f)) fs::copy_file(*run_ / f, broken / f);
  io::write_file_atomically(broken / "metrics.jsonl",
                            "{\"iter\": 1, \"loss\": 0.5}\n{\"iter\": 2,\n");
  EXPECT_EQ(ddhgs("report " + broken.string(), &out), 1);
  EXPECT_TRUE(contains(last_line(out), "metrics.jsonl: line 2")) << out;
  EXPECT_FALSE(fs::exists(broken / "report"));
}

}  // namespace
}  // namespace ddhgs
