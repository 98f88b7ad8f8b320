// `ddhgs train --resume` under settings that shape another model: refused in
// one line naming the setting, both values and the files, before the log
// announces a model; and a resumed run's config.json, log and model agree.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

using test::ddhgs;
using test::error_lines;

class ResumeSettings : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(test::temp_dir("resume_settings"));
    std::string out;
    ASSERT_EQ(ddhgs("synth --preset demo --width 32 --height 24 --bands 4 --views 12 --out " +
                        (*dir_ / "scene").string(),
                    &out),
              0)
        << out;
    for (const char* rank : {"1", "2"})
      ASSERT_EQ(ddhgs("train " + (*dir_ / "scene").string() + " --out " +
                          (*dir_ / ("rank" + std::string(rank))).string() +
                          " --preset demo --iterations 20 --checkpoint-every 10"
                          " --set model.spectral_rank=" +
                          rank,
                      &out),
                0)
          << out;
  }
  static void TearDownTestSuite() { delete dir_; }

  // A copy of the rank-1 run to damage.
  static fs::path copy(const std::string& name) {
    const fs::path to = *dir_ / name;
    fs::remove_all(to);
    fs::copy(*dir_ / "rank1", to, fs::copy_options::recursive);
    fs::remove(to / ".ddhgs-lock");
    return to;
  }

  static fs::path* dir_;
};
fs::path* ResumeSettings::dir_ = nullptr;

// Resuming `run` is refused in one line holding every part of `says`, with
// nothing announced and nothing of the run changed.
void expect_refused(const fs::path& run, const std::vector<std::string>& says) {
  const std::string config = io::read_file(run / "config.json");
  const std::string checkpoint = io::read_file(run / "checkpoint.pt");
  std::string out;
  EXPECT_EQ(ddhgs("train --resume " + run.string() + " --iterations 30", &out), 1) << out;
  const std::vector<std::string> errors = error_lines(out);
  ASSERT_EQ(errors.size(), 1u) << out;
  for (const std::string& part : says) EXPECT_NE(errors[0].find(part), std::string::npos) << out;
  EXPECT_EQ(out.find("colour model:"), std::string::npos) << out;
  EXPECT_EQ(io::read_file(run / "config.json"), config);
  EXPECT_EQ(io::read_file(run / "checkpoint.pt"), checkpoint);
}

void edit_config(const fs::path& run, const std::string& from, const std::string& to) {
  std::string text = io::read_file(run / "config.json");
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  io::write_file_atomically(run / "config.json", text);
}

TEST_F(ResumeSettings, AnEditedConfigIsRefusedNamingTheSetting) {
  const fs::path rank = copy("rank_edited");
  edit_config(rank, "\"spectral_rank\": 1", "\"spectral_rank\": 3");
  expect_refused(rank, {(rank / "config.json").string() + ": model.spectral_rank is 3, but " +
                        (rank / "checkpoint.pt").string() + " was trained with 1"});
  const fs::path sh = copy("sh_edited");
  edit_config(sh, "\"sh_degree\": 3", "\"sh_degree\": 2");
  expect_refused(sh, {"model.sh_degree is 2, but", "was trained with 3"});
  const fs::path bands = copy("bands_edited");
  edit_config(bands, "\"band_max_nm\": 1000000000.0", "\"band_max_nm\": 700.0");
  expect_refused(bands,
                 {"the dataset's band count (data.* settings) is 2, but", "was trained with 4"});
}

TEST_F(ResumeSettings, ACheckpointOfAnotherModelIsRefused) {
  const fs::path run = copy("swapped");
  fs::copy_file(*dir_ / "rank2" / "checkpoint.pt", run / "checkpoint.pt",
                fs::copy_options::overwrite_existing);
  expect_refused(run, {"model.spectral_rank is 1, but " + (run / "checkpoint.pt").string() +
                       " was trained with 2"});
}

TEST_F(ResumeSettings, AResumedRunsConfigLogAndModelAgree) {
  const fs::path run = copy("agreeing");
  std::string out;
  ASSERT_EQ(ddhgs("train --resume " + run.string() + " --iterations 30", &out), 0) << out;
  EXPECT_NE(out.find("colour model: 1 latent channels for 4 bands (basis and mean from the "
                     "checkpoint)"),
            std::string::npos)
      << out;
  const nlohmann::json config = nlohmann::json::parse(io::read_file(run / "config.json"));
  EXPECT_EQ(config["iterations"], 30);
  EXPECT_EQ(config["model"]["spectral_rank"], 1);
  EXPECT_EQ(config["model"]["sh_degree"], 3);
  const io::GaussianPly ply = io::read_gaussian_ply(run / "gaussians.ply");
  EXPECT_EQ(ply.basis.size(1), 1);  // rank 1
  EXPECT_EQ(ply.bands(), 4);
  EXPECT_EQ(ply.sh_degree(), 3);
  // The checkpoint it wrote resumes under its config again.
  ASSERT_EQ(ddhgs("train --resume " + run.string() + " --iterations 35", &out), 0) << out;
}

}  // namespace
}  // namespace ddhgs
