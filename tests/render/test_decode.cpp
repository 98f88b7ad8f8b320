// render::decode_latent (the latent colour model's fused decode) against the
// same map in double-precision LibTorch ops: values and every gradient.
#include <gtest/gtest.h>

#include "render/decode.h"
#include "render_fixture.h"

namespace ddhgs::test {
namespace {

using torch::Tensor;

TEST(DecodeLatent, ValuesAndGradientsMatchTheDenseMap) {
  torch::manual_seed(4);
  // More pixels than one reduction chunk, and a band count that is not a
  // multiple of the vector width.
  const int64_t P = 5000, K = 5, M = 37;
  std::vector<Tensor> inputs = {torch::randn({P, K}), torch::rand({P}), torch::randn({M, K}),
                                torch::rand({M}), torch::rand({M})};
  std::vector<Tensor> fast, ref;
  for (const Tensor& t : inputs) {
    fast.push_back(t.clone().requires_grad_(true));
    ref.push_back(t.to(torch::kFloat64).requires_grad_(true));
  }
  const Tensor weights = torch::randn({P, M}, torch::kFloat64);
  const Tensor got = render::decode_latent(fast[0], fast[1], fast[2], fast[3], fast[4]);
  const Tensor a = ref[1].unsqueeze(1);
  const Tensor expected = ref[0].matmul(ref[2].t()) + a * ref[3] + (1 - a) * ref[4];
  EXPECT_LT(scaled_error(got, expected), 1e-6);
  (got.to(torch::kFloat64) * weights).sum().backward();
  (expected * weights).sum().backward();
  const char* names[] = {"latent", "alpha", "basis", "mean", "background"};
  for (size_t i = 0; i < inputs.size(); ++i) {
    ASSERT_TRUE(fast[i].grad().defined()) << names[i];
    EXPECT_LT(scaled_error(fast[i].grad(), ref[i].grad()), 1e-5) << names[i];
  }
}

TEST(DecodeLatent, RefusesMismatchedShapes) {
  EXPECT_THROW(render::decode_latent(torch::zeros({4, 3}), torch::zeros({4}), torch::zeros({6, 2}),
                                     torch::zeros({6}), torch::zeros({6})),
               std::exception);
}

}  // namespace
}  // namespace ddhgs::test
