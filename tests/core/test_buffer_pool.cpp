// core::pooled_empty: blocks come back to the pool and are handed out again,
// tensors keep a storage use count of 1 (so autograd steals them into
// .grad), stale blocks are freed.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include "core/buffer_pool.h"

using namespace ddhgs;

namespace {

constexpr int64_t kLarge = 1 << 20;  // floats: 4 MB, above kPoolMinBytes

TEST(BufferPool, ReleasedBlockIsHandedOutAgain) {
  core::pool_release_idle();
  void* first = nullptr;
  {
    at::Tensor t = core::pooled_empty({kLarge});
    first = t.data_ptr();
    EXPECT_EQ(t.numel(), kLarge);
    EXPECT_TRUE(t.is_contiguous());
    EXPECT_EQ(t.storage().use_count(), 1);
  }
  EXPECT_GE(core::pool_idle_bytes(), size_t(kLarge) * 4);
  // A slightly smaller request of another shape reuses the block.
  at::Tensor again = core::pooled_empty({kLarge / 8, 7});
  EXPECT_EQ(again.data_ptr(), first);
  EXPECT_EQ(core::pool_idle_bytes(), 0u);
  // A block in use is never handed out twice.
  at::Tensor other = core::pooled_empty({kLarge});
  EXPECT_NE(other.data_ptr(), first);
}

TEST(BufferPool, MuchSmallerRequestsDoNotTakeALargeBlock) {
  core::pool_release_idle();
  void* big = core::pooled_empty({4 * kLarge}).data_ptr();
  at::Tensor small = core::pooled_empty({kLarge});
  EXPECT_NE(small.data_ptr(), big);
  EXPECT_GE(core::pool_idle_bytes(), size_t(4 * kLarge) * 4);
  core::pool_release_idle();
  EXPECT_EQ(core::pool_idle_bytes(), 0u);
}

TEST(BufferPool, SmallRequestsAreNotPooled) {
  core::pool_release_idle();
  { at::Tensor t = core::pooled_empty({16, 16}, at::kDouble); }
  EXPECT_EQ(core::pool_idle_bytes(), 0u);
}

TEST(BufferPool, StaleBlocksAreFreed) {
  core::pool_release_idle();
  { at::Tensor unused = core::pooled_empty({3 * kLarge}); }
  // Many requests of another size, each served by one recycled block...
  for (int i = 0; i < 100; ++i) at::Tensor t = core::pooled_empty({kLarge});
  EXPECT_EQ(core::pool_idle_bytes(), size_t(4 * kLarge) * 4);
  // ...then one that fits no idle block frees the block nobody asked for.
  { at::Tensor t = core::pooled_empty({kLarge / 2}); }
  EXPECT_EQ(core::pool_idle_bytes(), size_t(kLarge) * 4 + size_t(kLarge / 2) * 4);
  core::pool_release_idle();
}

TEST(BufferPool, AutogradStealsThePooledGradient) {
  core::pool_release_idle();
  // A custom backward returning a pooled gradient.
  struct Twice : torch::autograd::Function<Twice> {
    static torch::Tensor forward(torch::autograd::AutogradContext*, const torch::Tensor& x) {
      return x * 2;
    }
    static torch::autograd::variable_list backward(torch::autograd::AutogradContext*,
                                                   torch::autograd::variable_list g) {
      at::Tensor out = core::pooled_empty(g[0].sizes());
      out.copy_(g[0] * 2);
      return {out};
    }
  };
  auto leaf = torch::ones({kLarge}).requires_grad_(true);
  auto y = Twice::apply(leaf);
  y.sum().backward();
  // The pooled gradient itself became .grad (no copy): freeing .grad returns it.
  EXPECT_EQ(core::pool_idle_bytes(), 0u);
  EXPECT_TRUE(torch::allclose(leaf.grad(), torch::full({kLarge}, 2.0f)));
  leaf.mutable_grad() = torch::Tensor();
  EXPECT_GE(core::pool_idle_bytes(), size_t(kLarge) * 4);
}

}  // namespace
