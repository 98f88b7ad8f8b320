// `ddhgs train` end to end on a tiny synthetic scene: quality bar,
// densification, bit-for-bit resume, and refusals.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>

#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

// Densification compressed into a short run (at 200 iterations: from 30
// until 170, opacity reset at 100, SH degree every 60).
const std::string kSchedule =
    " --preset demo --set densify.from_fraction=0.15 --set densify.every=30"
    " --set densify.until_fraction=0.85 --set densify.opacity_reset_every_fraction=0.5"
    " --set model.sh_degree_every_fraction=0.3 --set optim.means_lr_decay_fraction=1"
    " --checkpoint-every 100 --set output.test_every=50";  // test records must not disturb resume

const fs::path& scene() {
  static const fs::path dir = [] {
    fs::path d = test::temp_dir("train_cli_scene") / "scene";
    std::string out;
    int rc = test::run_command(test::ddhgs_binary() +
                                   " synth --preset demo --width 48 --height 36 --bands 8"
                                   " --views 12 --points 800 --out " +
                                   d.string(),
                               &out);
    EXPECT_EQ(rc, 0) << out;
    return d;
  }();
  return dir;
}

int train(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " train " + args, out);
}

using test::read_json;

// A copy of `run` taken back to its numbered checkpoint at `iteration`, as if
// it had been interrupted there.
void copy_back_to(const fs::path& run, int64_t iteration, const fs::path& copy) {
  fs::remove_all(copy);
  fs::copy(run, copy, fs::copy_options::recursive);
  fs::copy_file(copy / "checkpoints" / ("ckpt_" + std::to_string(iteration) + ".pt"),
                copy / "checkpoint.pt", fs::copy_options::overwrite_existing);
  fs::remove(copy / "gaussians.ply");
}

std::vector<nlohmann::json> read_metrics(const fs::path& p) {
  std::vector<nlohmann::json> records;
  std::istringstream lines(io::read_file(p));
  for (std::string line; std::getline(lines, line);) records.push_back(nlohmann::json::parse(line));
  return records;
}

TEST(TrainCli, TrainsDensifiesAndResumesBitForBit) {
  fs::path runs = test::temp_dir("train_cli_runs");
  std::string out;
  const fs::path straight = runs / "straight";
  ASSERT_EQ(
      train(scene().string() + " --out " + straight.string() + " --iterations 200" + kSchedule,
            &out),
      0)
      << out;
  for (const char* f : {"config.json", "gaussians.ply", "checkpoint.pt", "metrics.jsonl",
                        "train_summary.json", "checkpoints/ckpt_100.pt", "checkpoints/ckpt_200.pt"})
    EXPECT_TRUE(fs::exists(straight / f)) << f;

  auto summary = read_json(straight / "train_summary.json");
  EXPECT_EQ(summary["iterations"], 200);
  EXPECT_EQ(summary["bands"], 8);
  EXPECT_EQ(summary["bytes_per_gaussian"], (11 + 8 * 16) * 16);
  // ctest sets DDHGS_THREADS=2 (tests/CMakeLists.txt).
  EXPECT_EQ(summary["threads"], 2);
  EXPECT_EQ(summary["thread_source"], "DDHGS_THREADS");
  // Fixed bars, far below what the run reaches but far above an untrained model.
  EXPECT_GT(summary["test_psnr_clean"].get<double>(), 19.0) << summary.dump();
  EXPECT_GT(summary["test_psnr"].get<double>(), 18.0) << summary.dump();

  auto metrics = read_metrics(straight / "metrics.jsonl");
  ASSERT_FALSE(metrics.empty());
  EXPECT_EQ(metrics.back()["iter"], 200);
  EXPECT_GT(metrics.back()["densify_added"].get<int>(), 0);
  EXPECT_GT(metrics.back()["densify_removed"].get<int>(), 0);
  EXPECT_GT(metrics.back()["train_psnr"].get<double>(),
            metrics.front()["train_psnr"].get<double>());

  auto config = read_json(straight / "config.json");
  EXPECT_EQ(config["format_version"], 2);
  // The demo preset learns the background: the constant backdrop of the synth
  // scene (its clean cubes' top rows are all backdrop) is recovered, from 0.
  EXPECT_EQ(config["model"]["learn_background"], true);
  auto learned = torch::tensor(
      read_json(straight / "background.json")["background"].get<std::vector<float>>());
  auto clean = io::cube_to_float(io::read_cube(scene() / "clean" / "r_000.npy"));
  auto backdrop = clean.select(0, 0).mean(0);  // [N]
  ASSERT_EQ(learned.size(0), backdrop.size(0));
  EXPECT_LT((learned - backdrop).abs().max().item<double>(),
            0.1 * backdrop.abs().max().item<double>())
      << learned << backdrop;
  EXPECT_EQ(config["data"]["path"], fs::absolute(scene()).lexically_normal().string());
  EXPECT_EQ(config["densify"]["every"], 30);

  // Stopped at 100, then resumed: the same bytes as the straight run.
  const fs::path split = runs / "split";
  copy_back_to(straight, 100, split);
  ASSERT_EQ(train("--resume " + split.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(split / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));
  auto resumed = read_metrics(split / "metrics.jsonl");
  ASSERT_EQ(resumed.size(), metrics.size());
  for (size_t i = 0; i < metrics.size(); ++i)
    EXPECT_EQ(resumed[i]["loss"], metrics[i]["loss"]) << i;
}

// A test record measures the Gaussians its step optimised, before that
// step's densification changes them. Two runs alike up to iteration 40, where
// one densifies (every Gaussian with a gradient cloned or split) and the other
// does not (densify.every 0): both record the same test PSNR at 40, though
// the first already holds more Gaussians there.
TEST(TrainCli, TestRecordsMeasureTheModelBeforeItsDensification) {
  fs::path runs = test::temp_dir("train_cli_test_records");
  const std::string common =
      " --preset demo --iterations 60 --set output.test_every=20 --set output.log_every=20"
      " --set densify.from_fraction=0.5 --set densify.until_fraction=1"
      " --set densify.opacity_reset_every_fraction=0 --set densify.grad_threshold=0";
  std::string out;
  const fs::path densified = runs / "densified", kept = runs / "kept";
  ASSERT_EQ(
      train(scene().string() + " --out " + densified.string() + common + " --set densify.every=20",
            &out),
      0)
      << out;
  ASSERT_EQ(
      train(scene().string() + " --out " + kept.string() + common + " --set densify.every=0", &out),
      0)
      << out;
  auto at = [](const fs::path& run, int iteration) {
    for (const auto& record : read_metrics(run / "metrics.jsonl"))
      if (record["iter"] == iteration) return record;
    ADD_FAILURE() << run << " has no record of iteration " << iteration;
    return nlohmann::json::object();
  };
  const auto a = at(densified, 40), b = at(kept, 40);
  ASSERT_TRUE(a.contains("test_psnr_clean")) << a.dump();
  EXPECT_GT(a["num_gaussians"].get<int64_t>(), b["num_gaussians"].get<int64_t>());
  EXPECT_EQ(a["test_psnr"], b["test_psnr"]);
  EXPECT_EQ(a["test_psnr_clean"], b["test_psnr_clean"]);
  // From there the models differ.
  EXPECT_NE(at(densified, 60)["test_psnr"], at(kept, 60)["test_psnr"]);
}

TEST(TrainCli, WavelengthEncoderTrainsResumesAndIsBakedIntoThePly) {
  // A large encoder learning rate so 120 iterations move its offsets visibly.
  const std::string args = " --wavelength-encoder --set wavelength_encoder.lr=1e-3" + kSchedule;
  fs::path runs = test::temp_dir("train_cli_encoder");
  std::string out;
  const fs::path straight = runs / "straight", split = runs / "split", off = runs / "off";
  ASSERT_EQ(
      train(scene().string() + " --out " + straight.string() + " --iterations 120" + args, &out), 0)
      << out;
  ASSERT_EQ(
      train(scene().string() + " --out " + off.string() + args + " --no-wavelength-encoder", &out),
      1);
  EXPECT_NE(out.find("conflicts with --no-wavelength-encoder"), std::string::npos) << out;
  ASSERT_EQ(
      train(scene().string() + " --out " + off.string() + " --iterations 120" + kSchedule, &out), 0)
      << out;
  // The encoder changes the model...
  EXPECT_NE(io::read_file(off / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));
  EXPECT_EQ(read_json(straight / "config.json")["wavelength_encoder"]["enabled"], true);
  EXPECT_GT(read_json(straight / "train_summary.json")["wavelength_offsets_abs_max"].get<double>(),
            0.0);

  // ...its weights and optimizer state resume bit for bit...
  copy_back_to(straight, 100, split);
  ASSERT_EQ(train("--resume " + split.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(split / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));

  // ...and the PLY carries the offsets: `ddhgs eval` renders the PLY alone and
  // gets the PSNR the trainer measured with the encoder.
  ASSERT_EQ(test::run_command(test::ddhgs_binary() + " eval " + straight.string(), &out), 0) << out;
  const double trained = read_json(straight / "train_summary.json")["test_psnr"].get<double>();
  const double evaluated = read_json(straight / "eval" / "metrics.json")["psnr"].get<double>();
  EXPECT_NEAR(evaluated, trained, 1e-4);
}

TEST(TrainCli, LatentColourModelTrainsResumesAndItsPlyRendersAsTrained) {
  const std::string args = " --set model.spectral_rank=3" + kSchedule;
  fs::path runs = test::temp_dir("train_cli_latent");
  std::string out;
  const fs::path straight = runs / "straight", split = runs / "split";
  ASSERT_EQ(
      train(scene().string() + " --out " + straight.string() + " --iterations 120" + args, &out), 0)
      << out;
  EXPECT_NE(out.find("colour model: 3 latent channels for 8 bands"), std::string::npos) << out;
  const auto summary = read_json(straight / "train_summary.json");
  EXPECT_EQ(summary["colour_channels"], 3);
  EXPECT_EQ(summary["bytes_per_gaussian"], (11 + 3 * 16) * 16);
  EXPECT_GT(summary["test_psnr_clean"].get<double>(), 19.0) << summary.dump();
  // The PLY holds 3 channels per Gaussian and the 8 bands' basis rows.
  const std::string ply = io::read_file(straight / "gaussians.ply");
  EXPECT_NE(ply.find("property float f_dc_2\n"), std::string::npos);
  EXPECT_EQ(ply.find("property float f_dc_3\n"), std::string::npos);
  size_t rows = 0;
  for (size_t at = ply.find("comment band_basis "); at != std::string::npos;
       at = ply.find("comment band_basis ", at + 1))
    ++rows;
  EXPECT_EQ(rows, 8u);

  // The basis, the coefficients and their optimizer state resume bit for bit.
  copy_back_to(straight, 100, split);
  ASSERT_EQ(train("--resume " + split.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(split / "gaussians.ply"), ply);
  // The log says where the basis comes from: the checkpoint, not a new PCA.
  EXPECT_NE(out.find("3 latent channels for 8 bands (basis and mean from the checkpoint)"),
            std::string::npos)
      << out;
  EXPECT_EQ(out.find("principal components"), std::string::npos) << out;

  // `ddhgs eval` renders the PLY alone and measures what the trainer did.
  ASSERT_EQ(test::run_command(test::ddhgs_binary() + " eval " + straight.string(), &out), 0) << out;
  EXPECT_NEAR(read_json(straight / "eval" / "metrics.json")["psnr"].get<double>(),
              summary["test_psnr"].get<double>(), 1e-4);

  // With the wavelength encoder, its output moves each band's basis row and
  // mean; the PLY holds the moved basis, so eval again measures what the
  // trainer did.
  const fs::path encoder = runs / "encoder";
  ASSERT_EQ(
      train(scene().string() + " --out " + encoder.string() +
                " --iterations 120 --wavelength-encoder --set wavelength_encoder.lr=1e-3" + args,
            &out),
      0)
      << out;
  const auto encoded = read_json(encoder / "train_summary.json");
  EXPECT_GT(encoded["wavelength_offsets_abs_max"].get<double>(), 0.0);
  EXPECT_NE(io::read_file(encoder / "gaussians.ply"), ply);
  ASSERT_EQ(test::run_command(test::ddhgs_binary() + " eval " + encoder.string(), &out), 0) << out;
  EXPECT_NEAR(read_json(encoder / "eval" / "metrics.json")["psnr"].get<double>(),
              encoded["test_psnr"].get<double>(), 1e-4);

  // A run of 120 iterations with `settings`, and a copy resumed from its
  // checkpoint at 100 that must end with the same PLY, bit for bit.
  const auto train_and_resume = [&](const std::string& name, const std::string& settings,
                                    std::string* run_ply) {
    const fs::path run = runs / name, split = runs / (name + "_split");
    ASSERT_EQ(
        train(scene().string() + " --out " + run.string() + " --iterations 120" + settings + args,
              &out),
        0)
        << out;
    *run_ply = io::read_file(run / "gaussians.ply");
    copy_back_to(run, 100, split);
    ASSERT_EQ(train("--resume " + split.string(), &out), 0) << out;
    EXPECT_EQ(io::read_file(split / "gaussians.ply"), *run_ply);
  };

  // Measuring 3 of the 8 bands a step (drawn from seed and iteration, the
  // drawn rows' Adam state in the checkpoint) resumes bit for bit too.
  std::string sampled_ply;
  ASSERT_NO_FATAL_FAILURE(
      train_and_resume("sampled", " --set loss.bands_per_step=3", &sampled_ply));
  EXPECT_NE(sampled_ply, ply);

  // Measuring a random crop of half the pixels a step (drawn from seed and
  // iteration) resumes bit for bit too. The scene's views are below the
  // default threshold (loss.view_fraction_from_pixels), so the default run
  // above measured whole views and this one crops them at the default 0.5.
  std::string cropped_ply;
  ASSERT_NO_FATAL_FAILURE(
      train_and_resume("cropped", " --set loss.view_fraction_from_pixels=0", &cropped_ply));
  EXPECT_NE(cropped_ply, ply);
  EXPECT_GT(read_json(runs / "cropped" / "train_summary.json")["test_psnr_clean"].get<double>(),
            19.0);

  // A rank above the band count is refused before anything is written.
  ASSERT_EQ(train(scene().string() + " --out " + (runs / "nine").string() +
                      " --set model.spectral_rank=9",
                  &out),
            1);
  EXPECT_NE(out.find("model.spectral_rank 9 is above the scene's 8 bands"), std::string::npos)
      << out;
  EXPECT_FALSE(fs::exists(runs / "nine"));
}

// The default (model.spectral_rank -1) is a subspace at the scene's signal
// rank from model.subspace_from_bands bands on, per band below.
TEST(TrainCli, DefaultColourModelFollowsTheBandCount) {
  fs::path runs = test::temp_dir("train_cli_auto_rank");
  std::string out;
  ASSERT_EQ(train(scene().string() + " --out " + (runs / "eight").string() + " --iterations 10" +
                      kSchedule,
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("one SH set per band (8 bands, below model.subspace_from_bands 16)"),
            std::string::npos)
      << out;
  EXPECT_EQ(read_json(runs / "eight" / "train_summary.json")["colour_channels"], 8);
  ASSERT_EQ(train(scene().string() + " --out " + (runs / "from8").string() +
                      " --iterations 10 --set model.subspace_from_bands=8" + kSchedule,
                  &out),
            0)
      << out;
  const int64_t k = read_json(runs / "from8" / "train_summary.json")["colour_channels"];
  EXPECT_GE(k, 1);
  EXPECT_LT(k, 8);
  EXPECT_NE(out.find("colour model: " + std::to_string(k) + " latent channels for 8 bands"),
            std::string::npos)
      << out;
}

TEST(TrainCli, TrainsOnEverySecondBandAndEvalMeasuresTheOthers) {
  fs::path runs = test::temp_dir("train_cli_held_out");
  std::string out;
  const fs::path run = runs / "run";
  ASSERT_EQ(
      train(scene().string() + " --out " + run.string() +
                " --iterations 120 --set data.band_step=2 --set model.spectral_rank=2" + kSchedule,
            &out),
      0)
      << out;
  EXPECT_EQ(read_json(run / "train_summary.json")["bands"], 4);  // bands 0, 2, 4, 6 of 8
  ASSERT_EQ(
      test::run_command(test::ddhgs_binary() + " eval " + run.string() + " --held-out-bands", &out),
      0)
      << out;
  const auto held = read_json(run / "eval" / "held_out_bands.json");
  EXPECT_EQ(held["truth"], "clean");
  // Bands 1, 3 and 5 lie between trained ones; band 7 beyond the last is
  // not extrapolated.
  ASSERT_EQ(held["bands"].size(), 7u);
  for (size_t b = 0; b < 7; ++b) EXPECT_EQ(held["bands"][b]["held_out"], b % 2 == 1) << b;
  EXPECT_EQ(held["skipped_nm"].size(), 1u);
  // Far above an unrelated image, though 86 nm apart the red edge does not
  // interpolate well (on 141 bands it does: docs/benchmarks.md).
  EXPECT_GT(held["held_out_psnr"].get<double>(), 15.0) << held.dump();
  EXPECT_GT(held["trained_psnr"].get<double>(), 19.0) << held.dump();
  // A run that trained on every band has nothing held out.
  const fs::path every = runs / "every";
  ASSERT_EQ(train(scene().string() + " --out " + every.string() + " --iterations 20", &out), 0)
      << out;
  ASSERT_EQ(test::run_command(
                test::ddhgs_binary() + " eval " + every.string() + " --held-out-bands", &out),
            1);
  EXPECT_NE(out.find("no band is held out"), std::string::npos) << out;
}

TEST(TrainCli, RefusesAnExistingRunAndBadConfigs) {
  fs::path runs = test::temp_dir("train_cli_refuse");
  fs::create_directories(runs / "taken");
  std::ofstream(runs / "taken" / "keep.txt") << "earlier results";
  std::string out;
  for (const char* force : {"", " --force"}) {
    EXPECT_EQ(train(scene().string() + " --out " + (runs / "taken").string() + force, &out), 1);
    EXPECT_NE(out.find("holds files ddhgs did not write"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(runs / "taken" / "keep.txt"));
  }

  EXPECT_EQ(
      train(scene().string() + " --out " + (runs / "a").string() + " --set densify.evry=3", &out),
      1);
  EXPECT_NE(out.find("unknown key 'densify.evry'"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(runs / "a"));

  EXPECT_EQ(
      train(scene().string() + " --out " + (runs / "b").string() + " --set iterations=x", &out), 1);
  EXPECT_NE(out.find("'iterations' must be an integer"), std::string::npos) << out;

  EXPECT_EQ(train((runs / "missing").string() + " --out " + (runs / "c").string(), &out), 1);
  EXPECT_NE(out.find("no such dataset folder"), std::string::npos) << out;

  EXPECT_EQ(train("--resume " + (runs / "taken").string(), &out), 1);
  EXPECT_NE(out.find("not a ddhgs run folder"), std::string::npos) << out;
}

}  // namespace
}  // namespace ddhgs
