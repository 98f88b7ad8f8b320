// A flight larger than one machine: `ddhgs partition` cuts a synthetic
// survey into blocks, each block trains as an ordinary scene, and `ddhgs
// merge` joins them into a run that eval, render and export read over the
// whole flight. Bad input leaves nothing behind.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <set>

#include "io/blocks/block_grid.h"
#include "io/blocks/partition.h"
#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "io/scene/scene.h"
#include "reliability/cli_support.h"
#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;
using test::ddhgs;

// A 12-capture survey of two lines over a field into `flight` (more synth
// flags in `extra`); its registered 5-band cubes.
fs::path synth_survey(const fs::path& flight, const std::string& extra = "") {
  std::string out;
  EXPECT_EQ(ddhgs("-q synth --preset rig-nadir --views 12 --lines 2 --field-spacing 1.5 "
                  "--width 32 --height 24 --supersample 1 " +
                      extra + " --out " + flight.string(),
                  &out),
            0)
      << out;
  return flight / "cubes";
}

const fs::path& survey() {
  static const fs::path scene = synth_survey(test::temp_dir("blocks_cli") / "flight");
  return scene;
}

int64_t gaussians_in_cell(const fs::path& ply, const io::BlockGrid& grid, int block) {
  const io::GaussianPly model = io::read_gaussian_ply(ply);
  const torch::Tensor means = model.means.to(torch::kFloat64).contiguous();
  const double* p = means.data_ptr<double>();
  int64_t count = 0;
  for (int64_t g = 0; g < means.size(0); ++g) {
    const core::Vec3 x{p[3 * g], p[3 * g + 1], p[3 * g + 2]};
    count += grid.block_of(grid.frame.along(x), grid.frame.across(x)) == block;
  }
  return count;
}

TEST(BlocksCli, PartitionTrainMergeEvaluatesEveryHeldOutView) {
  const fs::path root = test::temp_dir("blocks_cli_flow");
  const fs::path blocks = root / "blocks", merged = root / "merged";
  std::string out;
  ASSERT_EQ(
      ddhgs("partition " + survey().string() + " --blocks 2 --overlap 0.2 --out " + blocks.string(),
            &out),
      0)
      << out;
  const io::BlocksFile file = io::read_blocks_file(blocks / "blocks.json");
  ASSERT_EQ(file.blocks.size(), 2u);
  EXPECT_EQ(file.grid.rows * file.grid.cols, 2);
  const auto scene = io::load_scene(survey());
  std::set<std::string> scene_test, block_test, block_train;
  for (int v : scene->test) scene_test.insert(scene->views[size_t(v)].name);
  int64_t points = 0;
  for (const io::BlockRecord& b : file.blocks) {
    const auto block = io::load_scene(blocks / b.name);
    EXPECT_EQ(block->train.size(), b.train_views.size());
    EXPECT_EQ(block->test.size(), b.test_views.size());
    EXPECT_TRUE(block->has_clean()) << b.name;
    EXPECT_EQ(block->wavelengths_nm, scene->wavelengths_nm);
    for (int v : block->test) block_test.insert(block->views[size_t(v)].name);
    for (int v : block->train) block_train.insert(block->views[size_t(v)].name);
    // Neither block holds every view: the cut is real.
    EXPECT_LT(block->views.size(), scene->views.size()) << b.name;
    points += b.points;
    EXPECT_TRUE(fs::exists(blocks / b.name / "synth.json") || !fs::exists(survey() / "synth.json"));
  }
  // The scene's split holds in every block: no held-out view is trained on.
  for (const std::string& name : block_test) EXPECT_TRUE(scene_test.count(name)) << name;
  for (const std::string& name : block_train) EXPECT_FALSE(scene_test.count(name)) << name;
  // The margins overlap: some points are in both blocks.
  EXPECT_GT(points, scene->points.xyz.size(0));

  for (const io::BlockRecord& b : file.blocks)
    ASSERT_EQ(ddhgs("-q train " + (blocks / b.name).string() + " --out " +
                        (blocks / b.name / "run").string() + test::kQuickTrain,
                    &out),
              0)
        << out;
  // --seam-blend 0: exactly each block's Gaussians in its own cell, as trained.
  const fs::path cut = root / "cut";
  ASSERT_EQ(
      ddhgs("-q merge " + blocks.string() + " --out " + cut.string() + " --seam-blend 0", &out), 0)
      << out;
  int64_t expected = 0;
  for (size_t b = 0; b < file.blocks.size(); ++b)
    expected += gaussians_in_cell(blocks / file.blocks[b].name / "run" / "gaussians.ply", file.grid,
                                  int(b));
  EXPECT_EQ(io::read_gaussian_ply(cut / "gaussians.ply").means.size(0), expected);
  // By default the blocks are cross-faded across the border: every Gaussian
  // with a weight above 0 (BlockGrid::blend_weight) is kept, its opacity
  // times that weight, in block order.
  ASSERT_EQ(ddhgs("merge " + blocks.string() + " --out " + merged.string(), &out), 0) << out;
  const io::GaussianPly joint = io::read_gaussian_ply(merged / "gaussians.ply");
  const torch::Tensor joint_opacity = torch::sigmoid(joint.logit_opacities.to(torch::kFloat64));
  int64_t at = 0, faded = 0;
  for (size_t b = 0; b < file.blocks.size(); ++b) {
    const io::GaussianPly block =
        io::read_gaussian_ply(blocks / file.blocks[b].name / "run" / "gaussians.ply");
    const torch::Tensor means = block.means.to(torch::kFloat64).contiguous();
    const torch::Tensor opacity = torch::sigmoid(block.logit_opacities.to(torch::kFloat64));
    for (int64_t g = 0; g < means.size(0); ++g) {
      const core::Vec3 x{means[g][0].item<double>(), means[g][1].item<double>(),
                         means[g][2].item<double>()};
      const double w =
          file.grid.blend_weight(int(b), file.grid.frame.along(x), file.grid.frame.across(x), 1);
      if (w <= 0) continue;
      ASSERT_LT(at, joint.means.size(0));
      EXPECT_TRUE(torch::equal(joint.means[at], block.means[g])) << at;
      EXPECT_NEAR(joint_opacity[at].item<double>(), w * opacity[g].item<double>(), 1e-6) << at;
      faded += w < 1;
      ++at;
    }
  }
  EXPECT_EQ(at, joint.means.size(0));
  EXPECT_GT(at, expected);  // the margins' Gaussians of both neighbours
  EXPECT_GT(faded, 0);
  EXPECT_NE(out.find("faded across the seams"), std::string::npos) << out;
  const json config = json::parse(io::read_file(merged / "config.json"));
  EXPECT_EQ(fs::path(config["data"]["path"].get<std::string>()),
            fs::absolute(survey()).lexically_normal());
  // One backdrop for the whole flight: every block drew over it, and so
  // does the merged run.
  const torch::Tensor backdrop = io::flight_backdrop(*scene, scene->train);
  const json drawn = json::parse(io::read_file(merged / "background.json"))["background"];
  ASSERT_EQ(int64_t(drawn.size()), scene->bands());
  for (int64_t k = 0; k < scene->bands(); ++k)
    EXPECT_FLOAT_EQ(drawn[size_t(k)].get<float>(), backdrop[k].item<float>()) << k;

  // eval measures the whole flight's held-out views; render and export read the run.
  ASSERT_EQ(ddhgs("-q eval " + merged.string(), &out), 0) << out;
  const std::string per_view = io::read_file(merged / "eval" / "per_view.csv");
  size_t measured = 0;  // a row against the views and one against the clean truth per view
  for (size_t at = per_view.find(",views,"); at != std::string::npos;
       at = per_view.find(",views,", at + 1))
    ++measured;
  EXPECT_EQ(measured, scene->test.size()) << per_view;
  EXPECT_EQ(ddhgs("-q export " + merged.string() + " --out " + (root / "m.ply").string(), &out), 0)
      << out;
  EXPECT_EQ(ddhgs("-q render " + merged.string() + " --split test", &out), 0) << out;
}

// Latent blocks have bases of their own; the merged model holds them side by
// side (and each block's mean as one more channel), so every Gaussian keeps
// the spectrum it had in its block.
TEST(BlocksCli, LatentBlocksKeepTheirSpectraInTheMergedModel) {
  const fs::path root = test::temp_dir("blocks_cli_latent");
  const fs::path blocks = root / "blocks", merged = root / "merged";
  std::string out;
  ASSERT_EQ(
      ddhgs("-q partition " + survey().string() + " --blocks 1x2 --out " + blocks.string(), &out),
      0)
      << out;
  const io::BlocksFile file = io::read_blocks_file(blocks / "blocks.json");
  for (const io::BlockRecord& b : file.blocks)
    ASSERT_EQ(ddhgs("-q train " + (blocks / b.name).string() + " --out " +
                        (root / "runs" / b.name).string() + test::kQuickTrain +
                        " --set model.spectral_rank=2",
                    &out),
              0)
        << out;
  ASSERT_EQ(ddhgs("-q merge " + blocks.string() + " --runs " + (root / "runs").string() +
                      "/{block} --out " + merged.string(),
                  &out),
            0)
      << out;
  constexpr double kC0 = 0.28209479177387814;
  const io::GaussianPly joint = io::read_gaussian_ply(merged / "gaussians.ply");
  ASSERT_TRUE(joint.basis.defined());
  EXPECT_EQ(joint.basis.size(1), 2 * (2 + 1));
  EXPECT_EQ(joint.mean.abs().max().item<float>(), 0.0f);
  const torch::Tensor joint_spectra = (joint.sh_dc * kC0).matmul(joint.basis.t());  // [G, N]
  int64_t at = 0;
  for (size_t b = 0; b < file.blocks.size(); ++b) {
    const io::GaussianPly block =
        io::read_gaussian_ply(root / "runs" / file.blocks[b].name / "gaussians.ply");
    ASSERT_EQ(block.basis.size(1), 2);
    const torch::Tensor means = block.means.to(torch::kFloat64);
    std::vector<int64_t> kept;
    for (int64_t g = 0; g < means.size(0); ++g) {
      const core::Vec3 x{means[g][0].item<double>(), means[g][1].item<double>(),
                         means[g][2].item<double>()};
      if (file.grid.blend_weight(int(b), file.grid.frame.along(x), file.grid.frame.across(x), 1) >
          0)
        kept.push_back(g);
    }
    const torch::Tensor index = torch::tensor(kept, torch::kInt64);
    const torch::Tensor own =
        (block.sh_dc.index_select(0, index) * kC0).matmul(block.basis.t()) + block.mean;
    const torch::Tensor there = joint_spectra.narrow(0, at, int64_t(kept.size()));
    EXPECT_TRUE(torch::allclose(there, own, 1e-5, 1e-5)) << (there - own).abs().max();
    EXPECT_TRUE(torch::equal(joint.means.narrow(0, at, int64_t(kept.size())),
                             block.means.index_select(0, index)));
    at += int64_t(kept.size());
  }
  EXPECT_EQ(at, joint.means.size(0));
  EXPECT_EQ(ddhgs("-q eval " + merged.string(), &out), 0) << out;
}

// The workstation flow (scripts/slurm/local.sh): every block trained by
// xargs -P, then merged; a second call trains nothing again.
// Each block carries its place in the flight (block.json) and trains as the
// flight's own model would have trained its ground: over the flight's
// training views (a step whose view is elsewhere moves its Gaussians on
// momentum alone), with the flight's extent, the loss only in its cell and
// margin. A block that is the whole flight trains bit for bit as the scene
// does on its own.
TEST(BlocksCli, ABlockTrainsOnItsFlightsScheduleAndExtent) {
  const fs::path root = test::temp_dir("blocks_cli_flight");
  const fs::path blocks = root / "blocks";
  std::string out;
  ASSERT_EQ(
      ddhgs("-q partition " + survey().string() + " --blocks 2 --out " + blocks.string(), &out), 0)
      << out;
  const io::BlocksFile file = io::read_blocks_file(blocks / "blocks.json");
  const auto scene = io::load_scene(survey());
  const double flight_extent = io::scene_extent(*scene, scene->train);
  const torch::Tensor backdrop = io::flight_backdrop(*scene, scene->train);
  for (size_t b = 0; b < file.blocks.size(); ++b) {
    const auto context = io::read_block_context(blocks / file.blocks[b].name);
    ASSERT_TRUE(context.has_value()) << file.blocks[b].name;
    EXPECT_EQ(context->name, file.blocks[b].name);
    EXPECT_EQ(context->flight_train_views, int64_t(scene->train.size()));
    EXPECT_DOUBLE_EQ(context->flight_extent, flight_extent);
    EXPECT_DOUBLE_EQ(context->cell.u0, file.grid.cell(int(b)).u0);
    EXPECT_DOUBLE_EQ(context->margined.v1, file.grid.margined(int(b)).v1);
    EXPECT_DOUBLE_EQ(context->frame.n.dot(file.grid.frame.n), 1);
    // Every block has the one backdrop, the flight's.
    ASSERT_EQ(int64_t(context->background.size()), scene->bands());
    for (int64_t k = 0; k < scene->bands(); ++k)
      EXPECT_FLOAT_EQ(float(context->background[size_t(k)]), backdrop[k].item<float>());
  }

  const fs::path block = blocks / "block_00", run = block / "run";
  ASSERT_EQ(ddhgs("train " + block.string() + " --out " + run.string() + test::kQuickTrain +
                      " --set output.log_every=1",
                  &out),
            0)
      << out;
  EXPECT_NE(out.find("data.block_as_flight"), std::string::npos) << out;
  const json summary = json::parse(io::read_file(run / "train_summary.json"));
  const size_t own = file.blocks[0].train_views.size();
  EXPECT_EQ(summary["block"]["flight_train_views"].get<size_t>(), scene->train.size());
  EXPECT_EQ(summary["block"]["own_train_views"].get<size_t>(), own);
  EXPECT_DOUBLE_EQ(summary["block"]["flight_extent"].get<double>(), flight_extent);
  // The run draws over the flight's backdrop, unchanged by training (a
  // learned background moves from its first step).
  EXPECT_NE(out.find("draws over the flight's backdrop"), std::string::npos) << out;
  const json drawn = json::parse(io::read_file(run / "background.json"))["background"];
  ASSERT_EQ(int64_t(drawn.size()), scene->bands());
  for (int64_t k = 0; k < scene->bands(); ++k)
    EXPECT_EQ(drawn[size_t(k)].get<float>(), backdrop[k].item<float>()) << k;
  // Every step has a record: those that rendered a view have a loss, the
  // others lie elsewhere in the flight; both kinds happen.
  int rendered = 0, elsewhere = 0;
  const std::string log = io::read_file(run / "metrics.jsonl");
  for (size_t at = 0, end; (end = log.find('\n', at)) != std::string::npos; at = end + 1) {
    const json record = json::parse(log.substr(at, end - at));
    if (record.contains("loss")) ++rendered;
    if (record.value("elsewhere", false)) ++elsewhere;
  }
  EXPECT_EQ(rendered + elsewhere, 20);
  EXPECT_GT(rendered, 0);
  EXPECT_GT(elsewhere, 0);
  ASSERT_LT(own, scene->train.size());

  // The block as its own flight: its own views, its own extent, a box round
  // everything. Then the flight's schedule is the scene's own.
  const fs::path whole = root / "whole";
  fs::copy(block, whole, fs::copy_options::recursive);
  fs::remove_all(whole / "run");
  const auto alone = io::load_scene(whole);
  io::BlockContext context = *io::read_block_context(whole);
  context.flight_train_views = int64_t(alone->train.size());
  context.flight_extent = io::scene_extent(*alone, alone->train);
  context.margined = {-1e9, 1e9, -1e9, 1e9};
  context.background.clear();  // learned, as the scene alone learns it
  io::write_block_context(whole / io::kBlockContextFile, context);
  for (const char* as_flight : {"true", "false"})
    ASSERT_EQ(ddhgs("-q train " + whole.string() + " --out " + (root / as_flight).string() +
                        test::kQuickTrain + " --set data.block_as_flight=" + as_flight,
                    &out),
              0)
        << out;
  EXPECT_EQ(io::read_file(root / "true" / "gaussians.ply"),
            io::read_file(root / "false" / "gaussians.ply"));

  // A box that no view sees: nothing to learn, so no training PSNR (the
  // render against itself would read 120 dB), and the loss is zero.
  context.margined = {1e6, 1e6 + 1, 1e6, 1e6 + 1};
  io::write_block_context(whole / io::kBlockContextFile, context);
  ASSERT_EQ(ddhgs("-q train " + whole.string() + " --out " + (root / "nowhere").string() +
                      test::kQuickTrain + " --set output.log_every=1",
                  &out),
            0)
      << out;
  const std::string nowhere = io::read_file(root / "nowhere" / "metrics.jsonl");
  int records = 0;
  for (size_t at = 0, end; (end = nowhere.find('\n', at)) != std::string::npos; at = end + 1) {
    const json record = json::parse(nowhere.substr(at, end - at));
    EXPECT_FALSE(record.contains("train_psnr")) << record.dump();
    EXPECT_EQ(record.value("loss", -1.0), 0.0) << record.dump();
    ++records;
  }
  EXPECT_EQ(records, 20);
}

TEST(BlocksCli, LocalScriptTrainsEveryBlockThenMerges) {
  const fs::path root = test::temp_dir("blocks_cli_local");
  const fs::path blocks = root / "blocks", merged = root / "merged";
  std::string out;
  ASSERT_EQ(
      ddhgs("-q partition " + survey().string() + " --blocks 2 --out " + blocks.string(), &out), 0)
      << out;
  const std::string script = "DDHGS=" + test::ddhgs_binary() + " JOBS=2 THREADS=1 bash " +
                             (test::source_dir() / "scripts" / "slurm" / "local.sh").string() +
                             " " + blocks.string() + " " + merged.string() + " " +
                             test::kQuickTrain;
  ASSERT_EQ(test::run_command(script, &out), 0) << out;
  for (const char* block : {"block_00", "block_01"}) {
    EXPECT_TRUE(fs::exists(blocks / block / "run" / "gaussians.ply")) << block;
    EXPECT_TRUE(fs::exists(root / "merged.logs" / (std::string(block) + ".log"))) << block;
  }
  ASSERT_TRUE(fs::exists(merged / "gaussians.ply"));
  const auto trained = fs::last_write_time(blocks / "block_00" / "run" / "gaussians.ply");
  fs::remove_all(merged);
  ASSERT_EQ(test::run_command(script, &out), 0) << out;
  EXPECT_EQ(fs::last_write_time(blocks / "block_00" / "run" / "gaussians.ply"), trained);
  EXPECT_TRUE(fs::exists(merged / "gaussians.ply"));
}

TEST(BlocksCli, NovelViewsAreHeldOutBetweenTheCapturesAndLeaveTheFlightAsItWas) {
  // The survey above again, with held-out captures between its own: 6
  // captures a line, two lines, so 5 novel views midway between them.
  const fs::path root = test::temp_dir("blocks_cli_novel");
  const fs::path cubes = synth_survey(root / "flight", "--novel-views");
  ASSERT_TRUE(fs::exists(cubes / "transforms.json"));
  std::string out;
  const auto plain = io::load_scene(survey()), novel = io::load_scene(cubes);
  auto names = [](const io::Scene& scene, const std::vector<int>& views) {
    std::vector<std::string> n;
    for (int v : views) n.push_back(scene.views[size_t(v)].name);
    std::sort(n.begin(), n.end());
    return n;
  };
  // Training is the flight's, as without the flag, and so are its files.
  EXPECT_EQ(names(*novel, novel->train), names(*plain, plain->train));
  std::vector<std::string> expected = names(*plain, plain->test);
  for (int i = 0; i < 5; ++i) expected.push_back("NOVEL_000" + std::to_string(i));
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(names(*novel, novel->test), expected);
  for (const auto& entry : fs::directory_iterator(survey() / "hyperspectral"))
    EXPECT_EQ(io::read_file(entry.path()),
              io::read_file(cubes / "hyperspectral" / entry.path().filename()))
        << entry.path();
  EXPECT_EQ(io::read_file(survey() / "points.ply"), io::read_file(cubes / "points.ply"));
  // No raw capture for them: the flight did not take them.
  EXPECT_FALSE(fs::exists(root / "flight" / "captures" / "NOVEL_0000_1.tif"));
  const json synth = json::parse(io::read_file(root / "flight" / "synth.json"));
  EXPECT_EQ(synth["novel_views"]["count"].get<int>(), 5);
  // Partitioned, every novel view is held out in a block that sees it.
  ASSERT_EQ(
      ddhgs("-q partition " + cubes.string() + " --blocks 2 --out " + (root / "blocks").string(),
            &out),
      0)
      << out;
  std::set<std::string> held_out;
  for (const io::BlockRecord& b : io::read_blocks_file(root / "blocks" / "blocks.json").blocks) {
    held_out.insert(b.test_views.begin(), b.test_views.end());
    for (const std::string& v : b.train_views)
      EXPECT_EQ(v.find("NOVEL_"), std::string::npos) << b.name;
  }
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(held_out.count("hyperspectral/NOVEL_000" + std::to_string(i) + ".npy"), 1u) << i;
}

TEST(BlocksCli, BadInputIsOneLineAndLeavesNothing) {
  const fs::path root = test::temp_dir("blocks_cli_bad");
  const fs::path out_dir = root / "blocks";
  std::string out;
  auto refused = [&](const std::string& args, const std::string& says) {
    EXPECT_NE(ddhgs(args, &out), 0) << args;
    const auto errors = test::error_lines(out);
    ASSERT_EQ(errors.size(), 1u) << out;
    EXPECT_NE(errors[0].find(says), std::string::npos) << errors[0];
    EXPECT_FALSE(fs::exists(out_dir)) << args;
    EXPECT_TRUE(test::temporaries(root).empty()) << args;
  };
  const std::string scene = survey().string();
  refused("partition " + root.string() + " --out " + out_dir.string(), "transforms.json");
  refused("partition " + scene + " --blocks 0 --out " + out_dir.string(), "--blocks");
  refused("partition " + scene + " --blocks 2x --out " + out_dir.string(), "--blocks");
  refused("partition " + scene + " --overlap 1.5 --out " + out_dir.string(), "--overlap");
  refused("partition " + scene + " --blocks 400 --out " + out_dir.string(), "no training view");
  // A frame whose file lies outside the scene folder: a block could not hold it.
  fs::create_directories(root / "outside");
  std::string text = io::read_file(survey() / "transforms.json");
  text.replace(text.find("hyperspectral/IMG_0000.npy"), 26, "../cubes/hyperspectral/IMG_0000.npy");
  io::write_file_atomically(root / "outside" / "transforms.json", text);
  refused("partition " + (root / "outside").string() + " --out " + out_dir.string(),
          "frames[0]: ../cubes/hyperspectral/IMG_0000.npy lies outside the scene folder");
  ASSERT_EQ(ddhgs("-q partition " + scene + " --blocks 1x2 --out " + out_dir.string(), &out), 0)
      << out;
  // Merging untrained blocks names the missing run; nothing is written.
  EXPECT_NE(ddhgs("merge " + out_dir.string() + " --out " + (root / "run").string(), &out), 0);
  ASSERT_EQ(test::error_lines(out).size(), 1u) << out;
  EXPECT_NE(out.find((out_dir / "block_00" / "run").string()), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "run"));
  // A seam blend outside [0, 1] is refused before anything is read.
  EXPECT_NE(
      ddhgs("merge " + out_dir.string() + " --out " + (root / "run").string() + " --seam-blend 1.5",
            &out),
      0);
  ASSERT_EQ(test::error_lines(out).size(), 1u) << out;
  EXPECT_NE(out.find("--seam-blend"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "run"));
  // A block's place in its flight that cannot be its own (fewer flight
  // views than the block trains on), or malformed: train refuses it naming
  // block.json, before it writes anything.
  const fs::path context_file = out_dir / "block_00" / io::kBlockContextFile;
  const std::string context = io::read_file(context_file);
  for (const auto& [key, value] :
       {std::pair<std::string, json>{"flight_train_views", 1},
        std::pair<std::string, json>{"flight_extent", -1.0},
        std::pair<std::string, json>{"background", json::array({0.5, 0.5})}}) {
    json bad = json::parse(context);
    bad[key] = value;
    io::write_file_atomically(context_file, bad.dump(2));
    EXPECT_NE(ddhgs("train " + (out_dir / "block_00").string() + " --out " +
                        (root / "run").string() + test::kQuickTrain,
                    &out),
              0);
    const auto errors = test::error_lines(out);
    ASSERT_EQ(errors.size(), 1u) << out;
    EXPECT_NE(errors[0].find(context_file.string()), std::string::npos) << errors[0];
    EXPECT_NE(errors[0].find(key), std::string::npos) << errors[0];
    EXPECT_FALSE(fs::exists(root / "run"));
  }
  io::write_file_atomically(context_file, context);
  // A second partition into the same folder needs --force.
  EXPECT_NE(ddhgs("partition " + scene + " --out " + out_dir.string(), &out), 0);
  EXPECT_NE(out.find("--force"), std::string::npos) << out;
  EXPECT_EQ(ddhgs("-q partition " + scene + " --out " + out_dir.string() + " --force", &out), 0)
      << out;
}

}  // namespace
}  // namespace ddhgs
