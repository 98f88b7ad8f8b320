#include "core/buffer_pool.h"

#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>
#include <vector>

namespace ddhgs::core {
namespace {

// A block is handed out for requests between 4/5 of its size and its size,
// so buffers that shrink a little (pruned Gaussians) keep their block.
constexpr size_t kFitNumerator = 5, kFitDenominator = 4;
// Blocks not handed out during this many requests are freed: sizes that
// stopped being asked for (the Gaussian count grew) do not linger.
constexpr uint64_t kMaxIdleRequests = 64;
constexpr size_t kAlignment = 64;

// New blocks are sized up to the next of four size classes per octave (at
// most 19 % more than asked, inside the 5/4 fit): buffers whose size changes
// from step to step (a random crop of the view per step) then meet blocks of
// their class again instead of each new size faulting in fresh pages. Powers
// of two keep their size; every class is a whole number of pages.
// Only pooled sizes come here, so bytes >= 2^20 and octave >> 20 is exact.
static_assert(kPoolMinBytes >= (size_t(1) << 20));
size_t size_class(size_t bytes) {
  constexpr size_t kPage = 4096;
  constexpr size_t kSteps[] = {1246974, 1482910, 1763487};           // 2^(k/4) * 2^20, k = 1..3
  const size_t octave = size_t(1) << (63 - __builtin_clzll(bytes));  // largest power of 2 <= bytes
  size_t cls = octave;
  for (size_t k = 0; cls < bytes && k < 3; ++k) cls = (octave >> 20) * kSteps[k];
  if (cls < bytes) cls = 2 * octave;
  return (cls + kPage - 1) / kPage * kPage;
}

struct Block {
  void* data;
  size_t bytes;
  uint64_t released_at;  // request count when it came back
};

class Buffers {
 public:
  void* take(size_t bytes, size_t& capacity) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++requests_;
    size_t best = blocks_.size();
    for (size_t i = 0; i < blocks_.size(); ++i) {
      const size_t b = blocks_[i].bytes;
      if (b >= bytes && b * kFitDenominator <= bytes * kFitNumerator &&
          (best == blocks_.size() || b < blocks_[best].bytes))
        best = i;
    }
    if (best < blocks_.size()) {
      Block found = blocks_[best];
      blocks_.erase(blocks_.begin() + std::ptrdiff_t(best));
      capacity = found.bytes;
      return found.data;
    }
    evict_stale();
    capacity = size_class(bytes);
    void* data = std::aligned_alloc(kAlignment, capacity);
    if (!data) throw std::bad_alloc();
    return data;
  }

  void give_back(void* data, size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    blocks_.push_back({data, bytes, requests_});
  }

  size_t idle_bytes() {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t total = 0;
    for (const Block& b : blocks_) total += b.bytes;
    return total;
  }

  void release_idle() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Block& b : blocks_) std::free(b.data);
    blocks_.clear();
  }

 private:
  void evict_stale() {
    for (size_t i = blocks_.size(); i-- > 0;) {
      if (requests_ - blocks_[i].released_at <= kMaxIdleRequests) continue;
      std::free(blocks_[i].data);
      blocks_.erase(blocks_.begin() + std::ptrdiff_t(i));
    }
  }

  std::mutex mutex_;
  std::vector<Block> blocks_;
  uint64_t requests_ = 0;
};

// Never destroyed: pooled tensors may outlive static destruction order.
Buffers& buffers() {
  static Buffers* p = new Buffers();
  return *p;
}

// The innermost CropScope of this thread (crop_pixels 0: none).
thread_local int64_t t_crop_pixels = 0, t_full_pixels = 0;

}  // namespace

CropScope::CropScope(int64_t crop_pixels, int64_t full_pixels)
    : previous_crop_(t_crop_pixels), previous_full_(t_full_pixels) {
  const bool valid = crop_pixels > 0 && full_pixels >= crop_pixels;
  t_crop_pixels = valid ? crop_pixels : 0;
  t_full_pixels = valid ? full_pixels : 0;
}

CropScope::~CropScope() {
  t_crop_pixels = previous_crop_;
  t_full_pixels = previous_full_;
}

at::Tensor pooled_empty(at::IntArrayRef sizes, at::ScalarType dtype) {
  int64_t numel = 1;
  for (int64_t s : sizes) numel *= s;
  const size_t bytes = size_t(numel) * at::elementSize(dtype);
  size_t serve_as = bytes;
  if (t_crop_pixels > 0 && bytes > 0 && bytes % size_t(t_crop_pixels) == 0)
    serve_as = bytes / size_t(t_crop_pixels) * size_t(t_full_pixels);
  if (serve_as < kPoolMinBytes) return at::empty(sizes, at::TensorOptions().dtype(dtype));
  size_t capacity = 0;
  // A crop's image asks for the block of the whole view's image.
  void* data = buffers().take(serve_as, capacity);
  return at::from_blob(
      data, sizes, [capacity](void* p) { buffers().give_back(p, capacity); },
      at::TensorOptions().dtype(dtype));
}

size_t pool_idle_bytes() {
  return buffers().idle_bytes();
}

void pool_release_idle() {
  buffers().release_idle();
}

}  // namespace ddhgs::core
