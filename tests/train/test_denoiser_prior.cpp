// The denoiser prior's training: it learns a correction that carries to
// views it never saw, resumes to the same weights as one uninterrupted run,
// and its file refuses what is not a prior.
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "model/denoiser_fixtures.h"
#include "support/test_support.h"
#include "train/denoiser_prior.h"

namespace ddhgs {
namespace {

namespace fs = std::filesystem;

model::Denoiser tiny_prior(int64_t channels, uint64_t seed) {
  torch::manual_seed(seed);
  return {model::UNet(test::tiny_unet_options(channels)), model::NoiseSchedule(),
          model::Prediction::Residual};
}

// Pairs whose render is the truth lifted by 0.08 in every coefficient: the
// correction to learn is a constant one.
std::vector<train::PriorPair> lifted_pairs(int count, int64_t channels, uint64_t seed) {
  torch::manual_seed(seed);
  std::vector<train::PriorPair> pairs;
  for (int i = 0; i < count; ++i) {
    const auto truth = torch::rand({20, 20, channels}) * 0.4 + 0.3;
    pairs.push_back({truth + 0.08, truth});
  }
  return pairs;
}

train::PriorTrainingOptions small_options() {
  train::PriorTrainingOptions o;
  o.steps = 6;
  o.batch = 2;
  o.crop = 16;
  o.lr = 1e-3;
  o.seed = 9;
  o.sampler.start_strength = 0.1;
  o.sampler.steps = 1;
  return o;
}

TEST(DenoiserPrior, ResumedTrainingEndsWhereOneRunEnds) {
  const auto pairs = lifted_pairs(3, 2, 1);
  train::PriorTraining whole(tiny_prior(2, 5), small_options(), pairs);
  for (int i = 0; i < 6; ++i) whole.train_step();

  const fs::path state = test::temp_dir("prior_resume") / "p.pt.state.pt";
  {
    train::PriorTraining first(tiny_prior(2, 5), small_options(), pairs);
    for (int i = 0; i < 3; ++i) first.train_step();
    first.save_state(state);
  }
  // A fresh start (other initial weights): the state decides.
  train::PriorTraining second(tiny_prior(2, 77), small_options(), pairs);
  ASSERT_TRUE(second.load_state(state));
  EXPECT_EQ(second.step(), 3);
  for (int i = 0; i < 3; ++i) second.train_step();

  const auto a = whole.denoiser().unet->named_parameters();
  const auto b = second.denoiser().unet->named_parameters();
  for (const auto& p : a)
    EXPECT_TRUE(torch::equal(p.value(), b[p.key()])) << p.key() << " differs after resuming";
  EXPECT_FALSE(second.load_state(state.parent_path() / "none.pt"));
}

// A constant lift learned on some pairs is taken off views of a scene the
// training never saw, through that scene's own subspace.
// (Both objectives.)
TEST(DenoiserPrior, LearnsACorrectionThatCarriesToUnseenViews) {
  for (const std::string objective : {"restoration", "diffusion"}) {
    SCOPED_TRACE(objective);
    train::PriorTrainingOptions o = small_options();
    o.objective = train::parse_prior_objective(objective, "test");
    o.steps = 150;
    o.batch = 4;
    o.decay_fraction = 0.2;
    train::PriorTraining training(tiny_prior(2, 3), o, lifted_pairs(6, 2, 2));

    // An unseen 5-band scene: spectra on a 2-D plane; the render is the truth
    // moved by +0.08 x scale along each of the plane's axes (a lift of 0.08 in
    // both coefficients).
    torch::manual_seed(4);
    const auto axes = torch::tensor({{1., 1., 1., 1., 1.}, {-1., -1., 0., 1., 1.}});
    const auto unit = axes / axes.norm(2, 1, true);  // [2, 5] orthonormal rows
    const auto mean = torch::full({5}, 0.4);
    auto coeffs = (torch::rand({24, 24, 2}) - 0.5) * 0.3;
    const auto truth = mean + torch::matmul(coeffs, unit);
    const model::SpectralSubspace s =
        model::fit_spectral_subspace(truth.reshape({-1, 5}).to(torch::kFloat64), 2);
    const auto lift = torch::matmul(torch::full({2}, 0.08f * float(s.scale)), s.basis.t());
    const std::vector<train::PriorCheckView> unseen = {{truth + lift, truth, s}};

    const auto [raw_before, denoised_before] = training.check(unseen);
    double loss = 0, identity = 0;
    for (int i = 0; i < o.steps; ++i) {
      const auto [l, id] = training.train_step();
      if (i >= o.steps - 30) loss += l, identity += id;
    }
    const auto [raw, denoised] = training.check(unseen);
    std::printf("loss %.5f vs identity %.5f; unseen view %.2f dB raw, %.2f before, %.2f after\n",
                loss / 30, identity / 30, raw, denoised_before, denoised);
    EXPECT_NEAR(raw, raw_before, 1e-9);
    EXPECT_NEAR(denoised_before, raw, 0.05);  // untrained: the render back
    EXPECT_LT(loss, 0.5 * identity);
    EXPECT_GT(denoised, raw + 3.0);
  }
  EXPECT_THROW(train::parse_prior_objective("regression", "--objective"), core::Error);
}

TEST(DenoiserPrior, TheFileKeepsTheNetworkAndRefusesOtherFiles) {
  const fs::path dir = test::temp_dir("prior_file");
  model::Denoiser prior{test::live_unet(test::tiny_unet_options(3), 12), model::NoiseSchedule(200),
                        model::Prediction::Residual};
  train::write_prior(dir / "p.pt", prior, {{"command", "ddhgs prior c --out p.pt"}, {"steps", 7}});
  const train::PriorFile read = train::read_prior(dir / "p.pt");
  EXPECT_EQ(read.info["channels"], 3);
  EXPECT_EQ(read.info["steps"], 7);
  EXPECT_EQ(read.info["command"], "ddhgs prior c --out p.pt");
  EXPECT_EQ(read.denoiser.schedule.steps, 200);
  for (const auto& p : prior.unet->named_parameters())
    EXPECT_TRUE(torch::equal(p.value(), read.denoiser.unet->named_parameters()[p.key()]));

  auto refused = [&](const fs::path& file, const std::string& problem) {
    try {
      train::read_prior(file);
      ADD_FAILURE() << file << " was read as a prior";
    } catch (const core::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(file.filename().string()), std::string::npos) << what;
      EXPECT_NE(what.find(problem), std::string::npos) << what;
    }
  };
  refused(dir / "missing.pt", "no such");
  train::write_denoiser(dir / "denoiser.pt", prior);  // a run's denoiser, not a prior
  refused(dir / "denoiser.pt", "not a ddhgs denoiser prior");
  std::ofstream(dir / "junk.pt") << "not an archive";
  refused(dir / "junk.pt", "unreadable");
}

}  // namespace
}  // namespace ddhgs
