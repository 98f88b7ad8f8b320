// io::read_response_csv against files with known content, and the examples
// shipped in examples/responses/.
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "io/response/response_csv.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

fs::path write_text(const std::string& name, const std::string& text) {
  const fs::path path = test::temp_dir("response_csv") / name;
  std::ofstream(path) << text;
  return path;
}

TEST(ResponseCsv, ReadsCommentsHeaderAndRows) {
  const auto r = read_response_csv(
      write_text("ok.csv", "# a comment\nwavelength_nm, red ,nir\n500,0.5,0\n\n510,1,0.25\r\n"));
  EXPECT_EQ(r.channels, (std::vector<std::string>{"red", "nir"}));
  EXPECT_EQ(r.wavelengths_nm, (std::vector<double>{500, 510}));
  EXPECT_TRUE(torch::equal(r.values, torch::tensor({{0.5, 0.0}, {1.0, 0.25}}, torch::kFloat64)));
}

TEST(ResponseCsv, NamesTheFileAndLineOfABadRow) {
  const std::pair<const char*, const char*> cases[] = {
      {"wavelength_nm,a\n500,1\n500,2\n", "line 3: wavelengths must increase"},
      {"wavelength_nm,a\n500,x\n", "line 2: 'x' is not a number"},
      {"wavelength_nm,a\n500,1,2\n", "line 2: 3 values; expected 2"},
      {"wavelength_nm,a\n500,-1\n", "line 2: a response below 0"},
      {"wavelength_nm\n500\n", "line 1: no channel columns"},
      {"wavelength_nm,a\n", "no response rows"},
  };
  int i = 0;
  for (const auto& [text, message] : cases) {
    const fs::path path = write_text("bad" + std::to_string(i++) + ".csv", text);
    try {
      read_response_csv(path);
      ADD_FAILURE() << "read " << text;
    } catch (const core::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(message), std::string::npos) << what;
      EXPECT_NE(what.find(path.filename().string()), std::string::npos) << what;
    }
  }
}

TEST(ResponseCsv, TheShippedExamplesRead) {
  const fs::path dir = fs::path(DDHGS_SOURCE_DIR) / "examples" / "responses";
  const auto rededge = read_response_csv(dir / "micasense_rededge.csv");
  EXPECT_EQ(rededge.channels,
            (std::vector<std::string>{"blue", "green", "red", "red_edge", "nir"}));
  // Each peaks at its published centre.
  const std::vector<double> centres = {475, 560, 668, 717, 842};
  for (int64_t c = 0; c < 5; ++c) {
    const int64_t peak = rededge.values.select(1, c).argmax().item<int64_t>();
    EXPECT_NEAR(rededge.wavelengths_nm[size_t(peak)], centres[size_t(c)], 1.0) << c;
  }
  EXPECT_EQ(read_response_csv(dir / "rgb.csv").channels,
            (std::vector<std::string>{"red", "green", "blue"}));
}

}  // namespace
}  // namespace ddhgs::io
