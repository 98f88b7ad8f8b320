// The diffusion denoiser end to end (`ddhgs train` with loss.diffusion,
// `ddhgs eval` and `ddhgs render --denoise`) and `ddhgs ablate` on a tiny
// synthetic scene.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include "io/files/atomic_file.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

// A small U-Net and a short warm-up, so the term trains within 60 iterations;
// 20 denoiser fine-tuning steps follow the Gaussian iterations.
const std::string kDiffusion =
    " --preset demo --set diffusion.warmup=20 --set diffusion.base_channels=8"
    " --set diffusion.channel_multipliers=[1,2] --set diffusion.crop=16"
    " --set diffusion.sampler_steps=2 --set diffusion.sampler_samples=1"
    " --set diffusion.finetune_steps=20 --checkpoint-every 10";

const fs::path& scene() {
  static const fs::path dir = [] {
    fs::path d = test::temp_dir("ablate_cli_scene") / "scene";
    std::string out;
    int rc = test::run_command(test::ddhgs_binary() +
                                   " synth --preset demo --width 40 --height 32 --bands 6"
                                   " --views 10 --points 600 --out " +
                                   d.string(),
                               &out);
    EXPECT_EQ(rc, 0) << out;
    return d;
  }();
  return dir;
}

int ddhgs(const std::string& args, std::string* out) {
  return test::run_command(test::ddhgs_binary() + " " + args, out);
}

using test::read_json;

TEST(DenoiserCli, TrainsResumesBitForBitEvaluatesAndRenders) {
  const fs::path runs = test::temp_dir("denoiser_cli_runs");
  const fs::path straight = runs / "straight", split = runs / "split", plain = runs / "plain";
  const std::string train = "train " + scene().string() + " --set loss.diffusion=0.3" + kDiffusion;
  std::string out;
  ASSERT_EQ(ddhgs(train + " --iterations 60 --out " + straight.string(), &out), 0) << out;
  ASSERT_TRUE(fs::exists(straight / "denoiser.pt"));
  std::ifstream metrics(straight / "metrics.jsonl");
  double last_diffusion = -1;
  int finetune_records = 0;
  for (std::string line; std::getline(metrics, line);) {
    auto record = nlohmann::json::parse(line);
    const int iter = record["iter"].get<int>();
    if (iter > 20 && iter <= 60) last_diffusion = record.value("diffusion", -1.0);
    if (iter > 60) {
      EXPECT_EQ(record["phase"], "denoiser") << line;
      EXPECT_GT(record["diffusion_identity"].get<double>(), 0.0) << line;
      ++finetune_records;
    }
  }
  EXPECT_GT(last_diffusion, 0.0);
  EXPECT_GE(finetune_records, 2);
  auto summary = read_json(straight / "train_summary.json");
  EXPECT_EQ(summary["iterations"], 60);
  EXPECT_EQ(summary["denoiser_finetune_steps"], 20);
  EXPECT_GT(summary["denoiser_finetune_seconds"].get<double>(), 0.0);

  // The Gaussians are frozen while the denoiser is fine-tuned: the export
  // equals the one rendered from the checkpoint at the end of iteration 60.
  const fs::path at_60 = runs / "at_60";
  fs::copy(straight, at_60, fs::copy_options::recursive);
  fs::copy_file(at_60 / "checkpoints" / "ckpt_60.pt", at_60 / "checkpoint.pt",
                fs::copy_options::overwrite_existing);
  auto config = read_json(at_60 / "config.json");
  config["diffusion"]["finetune_steps"] = 0;
  io::write_file_atomically(at_60 / "config.json", config.dump(2));
  ASSERT_EQ(ddhgs("train --resume " + at_60.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(at_60 / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));
  EXPECT_NE(io::read_file(at_60 / "denoiser.pt"), io::read_file(straight / "denoiser.pt"));

  // Trained to 30 (and fine-tuned), then continued to 60: back to the end of
  // iteration 30, then the same Gaussians and U-Net as straight through. The
  // schedule stretches with the run's length, so these runs keep it flat: no
  // densification, SH degree 0, constant learning rates.
  const std::string flat =
      train + " --set densify.until_fraction=0 --set model.sh_degree_every_fraction=0" +
      " --set optim.lr_final_scale=1 --set optim.means_lr_final=" +
      read_json(straight / "config.json")["optim"]["means_lr_init"].dump();
  const fs::path flat_straight = runs / "flat_straight";
  ASSERT_EQ(ddhgs(flat + " --iterations 60 --out " + flat_straight.string(), &out), 0) << out;
  ASSERT_EQ(ddhgs(flat + " --iterations 30 --out " + split.string(), &out), 0) << out;
  // Without the checkpoint at the end of the Gaussian iterations there is
  // nothing to go back to: one line naming it and how to finish the run.
  const fs::path no_end = runs / "no_end";
  fs::copy(split, no_end, fs::copy_options::recursive);
  fs::remove(no_end / "checkpoints" / "ckpt_30.pt");
  EXPECT_NE(ddhgs("train --resume " + no_end.string() + " --iterations 60", &out), 0);
  EXPECT_NE(out.find("ckpt_30.pt: missing"), std::string::npos) << out;
  EXPECT_NE(out.find("resume without --iterations"), std::string::npos) << out;
  ASSERT_EQ(ddhgs("train --resume " + split.string() + " --iterations 60", &out), 0) << out;
  EXPECT_NE(out.find("continuing from the end of the Gaussian iterations"), std::string::npos)
      << out;
  EXPECT_EQ(io::read_file(split / "gaussians.ply"), io::read_file(flat_straight / "gaussians.ply"));
  EXPECT_EQ(io::read_file(split / "denoiser.pt"), io::read_file(flat_straight / "denoiser.pt"));

  // Without room to cache the renders, each step renders the views it draws:
  // the same U-Net.
  const fs::path uncached = runs / "uncached";
  ASSERT_EQ(ddhgs(train + " --iterations 60 --set diffusion.finetune_cache_mb=0 --out " +
                      uncached.string(),
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("rendering them as they are drawn"), std::string::npos) << out;
  EXPECT_EQ(io::read_file(uncached / "denoiser.pt"), io::read_file(straight / "denoiser.pt"));

  // Interrupted in the middle of the fine-tuning (checkpoint 70) and resumed.
  const fs::path mid = runs / "mid";
  fs::copy(straight, mid, fs::copy_options::recursive);
  fs::copy_file(mid / "checkpoints" / "ckpt_70.pt", mid / "checkpoint.pt",
                fs::copy_options::overwrite_existing);
  fs::remove(mid / "denoiser.pt");
  ASSERT_EQ(ddhgs("train --resume " + mid.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(mid / "denoiser.pt"), io::read_file(straight / "denoiser.pt"));

  ASSERT_EQ(ddhgs("eval " + straight.string() + " --denoise-steps 1,2 --fps-repeats 1", &out), 0)
      << out;
  auto denoised = read_json(straight / "eval" / "denoised.json");
  ASSERT_EQ(denoised["settings"].size(), 2u);
  EXPECT_EQ(denoised["settings"][1]["name"], "ddim2");
  for (const auto& s : denoised["settings"]) {
    EXPECT_TRUE(std::isfinite(s["clean"]["psnr"].get<double>())) << s.dump();
    EXPECT_GT(s["fps"].get<double>(), 0.0);
  }
  // Seeded: a second evaluation gives the same numbers.
  ASSERT_EQ(ddhgs("eval " + straight.string() + " --denoise-steps 1,2 --fps-repeats 1", &out), 0);
  auto again = read_json(straight / "eval" / "denoised.json");
  EXPECT_EQ(again["settings"][1]["psnr"], denoised["settings"][1]["psnr"]);
  ASSERT_EQ(
      ddhgs("eval " + straight.string() + " --denoise-steps 2 --samples 3 --fps-repeats 0", &out),
      0)
      << out;
  auto mean = read_json(straight / "eval" / "denoised.json")["settings"][0];
  EXPECT_EQ(mean["name"], "ddim2-mean3");
  EXPECT_EQ(mean["samples"], 3);
  EXPECT_NE(mean["psnr"], denoised["settings"][1]["psnr"]);

  ASSERT_EQ(ddhgs("render " + straight.string() + " --denoise 2 --format npy", &out), 0) << out;
  EXPECT_FALSE(fs::is_empty(straight / "renders" / "test_ddim2"));
  // The mean of several samples goes to its own folder, named as eval names it.
  ASSERT_EQ(ddhgs("render " + straight.string() + " --denoise 2 --samples 2 --format npy", &out), 0)
      << out;
  EXPECT_FALSE(fs::is_empty(straight / "renders" / "test_ddim2-mean2"));

  ASSERT_EQ(
      ddhgs(train + " --iterations 30 --out " + plain.string() + " --set loss.diffusion=0", &out),
      0)
      << out;
  EXPECT_FALSE(fs::exists(plain / "denoiser.pt"));
  EXPECT_EQ(ddhgs("render " + plain.string() + " --denoise 2", &out), 1);
  EXPECT_NE(out.find("no denoiser.pt"), std::string::npos) << out;
}

// Novel-view pairs: the denoiser learns from renders of views that auxiliary
// models never saw, is checked on training views it did not learn from, and
// is distilled back into the Gaussians through pseudo-views between cameras.
TEST(DenoiserCli, FoldPairsValidationAndDistillationResumeBitForBit) {
  const fs::path runs = test::temp_dir("denoiser_fold_runs");
  const fs::path straight = runs / "straight", plain = runs / "plain", stopped = runs / "stopped";
  // 40 Gaussian iterations, 20 fine-tuning steps (41-60), 40 distillation
  // steps (61-100), every second on a pseudo-view.
  const std::string stage =
      " --set loss.diffusion=0.3 --set diffusion.joint=false --set diffusion.pairs=folds"
      " --set diffusion.folds=2 --set diffusion.fold_iterations=0.5"
      " --set diffusion.distill_steps=40 --set diffusion.validation_every=0";
  const std::string train = "train " + scene().string() + kDiffusion +
                            " --iterations 40 --set output.test_every=40 --set output.log_every=1";
  std::string out;
  ASSERT_EQ(ddhgs(train + stage + " --out " + straight.string(), &out), 0) << out;
  // Two auxiliary models of 20 iterations rendered the 9 training views.
  EXPECT_NE(out.find("denoiser pairs: 9 training views rendered by 2 auxiliary models"),
            std::string::npos)
      << out;
  auto summary = read_json(straight / "train_summary.json");
  EXPECT_EQ(summary["denoiser_pairs"], "folds");
  EXPECT_EQ(summary["distill_steps"], 40);
  const int pseudo_views = summary["pseudo_views"].get<int>();
  EXPECT_GE(pseudo_views, 5);  // about one per gap between the 9 cameras
  EXPECT_FALSE(fs::exists(straight / "pseudo_views.pt"));  // removed at the end
  std::ifstream metrics(straight / "metrics.jsonl");
  int pseudo_steps = 0, view_steps = 0;
  for (std::string line; std::getline(metrics, line);) {
    auto record = nlohmann::json::parse(line);
    const int iter = record["iter"].get<int>();
    // No joint term: the Gaussian iterations cost what they cost without it.
    if (iter <= 40) {
      EXPECT_FALSE(record.contains("diffusion")) << line;
    }
    if (iter > 60) {
      EXPECT_EQ(record["phase"], "distill") << line;
      if (record.contains("pseudo_view")) {
        ++pseudo_steps;
        EXPECT_EQ((iter - 61) % 2, 1) << line;
        EXPECT_EQ(record["pseudo_view"].get<int>(), ((iter - 61) / 2) % pseudo_views) << line;
      } else {
        ++view_steps;
      }
    }
  }
  EXPECT_EQ(pseudo_steps, 20);
  EXPECT_EQ(view_steps, 20);

  // Without the stage's joint term the first 40 iterations are those of a
  // run without the stage: the same test PSNR before the distillation.
  ASSERT_EQ(ddhgs(train + " --out " + plain.string(), &out), 0) << out;
  const auto plain_summary = read_json(plain / "train_summary.json");
  EXPECT_EQ(summary["test_psnr_before_distillation"], plain_summary["test_psnr"]);
  EXPECT_NE(summary["test_psnr"], plain_summary["test_psnr"]);

  // Stopped (SIGINT) during the distillation and resumed: the pseudo-views
  // are kept for the resumed run, which ends where the straight one did.
  const std::string background =
      test::ddhgs_binary() + " " + train + stage + " --out " + stopped.string();
  const std::string metrics_file = (stopped / "metrics.jsonl").string();
  ASSERT_EQ(test::run_command("sh -c '" + background + " & pid=$!; until grep -q distill " +
                                  metrics_file + " 2>/dev/null; do sleep 0.02; done; kill -INT " +
                                  "$pid; wait $pid'",
                              &out),
            130)
      << out;
  ASSERT_TRUE(fs::exists(stopped / "pseudo_views.pt")) << out;
  ASSERT_EQ(ddhgs("train --resume " + stopped.string(), &out), 0) << out;
  EXPECT_EQ(io::read_file(stopped / "gaussians.ply"), io::read_file(straight / "gaussians.ply"));
  EXPECT_FALSE(fs::exists(stopped / "pseudo_views.pt"));

  // With a validation share the denoiser is measured on training views it
  // did not learn from, and distils only if it gained there.
  const fs::path checked = runs / "checked";
  ASSERT_EQ(
      ddhgs(train + stage + " --set diffusion.validation_every=4 --out " + checked.string(), &out),
      0)
      << out;
  summary = read_json(checked / "train_summary.json");
  const auto& validation = summary["denoiser_validation"];
  EXPECT_EQ(validation["views"], 2);  // positions 2 and 6 of the 9
  const double render = validation["psnr_render"], denoised = validation["psnr_denoised"];
  EXPECT_TRUE(std::isfinite(render) && std::isfinite(denoised)) << validation.dump();
  if (denoised > render) {
    EXPECT_EQ(summary["pseudo_views"], pseudo_views);
  } else {
    EXPECT_EQ(summary["pseudo_views"], 0);
    EXPECT_NE(out.find("distillation skipped"), std::string::npos) << out;
  }
}

// The cheaper pair sources, one auxiliary model each. An earlier
// checkpoint is recomputed with the run's own seed and schedule: taken at the
// run's end it is the run itself, so its pairs are the training pairs to the
// last bit; earlier, and with turned cameras, the renders fit their captures
// less well.
TEST(DenoiserCli, CheckpointAndPerturbedPairsAreRendersTheRunDidNotFit) {
  const fs::path runs = test::temp_dir("denoiser_pair_sources");
  const std::string train =
      "train " + scene().string() + kDiffusion + " --iterations 40 --set output.test_every=40" +
      " --set loss.diffusion=0.3 --set diffusion.joint=false" + " --set diffusion.finetune_steps=2";
  std::string out;
  auto pairs_psnr = [&](const std::string& name, const std::string& set) {
    const fs::path run = runs / name;
    EXPECT_EQ(ddhgs(train + set + " --out " + run.string(), &out), 0) << out;
    const auto summary = read_json(run / "train_summary.json");
    EXPECT_TRUE(summary.contains("denoiser_pairs_psnr")) << summary.dump();
    return summary.value("denoiser_pairs_psnr", 0.0);
  };
  const double fitted = pairs_psnr("training", "");
  const double at_end =
      pairs_psnr("end", " --set diffusion.pairs=checkpoint --set diffusion.fold_iterations=1");
  EXPECT_NE(out.find("rendered by the Gaussians as they were at iteration 40"), std::string::npos)
      << out;
  EXPECT_EQ(at_end, fitted);
  // Measured: 20.06 dB fitted, 15.75 at iteration 20, 19.91 with 3 px turns.
  const double halfway = pairs_psnr(
      "halfway", " --set diffusion.pairs=checkpoint --set diffusion.fold_iterations=0.5");
  EXPECT_NE(out.find("rendered by the Gaussians as they were at iteration 20"), std::string::npos)
      << out;
  EXPECT_LT(halfway, fitted - 1.0);
  const double perturbed =
      pairs_psnr("perturbed",
                 " --set diffusion.pairs=perturbed --set diffusion.fold_iterations=1"
                 " --set diffusion.perturb_px=3");
  EXPECT_NE(out.find("each camera turned by 3 px (40 iterations"), std::string::npos) << out;
  EXPECT_EQ(read_json(runs / "perturbed" / "train_summary.json")["denoiser_pairs"], "perturbed");
  EXPECT_LT(perturbed, fitted - 0.05);
}

TEST(AblateCli, WritesEveryRowWithFiniteValuesAndReusesFinishedRows) {
  const fs::path dir = test::temp_dir("ablate_cli") / "ablation";
  const std::string ablate =
      "ablate " + scene().string() + " --out " + dir.string() +
      " --preset demo --set iterations=40 --set diffusion.warmup=20"
      " --set diffusion.base_channels=8 --set diffusion.channel_multipliers=[1,2]"
      " --set diffusion.crop=16 --set diffusion.finetune_steps=10 --denoise-steps 2"
      " --fps-repeats 1";
  std::string out;
  ASSERT_EQ(ddhgs(ablate, &out), 0) << out;
  auto table = read_json(dir / "ablation.json");
  std::vector<std::string> rows, outputs;
  for (const auto& e : table["rows"]) {
    rows.push_back(e["row"]);
    outputs.push_back(e["output"]);
    for (const char* truth : {"views", "clean"})
      for (const char* key : {"psnr", "ssim", "sam", "rmse"})
        EXPECT_TRUE(std::isfinite(e[truth][key].get<double>())) << e.dump();
    EXPECT_GT(e["seconds_per_iteration"].get<double>(), 0.0);
    EXPECT_GT(e["fps"].get<double>(), 0.0);
  }
  EXPECT_EQ(rows, (std::vector<std::string>{"3dgs", "sl", "we", "we+sl", "diffusion", "diffusion",
                                            "full", "full", "subspace", "folds", "folds",
                                            "distilled", "distilled"}));
  EXPECT_EQ(outputs[4], "render");
  EXPECT_EQ(outputs[5], "ddim2-mean4");  // the default: the mean of 4 samples
  const std::string md = io::read_file(dir / "ablation.md");
  for (const char* line : {"| 3dgs | render |", "| we+sl | render |", "| full | ddim2-mean4, s="})
    EXPECT_NE(md.find(line), std::string::npos) << line << "\n" << md;

  // Each row switches exactly its components on.
  auto config = [&](const char* row) { return read_json(dir / row / "config.json"); };
  EXPECT_EQ(config("3dgs")["loss"]["spectral"], 0.0);
  EXPECT_EQ(config("3dgs")["wavelength_encoder"]["enabled"], false);
  EXPECT_EQ(config("sl")["loss"]["spectral"], 0.1);
  EXPECT_EQ(config("we")["wavelength_encoder"]["enabled"], true);
  EXPECT_EQ(config("diffusion")["loss"]["diffusion"], 0.3);
  EXPECT_EQ(config("full")["loss"]["spectral"], 0.1);
  EXPECT_EQ(config("full")["wavelength_encoder"]["enabled"], true);
  EXPECT_EQ(config("3dgs")["model"]["spectral_rank"], 0);
  EXPECT_EQ(config("subspace")["model"]["spectral_rank"], -1);
  EXPECT_EQ(config("subspace")["model"]["subspace_from_bands"], 0);  // a subspace at 8 bands too
  EXPECT_EQ(config("subspace")["loss"]["spectral"], 0.0);
  EXPECT_EQ(config("folds")["diffusion"]["pairs"], "folds");
  EXPECT_EQ(config("folds")["diffusion"]["joint"], false);
  EXPECT_EQ(config("folds")["diffusion"]["distill_steps"], 0);
  EXPECT_EQ(config("distilled")["diffusion"]["distill_steps"], 10);  // a quarter of 40
  EXPECT_EQ(read_json(dir / "distilled" / "train_summary.json")["distill_steps"], 10);
  EXPECT_NE(io::read_file(dir / "subspace" / "gaussians.ply").find("comment band_basis"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "we+sl" / "denoiser.pt"));
  EXPECT_TRUE(fs::exists(dir / "full" / "denoiser.pt"));
  EXPECT_NE(io::read_file(dir / "3dgs" / "gaussians.ply"),
            io::read_file(dir / "sl" / "gaussians.ply"));

  // The same command again trains nothing and gives the same quality numbers.
  ASSERT_EQ(ddhgs(ablate + " --rows 3dgs,full", &out), 0) << out;
  EXPECT_NE(out.find("reusing"), std::string::npos) << out;
  auto second = read_json(dir / "ablation.json");
  ASSERT_EQ(second["rows"].size(), 3u);
  EXPECT_EQ(second["rows"][2]["clean"], table["rows"][7]["clean"]);

  // Denoiser settings do not concern the rows without it: still reused.
  ASSERT_EQ(ddhgs(ablate + " --rows 3dgs,sl --set diffusion.min_snr_gamma=5", &out), 0) << out;
  for (const char* row : {"3dgs", "sl"})
    EXPECT_NE(out.find((dir / row).string() + " is already trained with this config; reusing"),
              std::string::npos)
        << row << "\n"
        << out;

  // Sampler keys only change the evaluation: the full row is reused, evaluated
  // with the new value, and its config says so for later `ddhgs eval` runs.
  ASSERT_EQ(ddhgs(ablate + " --rows full --set diffusion.sampler_samples=2", &out), 0) << out;
  EXPECT_NE(out.find("full is already trained with this config; reusing"), std::string::npos)
      << out;
  EXPECT_EQ(read_json(dir / "ablation.json")["rows"][1]["output"], "ddim2-mean2");
  EXPECT_EQ(config("full")["diffusion"]["sampler_samples"], 2);

  // Only the fine-tuning changed: the full row continues from the end of its
  // Gaussian iterations, so its raw render is unchanged and its denoiser is not.
  const std::string full_denoiser = io::read_file(dir / "full" / "denoiser.pt");
  ASSERT_EQ(ddhgs(ablate + " --rows full --set diffusion.finetune_steps=15", &out), 0) << out;
  EXPECT_NE(out.find("differs only in the denoiser's fine-tuning"), std::string::npos) << out;
  auto refined = read_json(dir / "ablation.json");
  EXPECT_EQ(refined["rows"][0]["clean"], table["rows"][6]["clean"]);
  EXPECT_NE(io::read_file(dir / "full" / "denoiser.pt"), full_denoiser);
  EXPECT_EQ(read_json(dir / "full" / "train_summary.json")["denoiser_finetune_steps"], 15);

  EXPECT_EQ(ddhgs(ablate + " --rows 3dgs,wavelet", &out), 1);
  EXPECT_NE(out.find("unknown row 'wavelet'"), std::string::npos) << out;
}

}  // namespace
}  // namespace ddhgs
