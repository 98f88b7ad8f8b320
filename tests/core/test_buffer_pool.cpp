// core::pooled_empty: blocks come back to the pool and are handed out again,
// tensors keep a storage use count of 1 (so autograd steals them into
// .grad), stale blocks are freed.
#include <gtest/gtest.h>

#include <optional>
#include <random>
#include <set>

#include "core/buffer_pool.h"
#include "core/tensor.h"

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

// A step on a random crop of its view asks for buffers of another size each
// time; blocks are made in size classes (four per octave), so those sizes
// keep meeting the same few blocks instead of each one faulting in new pages.
TEST(BufferPool, RequestsOfChangingSizesReuseAFewBlocks) {
  core::pool_release_idle();
  void* first = nullptr;
  { first = core::pooled_empty({5 * kLarge / 4}).data_ptr(); }  // 5 MB
  // 5.5 MB: more than the 5 MB asked for first, within that block's class.
  EXPECT_EQ(core::pooled_empty({11 * kLarge / 8}).data_ptr(), first);
  core::pool_release_idle();
  std::set<void*> blocks;
  std::mt19937 draw(7);
  for (int i = 0; i < 200; ++i) {
    // Two buffers in flight at once, each between 3 and 6 MB.
    const int64_t a = kLarge * 3 / 4 + int64_t(draw() % uint32_t(kLarge * 3 / 4));
    const int64_t b = kLarge * 3 / 4 + int64_t(draw() % uint32_t(kLarge * 3 / 4));
    at::Tensor x = core::pooled_empty({a}), y = core::pooled_empty({b});
    blocks.insert(x.data_ptr()), blocks.insert(y.data_ptr());
  }
  // 3-6 MB spans five classes; two of each at most (plus what the stale
  // eviction frees and makes again).
  EXPECT_LE(blocks.size(), 12u);
  core::pool_release_idle();
}

TEST(BufferPool, SmallRequestsAreNotPooled) {
  core::pool_release_idle();
  { at::Tensor t = core::pooled_empty({16, 16}, at::kDouble); }
  EXPECT_EQ(core::pool_idle_bytes(), 0u);
}

TEST(BufferPool, StaleBlocksAreFreed) {
  core::pool_release_idle();
  { at::Tensor unused = core::pooled_empty({4 * kLarge}); }
  // Many requests of another size, each served by one recycled block...
  for (int i = 0; i < 100; ++i) at::Tensor t = core::pooled_empty({kLarge});
  EXPECT_EQ(core::pool_idle_bytes(), size_t(5 * kLarge) * 4);
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

// Steps on random crops of one view: crops from a sliver to the whole view
// (sizes over several octaves), three crop images in flight per step (the
// target, the render and its gradient: [h, w, C] or [P, C]). Without a
// CropScope the pool makes blocks for many size classes and frees the ones
// that go unasked for a while; with one, every crop image is served like the
// whole view's, so the same three blocks come back on every step. Requests
// that are not a whole number of the crop's rows keep their own size.
TEST(BufferPool, CropsOfAViewShareTheWholeViewsBlocks) {
  constexpr int64_t kWidth = 256, kHeight = 200, kChannels = 24;  // 4.9 MB whole
  auto steps = [](bool scoped) {
    core::pool_release_idle();
    std::set<void*> blocks;
    std::mt19937 draw(11);
    for (int step = 0; step < 300; ++step) {
      const int64_t w = 8 + int64_t(draw() % uint32_t(kWidth - 7));
      const int64_t h = 8 + int64_t(draw() % uint32_t(kHeight - 7));
      std::optional<core::CropScope> scope;
      if (scoped) scope.emplace(w * h, kWidth * kHeight);
      at::Tensor target = core::pooled_empty({h, w, kChannels});
      at::Tensor render = core::pooled_empty({h * w, kChannels});
      at::Tensor grad = core::pooled_empty({h, w, kChannels});
      // Other buffers of the step, of sizes unrelated to the crop.
      for (int i = 0; i < 30; ++i) at::Tensor other = core::pooled_empty({kLarge / 2 + 3});
      for (const at::Tensor& t : {target, render, grad}) {
        if (t.nbytes() >= core::kPoolMinBytes || scoped) blocks.insert(t.data_ptr());
      }
    }
    core::pool_release_idle();
    return blocks.size();
  };
  EXPECT_EQ(steps(true), 3u);
  EXPECT_GT(steps(false), 10u);

  // A crop image takes the whole view's block; a request that is not a
  // whole number of the crop's rows keeps its own size.
  core::pool_release_idle();
  void* view_block = nullptr;
  { view_block = core::pooled_empty({4 * kLarge}).data_ptr(); }  // 16 MB, idle
  {
    core::CropScope scope(kLarge / 4, kLarge);              // 262,144 of 1,048,576 pixels
    const at::Tensor image = core::pooled_empty({kLarge});  // 16 bytes a pixel
    EXPECT_EQ(image.data_ptr(), view_block);
  }
  {
    core::CropScope scope(kLarge / 4, kLarge);
    const at::Tensor other = core::pooled_empty({kLarge + 1});
    EXPECT_NE(other.data_ptr(), view_block);
  }
  const at::Tensor outside = core::pooled_empty({kLarge});
  EXPECT_NE(outside.data_ptr(), view_block);
  core::pool_release_idle();
}

}  // namespace
