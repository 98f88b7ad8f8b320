#include <gtest/gtest.h>
#include <torch/nn/modules/linear.h>

#include <fstream>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "support/test_support.h"
#include "train/checkpoint.h"
#include "train/losses.h"
#include "train/run_folder.h"

using namespace ddhgs;
namespace fs = std::filesystem;

namespace {

train::TrainState make_state() {
  train::TrainState s;
  auto& g = s.gaussians;
  g.means = torch::randn({4, 3});
  g.log_scales = torch::randn({4, 3});
  g.quats = torch::randn({4, 4});
  g.logit_opacities = torch::randn({4, 1});
  g.sh_dc = torch::randn({4, 5});
  g.sh_rest = torch::randn({4, 5, 15});
  g.active_sh_degree = 2;
  auto tensors = g.tensors();
  for (size_t i = 0; i < tensors.size(); ++i) {
    tensors[i]->requires_grad_(true);
    s.adam.add(model::Gaussians::tensor_names()[i], *tensors[i], 0.01 * double(i + 1));
    tensors[i]->mutable_grad() = torch::randn(tensors[i]->sizes());
  }
  s.adam.step();
  s.stats.reset(4);
  s.stats.grad_sum = torch::rand({4});
  s.iteration = 123;
  s.counters = {5, 2, 12.5, 10.25};
  return s;
}

}  // namespace

TEST(Checkpoint, RoundTripRestoresEverything) {
  torch::manual_seed(21);
  auto dir = test::temp_dir("ckpt_roundtrip");
  auto s = make_state();
  auto module = std::make_shared<torch::nn::LinearImpl>(3, 2);
  s.modules.push_back({"encoder", module, 1e-3});
  train::add_module_groups(s.adam, s.modules.back());
  module->weight.mutable_grad() = torch::rand({2, 3});
  s.adam.step();  // the module's moments and step count are saved too
  train::save_checkpoint(dir / "c.pt", s);

  train::TrainState r;
  auto other = std::make_shared<torch::nn::LinearImpl>(3, 2);
  r.modules.push_back({"encoder", other, 0.0});
  train::load_checkpoint(dir / "c.pt", r, {});
  EXPECT_EQ(r.iteration, 123);
  EXPECT_EQ(r.gaussians.active_sh_degree, 2);
  EXPECT_EQ(r.counters.densify_added, 5);
  EXPECT_EQ(r.counters.densify_removed, 2);
  EXPECT_EQ(r.counters.seconds, 12.5);
  EXPECT_EQ(r.counters.gaussian_seconds, 10.25);
  auto a = s.gaussians.values(), b = r.gaussians.values();
  for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(torch::equal(a[i], b[i])) << i;
  for (const auto& g : s.adam.groups()) {
    const auto& h = r.adam.group(g.name);
    EXPECT_TRUE(torch::equal(g.exp_avg, h.exp_avg));
    EXPECT_TRUE(torch::equal(g.exp_avg_sq, h.exp_avg_sq));
    EXPECT_EQ(g.step, h.step);
    EXPECT_DOUBLE_EQ(g.lr, h.lr);
  }
  for (size_t i = 0; i < r.gaussians.tensors().size(); ++i)
    EXPECT_TRUE(r.adam.groups()[i].param.is_same(*r.gaussians.tensors()[i])) << i;
  // The optimizer steps the loaded module's own tensors, at the saved rate.
  EXPECT_TRUE(r.adam.group("encoder/weight").param.is_same(other->weight));
  EXPECT_EQ(r.adam.group("encoder/weight").step, 1);
  EXPECT_DOUBLE_EQ(r.adam.group("encoder/bias").lr, 1e-3);
  EXPECT_TRUE(torch::equal(s.stats.grad_sum, r.stats.grad_sum));
  EXPECT_TRUE(torch::equal(module->weight, other->weight));
  // No temporary file is left behind.
  int files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
}

TEST(Checkpoint, SavedModelReadsTheShapesAndTheRecord) {
  auto dir = test::temp_dir("ckpt_saved_model");
  // Per band: 5 bands, degree 3, one module, no record (an older checkpoint).
  auto s = make_state();
  s.modules.push_back({"background", std::make_shared<torch::nn::LinearImpl>(3, 2), 1e-3});
  train::add_module_groups(s.adam, s.modules.back());
  train::save_checkpoint(dir / "per_band.pt", s);
  train::CheckpointFile file = train::open_checkpoint(dir / "per_band.pt");
  train::SavedModel saved = train::saved_model(file);
  EXPECT_EQ(saved.bands, 5);
  EXPECT_EQ(saved.rank, 0);
  EXPECT_EQ(saved.sh_degree, 3);
  EXPECT_EQ(saved.modules, (std::vector<std::string>{"background"}));
  EXPECT_TRUE(saved.record.is_null());
  // The opened file loads as the path does.
  train::TrainState r;
  r.modules.push_back({"background", std::make_shared<torch::nn::LinearImpl>(3, 2), 0.0});
  train::load_checkpoint(file, r, {});
  EXPECT_EQ(r.iteration, 123);

  // Latent: 2 channels of degree 1 over a basis of 7 bands, with a record.
  auto l = make_state();
  l.gaussians.sh_dc = torch::randn({4, 2});
  l.gaussians.sh_rest = torch::randn({4, 2, 3});
  auto colour = std::make_shared<torch::nn::Module>();
  colour->register_parameter("basis", torch::randn({7, 2}));
  colour->register_parameter("mean", torch::randn({7}));
  l.modules = {{"colour_model", colour, 1e-3}};
  l.model_record = {{"settings", {{"model.spectral_rank", 2}}}};
  train::save_checkpoint(dir / "latent.pt", l);
  train::CheckpointFile latent = train::open_checkpoint(dir / "latent.pt");
  saved = train::saved_model(latent);
  EXPECT_EQ(saved.bands, 7);
  EXPECT_EQ(saved.rank, 2);
  EXPECT_EQ(saved.sh_degree, 1);
  EXPECT_EQ(saved.modules, (std::vector<std::string>{"colour_model"}));
  EXPECT_EQ(saved.record, l.model_record);
}

TEST(Checkpoint, RejectsMissingTruncatedAndForeignFiles) {
  auto dir = test::temp_dir("ckpt_bad");
  train::TrainState r;
  EXPECT_THROW(train::load_checkpoint(dir / "none.pt", r, {}), core::Error);
  std::ofstream(dir / "junk.pt") << "not a checkpoint";
  EXPECT_THROW(train::load_checkpoint(dir / "junk.pt", r, {}), core::Error);

  auto s = make_state();
  train::save_checkpoint(dir / "good.pt", s);
  std::ifstream in(dir / "good.pt", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir / "cut.pt", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  EXPECT_THROW(train::load_checkpoint(dir / "cut.pt", r, {}), core::Error);

  torch::serialize::OutputArchive future;
  future.write("meta", c10::IValue(std::string(R"({"format_version": 99, "iteration": 1})")));
  future.save_to((dir / "future.pt").string());
  try {
    train::load_checkpoint(dir / "future.pt", r, {});
    FAIL() << "a checkpoint of another format_version was accepted";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("format_version 99"), std::string::npos);
  }
}

TEST(Checkpoint, RunFolderIsReplacedOnlyWithForceAndTheEarlierRunKeptUntilTheEnd) {
  auto dir = test::temp_dir("run_folder");
  train::RunPaths run{dir / "run"};
  nlohmann::json config = {{"format_version", 1}};
  {
    auto writer = train::RunWriter::create(run, config, false, {});
    std::ofstream(run.checkpoint()) << "checkpoint";
    std::ofstream(run.gaussians()) << "old";
    writer->finished();
  }
  EXPECT_THROW(train::RunWriter::create(run, config, false, {}), core::Error);
  EXPECT_EQ(io::read_file(run.gaussians()), "old");
  const fs::path previous = dir / "run.previous";
  {
    // Replaced, then the new run fails before its first checkpoint: the
    // earlier run comes back.
    auto writer = train::RunWriter::create(run, config, true, {});
    EXPECT_FALSE(fs::exists(run.gaussians()));
    EXPECT_EQ(io::read_file(previous / "gaussians.ply"), "old");
    writer->failed();
  }
  EXPECT_EQ(io::read_file(run.gaussians()), "old");
  EXPECT_FALSE(fs::exists(previous));
  {
    auto writer = train::RunWriter::create(run, config, true, {});
    EXPECT_TRUE(fs::exists(previous));
    writer->finished();
  }
  EXPECT_FALSE(fs::exists(previous));
  EXPECT_FALSE(fs::exists(run.gaussians()));
}

TEST(Checkpoint, InterruptedReplacementIsNeverReplacedAgainAndFinishesOnResume) {
  auto dir = test::temp_dir("run_folder_pending");
  train::RunPaths run{dir / "run"};
  nlohmann::json config = {{"format_version", 1}};
  train::RunWriter::create(run, config, false, {})->finished();
  std::ofstream(run.checkpoint()) << "good";
  {
    // Interrupted (Ctrl-C) after a checkpoint: neither finished nor failed.
    auto writer = train::RunWriter::create(run, config, true, {});
    std::ofstream(run.checkpoint()) << "new";
  }
  const fs::path previous = dir / "run.previous";
  EXPECT_EQ(io::read_file(previous / "checkpoint.pt"), "good");
  // A second --force must not delete the only good copy.
  try {
    train::RunWriter::create(run, config, true, {});
    FAIL() << "replaced a run whose earlier replacement never finished";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("run.previous"), std::string::npos) << e.what();
  }
  EXPECT_EQ(io::read_file(previous / "checkpoint.pt"), "good");
  EXPECT_EQ(io::read_file(run.checkpoint()), "new");
  // --resume finishes the replacement.
  train::RunWriter::reopen(run)->finished();
  EXPECT_FALSE(fs::exists(previous));
  EXPECT_EQ(io::read_file(run.checkpoint()), "new");
}

TEST(Checkpoint, RunThatNeverCheckpointedIsReplacedWithoutForce) {
  auto dir = test::temp_dir("run_folder_unstarted");
  train::RunPaths run{dir / "run"};
  nlohmann::json config = {{"format_version", 1}};
  train::RunWriter::create(run, config, false, {});  // killed before its first checkpoint
  EXPECT_TRUE(train::is_unstarted_run(run));
  auto writer = train::RunWriter::create(run, config, false, {});
  writer->finished();
  EXPECT_FALSE(fs::exists(dir / "run.previous"));
}

TEST(Checkpoint, SecondWriterOfARunIsRefused) {
  auto dir = test::temp_dir("run_folder_lock");
  train::RunPaths run{dir / "run"};
  auto writer = train::RunWriter::create(run, {{"format_version", 1}}, false, {});
  std::ofstream(run.checkpoint()) << "checkpoint";
  for (bool replace : {false, true}) {
    try {
      train::RunWriter::create(run, {{"format_version", 1}}, replace, {});
      FAIL() << "a second writer was let in";
    } catch (const core::Error& e) {
      EXPECT_NE(std::string(e.what()).find("in use by ddhgs train (pid"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(train::RunWriter::reopen(run), core::Error);
  EXPECT_EQ(io::read_file(run.checkpoint()), "checkpoint");
}

TEST(Checkpoint, UnwritableRunFolderIsAClearError) {
  auto dir = test::temp_dir("run_folder_unwritable");
  std::ofstream(dir / "a-file") << "not a folder";
  train::RunPaths run{dir / "a-file" / "run"};
  try {
    train::RunWriter::create(run, {{"format_version", 1}}, false, {});
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot create the folder"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(io::read_file(dir / "a-file"), "not a folder");
}

TEST(Checkpoint, MetricsLogKeepsOnlyLinesUpToTheResumePoint) {
  auto dir = test::temp_dir("metrics_log");
  {
    train::MetricsLog log(dir / "m.jsonl", -1);
    for (int i = 1; i <= 5; ++i) log.write({{"iter", i * 10}});
  }
  {
    train::MetricsLog log(dir / "m.jsonl", 30);
    log.write({{"iter", 40}});
  }
  std::ifstream in(dir / "m.jsonl");
  std::vector<int> iters;
  for (std::string line; std::getline(in, line);)
    iters.push_back(nlohmann::json::parse(line)["iter"].get<int>());
  EXPECT_EQ(iters, (std::vector<int>{10, 20, 30, 40}));
}

TEST(Losses, WeightedSumAndPsnr) {
  auto render = torch::full({12, 12, 2}, 0.5f).requires_grad_(true);
  auto target = torch::full({12, 12, 2}, 0.4f);
  auto values = train::evaluate_losses(train::baseline_losses(0.8, 0.2), {render, target, 0, 1});
  ASSERT_EQ(values.terms.size(), 2u);
  EXPECT_NEAR(values.terms[0].second, 0.1, 1e-6);
  // Constant images: SSIM reduces to the luminance term.
  const double ssim = (2 * 0.5 * 0.4 + 1e-4) / (0.25 + 0.16 + 1e-4);
  EXPECT_NEAR(values.terms[1].second, 1 - ssim, 1e-5);
  EXPECT_NEAR(values.total.item<double>(), 0.8 * 0.1 + 0.2 * (1 - ssim), 1e-5);
  EXPECT_NEAR(train::psnr(render, target), 20.0, 1e-4);
  // A zero weight skips the term entirely.
  auto l1_only = train::evaluate_losses(train::baseline_losses(1.0, 0.0), {render, target, 0, 1});
  EXPECT_EQ(l1_only.terms.size(), 1u);
}
