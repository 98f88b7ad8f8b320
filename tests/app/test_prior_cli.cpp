// `ddhgs prior` end to end on a two-entry corpus of scripts/prior_corpus.sh:
// the prior file, its state and learning curve, resuming, and a run that
// loads the prior through diffusion.prior and is evaluated denoised.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;

using test::ddhgs;

size_t lines_of(const fs::path& path) {
  return test::lines(io::read_file(path));
}

TEST(PriorCli, TrainsResumesAndServesARun) {
  const fs::path root = test::temp_dir("prior_cli");
  const fs::path corpus = root / "corpus";
  std::string out;
  ASSERT_EQ(test::run_command(test::prior_corpus_command(corpus, "2", 4, 30), &out), 0) << out;

  const fs::path prior = root / "priors" / "p.pt";  // its folder is made
  const std::string common = " --batch 2 --crop 16 --base-channels 8 --check-every 2";
  ASSERT_EQ(
      ddhgs("prior " + corpus.string() + " --out " + prior.string() + " --steps 4" + common, &out),
      0)
      << out;
  EXPECT_NE(out.find("views kept for checks"), std::string::npos) << out;
  const fs::path curve = fs::path(prior.string() + ".curve.csv");
  ASSERT_TRUE(fs::exists(prior));
  ASSERT_TRUE(fs::exists(prior.string() + ".state.pt"));
  EXPECT_EQ(lines_of(curve), 3u);  // header, steps 2 and 4
  EXPECT_NE(out.find(prior.string() + " at step 4"), std::string::npos) << out;

  // Asked for more steps, it goes on from the last check.
  ASSERT_EQ(
      ddhgs("prior " + corpus.string() + " --out " + prior.string() + " --steps 6" + common, &out),
      0)
      << out;
  EXPECT_NE(out.find("resuming " + prior.string() + " at step 4"), std::string::npos) << out;
  EXPECT_EQ(lines_of(curve), 4u);
  EXPECT_NE(out.find(prior.string() + " at step 6"), std::string::npos) << out;
  {  // the curve's seconds count the whole training, across the rerun
    std::istringstream rows(io::read_file(curve));
    std::string row;
    std::vector<double> seconds;
    std::getline(rows, row);  // header
    while (std::getline(rows, row)) seconds.push_back(std::stod(row.substr(row.find(',') + 1)));
    ASSERT_EQ(seconds.size(), 3u);
    EXPECT_GT(seconds[1], 0);
    EXPECT_GT(seconds[2], seconds[1]);
  }
  ASSERT_EQ(
      ddhgs("prior " + corpus.string() + " --out " + prior.string() + " --steps 6" + common, &out),
      0)
      << out;
  EXPECT_NE(out.find("has already trained 6 steps"), std::string::npos) << out;

  // A run with the prior: its denoiser is the prior's in the scene's subspace.
  const fs::path scene = corpus / "scenes" / "000";
  const fs::path run = root / "run";
  ASSERT_EQ(ddhgs("train " + scene.string() + " --preset demo --iterations 30 --out " +
                      run.string() + " --set diffusion.prior=" + prior.string(),
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("the denoiser prior"), std::string::npos) << out;
  EXPECT_NE(out.find("not fine-tuned"), std::string::npos) << out;
  ASSERT_TRUE(fs::exists(run / "denoiser.pt"));
  ASSERT_EQ(ddhgs("eval " + run.string(), &out), 0) << out;
  const json denoised = test::read_json(run / "eval" / "denoised.json");
  EXPECT_FALSE(denoised.empty());
  EXPECT_NE(out.find("ddim1"), std::string::npos) << out;

  // A run trained without it, evaluated with the prior: the same raw metrics,
  // denoised ones from the prior.
  const fs::path plain = root / "plain";
  ASSERT_EQ(
      ddhgs("train " + scene.string() + " --preset demo --iterations 30 --out " + plain.string(),
            &out),
      0)
      << out;
  ASSERT_EQ(ddhgs("eval " + plain.string(), &out), 0) << out;
  EXPECT_FALSE(fs::exists(plain / "eval" / "denoised.json"));
  const json raw = test::read_json(plain / "eval" / "metrics.json");
  ASSERT_EQ(ddhgs("eval " + plain.string() + " --prior " + prior.string(), &out), 0) << out;
  EXPECT_NE(out.find("the denoiser prior"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(plain / "eval" / "denoised.json"));
  EXPECT_EQ(test::read_json(plain / "eval" / "metrics.json")["psnr"], raw["psnr"]);

  // Bad input: one line naming the file, nothing left behind.
  EXPECT_NE(ddhgs("prior " + root.string() + " --out " + (root / "x.pt").string(), &out), 0);
  EXPECT_NE(out.find("manifest.json"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "x.pt"));
  EXPECT_NE(ddhgs("train " + scene.string() + " --preset demo --iterations 30 --out " +
                      (root / "run2").string() +
                      " --set diffusion.prior=" + (root / "missing.pt").string(),
                  &out),
            0);
  EXPECT_NE(out.find("missing.pt: no such denoiser prior file"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "run2" / "gaussians.ply"));
}

}  // namespace
}  // namespace ddhgs
