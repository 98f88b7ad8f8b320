// eval_sh: fast path vs the dense reference (values and gradients), central
// finite differences, clamping, ignored coefficients, bad shapes.
#include <gtest/gtest.h>

#include <mutex>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/threads.h"
#include "render/rasterize.h"
#include "render/sh.h"
#include "render/sh_reference.h"

namespace ddhgs::render {
namespace {

struct ShCase {
  torch::Tensor dc, rest, means, center, offsets;  // [G, N], [G, N, 15], [G, 3], [3], [N, 16]
  int degree = 3;

  std::vector<torch::Tensor> leaves() const { return {dc, rest, means, center, offsets}; }
  ShCase converted(torch::ScalarType type, bool grad) const {
    ShCase c = *this;
    for (auto* t : {&c.dc, &c.rest, &c.means, &c.center, &c.offsets})
      *t = t->detach().to(type).clone().requires_grad_(grad);
    return c;
  }
};

// Random inputs in double; coefficients of a size that makes a few colours clamp.
ShCase random_case(int64_t G, int64_t N, int degree, uint64_t seed) {
  torch::manual_seed(seed);
  auto opts = torch::TensorOptions().dtype(torch::kFloat64);
  ShCase c;
  c.dc = torch::randn({G, N}, opts) * 1.2;
  c.dc[0].fill_(-5.0);  // clamped in every band
  c.rest = torch::randn({G, N, 15}, opts) * 0.4;
  c.means = torch::randn({G, 3}, opts) * 2.0;
  c.center = torch::tensor({0.3, -0.2, -4.0}, opts);
  c.offsets = torch::randn({N, 16}, opts) * 0.1;
  c.degree = degree;
  return c;
}

torch::Tensor run_fast(const ShCase& c) {
  return eval_sh(c.dc, c.rest, c.means, c.center, c.degree, c.offsets);
}
torch::Tensor run_reference(const ShCase& c) {
  return eval_sh_reference(c.dc, c.rest, c.means, c.center, c.degree, c.offsets);
}

std::vector<torch::Tensor> grads_of(const torch::Tensor& out, const torch::Tensor& weights,
                                    const ShCase& c) {
  auto leaves = c.leaves();
  auto grads = torch::autograd::grad({(out * weights.to(out.scalar_type())).sum()}, leaves, {},
                                     false, false, /*allow_unused=*/true);
  // The reference leaves inputs that a degree does not use out of its graph.
  for (size_t i = 0; i < grads.size(); ++i)
    if (!grads[i].defined()) grads[i] = torch::zeros_like(leaves[i]);
  return grads;
}

void expect_close(const torch::Tensor& a, const torch::Tensor& b, double tol,
                  const std::string& what) {
  ASSERT_EQ(a.sizes(), b.sizes()) << what;
  auto a64 = a.to(torch::kFloat64), b64 = b.to(torch::kFloat64);
  double scale = std::max(1.0, b64.abs().max().item<double>());
  double err = (a64 - b64).abs().max().item<double>();
  EXPECT_LE(err, tol * scale) << what << ": max abs error " << err;
}

const char* kLeafNames[] = {"sh_dc", "sh_rest", "means", "camera_center", "band_offsets"};

class ShVsReference : public ::testing::TestWithParam<std::tuple<int, int64_t>> {};

TEST_P(ShVsReference, ValuesAndGradientsMatch) {
  auto [degree, N] = GetParam();
  for (uint64_t seed : {1, 2}) {
    auto base = random_case(37, N, degree, seed);
    auto weights = torch::randn({37, N}, torch::kFloat64);
    auto ref_case = base.converted(torch::kFloat64, true);
    auto ref = run_reference(ref_case);
    ASSERT_TRUE((ref == 0).any().item<bool>()) << "inputs should exercise clamping";
    auto ref_grads = grads_of(ref, weights, ref_case);

    for (auto type : {torch::kFloat64, torch::kFloat32}) {
      const double tol = type == torch::kFloat64 ? 1e-12 : 2e-5;
      auto fast_case = base.converted(type, true);
      auto fast = run_fast(fast_case);
      EXPECT_EQ(fast.scalar_type(), type);
      expect_close(fast, ref, tol, "colour");
      auto fast_grads = grads_of(fast, weights, fast_case);
      for (size_t i = 0; i < fast_grads.size(); ++i)
        expect_close(fast_grads[i], ref_grads[i], tol, std::string("d ") + kLeafNames[i]);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(DegreesAndBands, ShVsReference,
                         ::testing::Combine(::testing::Values(0, 1, 2, 3),
                                            ::testing::Values<int64_t>(1, 3, 17, 128)));

// Central differences of L = sum(w * colour) in double, every input element.
TEST(EvalSh, GradientsMatchFiniteDifferences) {
  for (int degree = 0; degree <= 3; ++degree) {
    auto c = random_case(4, 3, degree, 10 + degree).converted(torch::kFloat64, true);
    auto weights = torch::randn({4, 3}, torch::kFloat64);
    auto analytic = grads_of(run_fast(c), weights, c);
    const double h = 1e-6;
    auto leaves = c.leaves();
    for (size_t i = 0; i < leaves.size(); ++i) {
      auto flat = leaves[i].detach().view({-1});
      auto expected = torch::zeros_like(flat);
      for (int64_t e = 0; e < flat.numel(); ++e) {
        torch::NoGradGuard no_grad;
        double saved = flat[e].item<double>();
        flat[e] = saved + h;
        double plus = (run_fast(c) * weights).sum().item<double>();
        flat[e] = saved - h;
        double minus = (run_fast(c) * weights).sum().item<double>();
        flat[e] = saved;
        expected[e] = (plus - minus) / (2 * h);
      }
      expect_close(analytic[i].reshape({-1}), expected, 1e-6,
                   std::string("degree ") + std::to_string(degree) + " d " + kLeafNames[i]);
    }
  }
}

TEST(EvalSh, ClampsAtZeroWithZeroGradient) {
  auto c = random_case(6, 4, 2, 3).converted(torch::kFloat64, false);
  {
    torch::NoGradGuard no_grad;
    c.dc.select(1, 1).fill_(-20.0);  // far below the clamp
    c.dc.select(1, 2).fill_(20.0);   // far above it
  }
  for (auto* t : {&c.dc, &c.rest, &c.means, &c.offsets}) t->requires_grad_(true);
  auto out = run_fast(c);
  EXPECT_TRUE(torch::all(out.select(1, 1) == 0).item<bool>());
  EXPECT_TRUE(torch::all(out.select(1, 2) > 1).item<bool>());
  out.sum().backward();
  EXPECT_TRUE(torch::all(c.dc.grad().select(1, 1) == 0).item<bool>());
  EXPECT_TRUE(torch::all(c.rest.grad().select(1, 1) == 0).item<bool>());
  EXPECT_TRUE(torch::allclose(c.dc.grad().select(1, 2),
                              torch::full({6}, sh_constants::C0, torch::kFloat64)));
  EXPECT_TRUE(torch::all(c.offsets.grad()[1] == 0).item<bool>());
}

TEST(EvalSh, CoefficientsAboveDegreeAreIgnored) {
  for (int degree = 0; degree < 3; ++degree) {
    auto c = random_case(9, 5, degree, 4).converted(torch::kFloat64, true);
    const int64_t K = sh_coeff_count(degree);
    auto out = run_fast(c);
    auto sliced = eval_sh(c.dc, c.rest.slice(2, 0, K - 1), c.means, c.center, degree,
                          c.offsets.slice(1, 0, K));
    EXPECT_TRUE(torch::equal(out, sliced));
    auto changed = c.converted(torch::kFloat64, false);
    {
      torch::NoGradGuard no_grad;
      changed.rest.slice(2, K - 1).add_(3.0);
      changed.offsets.slice(1, K).add_(3.0);
    }
    EXPECT_TRUE(torch::equal(out.detach(), run_fast(changed)));
    out.sum().backward();
    EXPECT_TRUE(torch::all(c.rest.grad().slice(2, K - 1) == 0).item<bool>());
    EXPECT_TRUE(torch::all(c.offsets.grad().slice(1, K) == 0).item<bool>());
  }
}

TEST(EvalSh, ReusedGradientBuffersAreFullyWritten) {
  // Gradients above 1 MB come from core::pooled_empty, whose blocks hold the
  // previous user's values: a degree-3 backward leaves non-zero rest
  // gradients in the block that the degree-1 backward then receives.
  core::pool_release_idle();
  for (int degree : {3, 1, 0, 2}) {
    auto base = random_case(4000, 17, degree, uint64_t(10 + degree));
    auto weights = torch::randn({4000, 17}, torch::kFloat64);
    auto fast_case = base.converted(torch::kFloat32, true);
    auto ref_case = base.converted(torch::kFloat64, true);
    auto fast_grads = grads_of(run_fast(fast_case), weights, fast_case);
    auto ref_grads = grads_of(run_reference(ref_case), weights, ref_case);
    for (size_t i = 0; i < fast_grads.size(); ++i)
      expect_close(fast_grads[i], ref_grads[i], 2e-5,
                   std::string("d ") + kLeafNames[i] + " at degree " + std::to_string(degree));
    const int64_t K = sh_coeff_count(degree);
    EXPECT_TRUE(torch::all(fast_grads[1].slice(2, K - 1) == 0).item<bool>()) << degree;
  }
}

TEST(EvalSh, RestSinkReceivesTheSameGradientInBlocks) {
  for (int degree : {0, 1, 2, 3}) {
    // 2500 Gaussians: several 1024-Gaussian chunks and 32-Gaussian blocks.
    auto base = random_case(2500, 17, degree, uint64_t(20 + degree));
    auto weights = torch::randn({2500, 17}, torch::kFloat64);
    auto plain = base.converted(torch::kFloat32, true);
    auto grads = grads_of(run_fast(plain), weights, plain);

    auto sunk = base.converted(torch::kFloat32, true);
    auto received = torch::zeros_like(sunk.rest);
    auto times = torch::zeros({2500}, torch::kInt32);
    std::mutex mutex;
    const ShRestSink sink = [&](int64_t first, int64_t count, const float* grad) {
      std::lock_guard<std::mutex> lock(mutex);
      received.slice(0, first, first + count)
          .copy_(torch::from_blob(const_cast<float*>(grad), {count, 17, 15}));
      times.slice(0, first, first + count) += 1;
    };
    auto out = eval_sh(sunk.dc, sunk.rest, sunk.means, sunk.center, degree, sunk.offsets, sink);
    auto leaves = sunk.leaves();
    auto sunk_grads = torch::autograd::grad({(out * weights.to(torch::kFloat32)).sum()}, leaves, {},
                                            false, false, /*allow_unused=*/true);
    EXPECT_TRUE(torch::all(times == 1).item<bool>()) << "every Gaussian exactly once";
    EXPECT_FALSE(sunk_grads[1].defined()) << "no rest gradient tensor";
    EXPECT_TRUE(torch::equal(received, grads[1])) << degree;
    for (size_t i : {0u, 2u, 3u, 4u})
      EXPECT_TRUE(torch::equal(sunk_grads[i], grads[i])) << kLeafNames[i] << " " << degree;
  }
}

TEST(EvalSh, KnownValueAlongOpticalAxis) {
  // Direction (0, 0, 1): Y = (C0, 0, C1, 0, ...), so colour = 0.5 + C0 dc + C1 rest[1].
  auto opts = torch::TensorOptions().dtype(torch::kFloat64);
  auto dc = torch::tensor({{0.7, -0.3}}, opts);
  auto rest = torch::zeros({1, 2, 3}, opts);
  rest[0][0][1] = 0.2;
  rest[0][1][1] = -0.1;
  auto out = eval_sh(dc, rest, torch::tensor({{1.0, 2.0, 8.0}}, opts),
                     torch::tensor({1.0, 2.0, 3.0}, opts), 1);
  using namespace sh_constants;
  EXPECT_NEAR(out[0][0].item<double>(), 0.5 + C0 * 0.7 + C1 * 0.2, 1e-15);
  EXPECT_NEAR(out[0][1].item<double>(), 0.5 - C0 * 0.3 - C1 * 0.1, 1e-15);
}

TEST(EvalSh, OptionalInputsAndNoGradKeepsNothing) {
  auto c = random_case(5, 2, 0, 5).converted(torch::kFloat32, true);
  auto out = eval_sh(c.dc, {}, c.means, c.center, 0);
  auto expected = (c.dc.detach() * sh_constants::C0 + 0.5).clamp_min(0);
  EXPECT_TRUE(torch::allclose(out, expected));
  EXPECT_TRUE(out.requires_grad());
  torch::NoGradGuard no_grad;
  auto quiet = eval_sh(c.dc, c.rest, c.means, c.center, 3, c.offsets);
  EXPECT_FALSE(quiet.requires_grad());
  EXPECT_FALSE(quiet.grad_fn());
}

TEST(EvalSh, GaussianAtCameraCentreIsFinite) {
  auto c = random_case(3, 2, 3, 6).converted(torch::kFloat64, true);
  auto center = c.means.detach()[1].clone();
  auto out = eval_sh(c.dc, c.rest, c.means, center, 3, c.offsets);
  out.sum().backward();
  EXPECT_TRUE(torch::isfinite(out).all().item<bool>());
  EXPECT_TRUE(torch::isfinite(c.means.grad()).all().item<bool>());
  EXPECT_TRUE(torch::allclose(
      out.detach()[1],
      (c.dc.detach()[1] + c.offsets.detach().select(1, 0)) * sh_constants::C0 + 0.5));
}

TEST(EvalSh, OffsetGradientIsIdenticalAcrossThreadCounts) {
  auto c = random_case(5000, 7, 3, 7).converted(torch::kFloat32, true);
  auto weights = torch::randn({5000, 7});
  // The SH kernels run on ddhgs's own pool (core/parallel.h), sized here.
  const int threads = core::thread_count();
  std::vector<torch::Tensor> results;
  for (int n : {1, 2, 3}) {
    core::configure_threads(n);
    results.push_back(grads_of(run_fast(c), weights, c)[4]);
  }
  core::configure_threads(threads);
  EXPECT_TRUE(torch::equal(results[0], results[1]));
  EXPECT_TRUE(torch::equal(results[0], results[2]));
}

TEST(EvalSh, BadShapesThrow) {
  auto c = random_case(4, 3, 3, 8).converted(torch::kFloat32, false);
  auto f64 = c.converted(torch::kFloat64, false);
  auto call = [](const torch::Tensor& dc, const torch::Tensor& rest, const torch::Tensor& means,
                 const torch::Tensor& center, int degree, const torch::Tensor& offsets) {
    return [=] { eval_sh(dc, rest, means, center, degree, offsets); };
  };
  std::vector<std::function<void()>> bad = {
      call(c.dc, c.rest, c.means, c.center, 4, c.offsets),                 // degree > 3
      call(c.dc, c.rest, c.means, c.center, -1, c.offsets),                // degree < 0
      call(c.dc.unsqueeze(0), c.rest, c.means, c.center, 3, c.offsets),    // dc 3-D
      call(c.dc.slice(1, 0, 0), c.rest, c.means, c.center, 0, {}),         // N = 0
      call(c.dc, {}, c.means, c.center, 1, c.offsets),                     // rest missing
      call(c.dc, c.rest.slice(2, 0, 8), c.means, c.center, 3, c.offsets),  // too few rest
      call(c.dc, c.rest.slice(1, 0, 2), c.means, c.center, 1, c.offsets),  // rest N mismatch
      call(c.dc, c.rest, c.means.slice(0, 0, 3), c.center, 3, c.offsets),  // G mismatch
      call(c.dc, c.rest, c.means.slice(1, 0, 2), c.center, 3, c.offsets),  // means [G, 2]
      call(c.dc, c.rest, c.means, c.center.slice(0, 0, 2), 3, c.offsets),  // centre of 2
      call(c.dc, c.rest, c.means, c.center, 3, c.offsets.slice(1, 0, 9)),  // offsets K < 16
      call(c.dc, c.rest, c.means, c.center, 3, c.offsets.slice(0, 0, 2)),  // offsets N
      call(c.dc, c.rest, f64.means, c.center, 3, c.offsets),               // mixed dtypes
      call(c.dc.to(torch::kInt32), {}, c.means, c.center, 0, {}),          // integer
      call(c.dc, c.rest.slice(0, 0, 2), c.means, c.center, 0, c.offsets),  // bad unused rest
  };
  for (size_t i = 0; i < bad.size(); ++i) EXPECT_THROW(bad[i](), core::Error) << "case " << i;
}

}  // namespace
}  // namespace ddhgs::render
