// io::read_response_csv against files with known content, and the examples
// shipped in examples/responses/.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>

#include "core/error.h"
#include "io/response/response_csv.h"
#include "support/error_text.h"
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

// Each case: the file's text and what the one-line error must say.
void expect_refused(const std::string& name, const std::string& text,
                    const std::vector<std::string>& says) {
  const fs::path path = write_text(name, text);
  try {
    read_response_csv(path);
    ADD_FAILURE() << "read " << name;
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path.string() + ": ", 0), 0u) << what;
    EXPECT_LT(what.size(), 400u) << name;
    for (const std::string& part : says) EXPECT_NE(what.find(part), std::string::npos) << what;
  }
}

TEST(ResponseCsv, AFirstRowOfNumbersIsNoHeader) {
  expect_refused("no_header.csv", "500,1\n510,1\n",
                 {"line 1: starts with the number '500', not a header", "wavelength_nm,NAME"});
  expect_refused("comment_then_numbers.csv", "# sensor\n\n500,1,2\n", {"line 3: starts with"});
}

TEST(ResponseCsv, EveryNumberIsWithinWhatFloat32Renders) {
  expect_refused("huge_response.csv", "wavelength_nm,red\n500,1e39\n",
                 {"line 2: '1e39' is out of range (at most 1e+18 in magnitude) (column 'red')"});
  expect_refused("huge_wavelength.csv", "wavelength_nm,red\n1e300,1\n",
                 {"line 2: '1e300' is out of range", "(column wavelength_nm)"});
  expect_refused("past_double.csv", "wavelength_nm,red\n500,1e999\n", {"'1e999' is out of range"});
  expect_refused("inf.csv", "wavelength_nm,red\n500,inf\n", {"'inf' is out of range"});
  expect_refused("nan.csv", "wavelength_nm,red\n500,nan\n", {"'nan' is not a number"});
  expect_refused("zero_wavelength.csv", "wavelength_nm,red\n0,1\n",
                 {"line 2: wavelength '0' nm is not above 0"});
  // The largest accepted value reads.
  const auto r = read_response_csv(write_text("edge.csv", "wavelength_nm,red\n500,1e18\n"));
  EXPECT_EQ(r.values.item<double>(), 1e18);
}

TEST(ResponseCsv, UserValuesAreQuotedInPart) {
  // A 5 MB number and a 1 MB channel name: a short message, the rest counted.
  expect_refused("long_number.csv", "wavelength_nm,red\n500," + std::string(5'000'000, '9') + "\n",
                 {"line 2: '" + std::string(80, '9') + "...' (and 4999920 more characters)",
                  "is out of range"});
  expect_refused("long_name.csv", "wavelength_nm," + std::string(1'000'000, 'n') + "\n500,1\n",
                 {"column 2's name '" + std::string(80, 'n') + "...' (and 999920 more characters)",
                  "is longer than 80 characters"});
  // A NUL is an escape and the message goes on after it.
  expect_refused("nul.csv",
                 std::string("wavelength_nm,red\n500,1\0"
                             "2\n",
                             26),
                 {"line 2: '1\\02' is not a number (column 'red')"});
  expect_refused("control_name.csv", "wavelength_nm,r\x1b[31m\n500,1\n",
                 {"column 2's name 'r\\x1b[31m' holds a control character"});
  expect_refused("repeated.csv", "wavelength_nm,red,red\n500,1,1\n",
                 {"line 1: column 3 repeats the name 'red'"});
}

TEST(ResponseCsv, OnlyRegularFilesAreRead) {
  const fs::path dir = test::temp_dir("response_csv_special");
  const fs::path fifo = dir / "pipe.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Opening a FIFO would wait for a writer for ever: refused before that.
  EXPECT_EQ(test::error_of([&] { read_response_csv(fifo); }),
            fifo.string() + ": is a FIFO (named pipe), expected a regular file");
  EXPECT_EQ(test::error_of([&] { read_response_csv(dir); }),
            dir.string() + ": is a folder, expected a file");
  EXPECT_EQ(test::error_of([&] { read_response_csv(dir / "none.csv"); }),
            (dir / "none.csv").string() + ": file not found");
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
