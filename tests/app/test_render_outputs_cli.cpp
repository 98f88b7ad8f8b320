// `ddhgs render` into an existing folder, and its response and list flags:
// a render of another format or band count leaves no stale frame beside its
// own, each kind of render has its own folder, and empty or malformed
// values end in one line.
#include <gtest/gtest.h>

#include <algorithm>

#include "io/files/atomic_file.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

using test::ddhgs;
using test::error_lines;

std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

bool any_name(const fs::path& dir, const std::string& part) {
  const auto names = listing(dir);
  return std::any_of(names.begin(), names.end(),
                     [&](const std::string& n) { return n.find(part) != std::string::npos; });
}

class RenderOutputs : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(test::temp_dir("render_outputs"));
    std::string out;
    ASSERT_EQ(ddhgs("synth --preset demo --width 32 --height 24 --bands 4 --views 12 --out " +
                        (*dir_ / "scene").string(),
                    &out),
              0)
        << out;
    ASSERT_EQ(ddhgs("train " + (*dir_ / "scene").string() + " --out " + run().string() +
                        " --preset demo --iterations 20",
                    &out),
              0)
        << out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static fs::path run() { return *dir_ / "run"; }
  static fs::path csv(const std::string& name, const std::string& text) {
    fs::create_directories(*dir_ / "responses");
    const fs::path path = *dir_ / "responses" / name;
    io::write_file_atomically(path, text);
    return path;
  }
  // Runs `render RUN args`: the one error line, or "" on success.
  static std::string render_error(const std::string& args) {
    std::string out;
    const int rc = ddhgs("render " + run().string() + " " + args, &out);
    const auto errors = error_lines(out);
    if (rc == 0) return "";
    EXPECT_EQ(rc, 1) << out;
    EXPECT_EQ(errors.size(), 1u) << out;
    return errors.empty() ? out : errors[0];
  }
  static fs::path* dir_;
};
fs::path* RenderOutputs::dir_ = nullptr;

TEST_F(RenderOutputs, AnotherFormatOrBandCountReplacesTheEarlierFrames) {
  const fs::path folder = run() / "renders" / "test_wavelengths";
  ASSERT_EQ(render_error("--wavelengths 400:700:1 --format npy --band 200"), "");
  EXPECT_TRUE(fs::exists(folder / "r_010.npy"));
  EXPECT_TRUE(fs::exists(folder / "r_010_band200.png"));
  // 11 bands instead of 301: nothing of the 301-band render is left.
  ASSERT_EQ(render_error("--wavelengths 500:600:10 --format envi"), "");
  EXPECT_EQ(listing(folder), (std::vector<std::string>{".ddhgs-output", "channels.json",
                                                       "r_010.hdr", "r_010.img", "r_010_rgb.png"}));
  EXPECT_NE(io::read_file(folder / "r_010.hdr").find("bands = 11"), std::string::npos);
  // The same channels as a .npy cube and another picture: the ENVI cube goes,
  // the other picture of the same channels stays.
  ASSERT_EQ(render_error("--wavelengths 500:600:10 --format npy --band 3"), "");
  EXPECT_EQ(listing(folder),
            (std::vector<std::string>{".ddhgs-output", "channels.json", "r_010.npy",
                                      "r_010_band3.png", "r_010_rgb.png"}));
}

TEST_F(RenderOutputs, ResponseRendersHaveAFolderOfTheirOwn) {
  const fs::path ndvi =
      csv("ndvi.csv", "wavelength_nm,red,nir\n500,1,0\n600,1,0\n700,0,1\n800,0,1\n");
  ASSERT_EQ(render_error("--index ndvi"), "");
  ASSERT_EQ(render_error("--response " + ndvi.string()), "");
  const fs::path renders = run() / "renders";
  EXPECT_TRUE(any_name(renders / "test_response_ndvi", "_rgb.png"));
  EXPECT_FALSE(any_name(renders / "test_ndvi", "_rgb.png"));
  EXPECT_TRUE(any_name(renders / "test_ndvi", "_ndvi.png"));
}

TEST_F(RenderOutputs, EmptyAndMalformedValuesEndInOneLine) {
  for (const char* flag : {"--wavelengths", "--index", "--response", "--band", "--data"})
    EXPECT_EQ(
        render_error(std::string(flag) + " ''"),
        "error: " + std::string(flag) + ": an empty value (give one, or leave the option out)");
  const fs::path headless = csv("headless.csv", "500,1\n600,1\n");
  EXPECT_EQ(render_error("--response " + headless.string()),
            "error: " + headless.string() +
                ": line 1: starts with the number '500', not a header; the first row names the "
                "columns (expected a header 'wavelength_nm,NAME,...' and rows of numbers)");
  const fs::path twins = csv("twins.csv", "wavelength_nm,left,right\n500,1,1\n600,1,1\n");
  EXPECT_EQ(render_error("--response " + twins.string()),
            "error: " + twins.string() +
                ": channels 'left' and 'right' have the same centre wavelength (550 nm); a "
                "rendered cube holds its channels by increasing wavelength");
  EXPECT_NE(render_error("--wavelengths 500:" + std::string(100000, '9') + ":1")
                .find("...' (and 99920 more characters)"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(run() / "renders" / "test_response_twins"));
}

}  // namespace
}  // namespace ddhgs
