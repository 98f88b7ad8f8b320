// render::decode_latent (the latent colour model's fused decode) against the
// same map in double-precision LibTorch ops: values and every gradient.
#include <gtest/gtest.h>

#include <string>

#include "render/decode.h"
#include "render_fixture.h"

namespace ddhgs::test {
namespace {

using torch::Tensor;

TEST(DecodeLatent, ValuesAndGradientsMatchTheDenseMap) {
  // More pixels than one reduction chunk; band counts that are not, and one
  // that is, a multiple of the vector width (8 or 16); latent counts of the
  // kernels compiled for 1-8 channels and of the one for any count.
  struct Case {
    int64_t P, K, M;
  };
  for (const Case c :
       {Case{5000, 5, 37}, Case{2100, 1, 16}, Case{300, 8, 3}, Case{2500, 12, 141}}) {
    SCOPED_TRACE("K " + std::to_string(c.K) + ", M " + std::to_string(c.M));
    torch::manual_seed(4);
    std::vector<Tensor> inputs = {torch::randn({c.P, c.K}), torch::rand({c.P}),
                                  torch::randn({c.M, c.K}), torch::rand({c.M}), torch::rand({c.M})};
    std::vector<Tensor> fast, ref;
    for (const Tensor& t : inputs) {
      fast.push_back(t.clone().requires_grad_(true));
      ref.push_back(t.to(torch::kFloat64).requires_grad_(true));
    }
    const Tensor weights = torch::randn({c.P, c.M}, torch::kFloat64);
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
}

TEST(DecodeLatent, RefusesMismatchedShapes) {
  EXPECT_THROW(render::decode_latent(torch::zeros({4, 3}), torch::zeros({4}), torch::zeros({6, 2}),
                                     torch::zeros({6}), torch::zeros({6})),
               std::exception);
}

}  // namespace
}  // namespace ddhgs::test
