// Large tensors whose memory is reused between training iterations.
//
// A training step allocates the same large buffers every iteration (SH
// gradients [G, N, 15], colours [G, N], images and loss gradients [H, W, N]).
// Fresh allocations of that size are mmap'd by glibc and page-faulted in on
// first touch, then unmapped when freed: at 141 bands this cost more system
// time than the step's arithmetic. A pooled tensor returns its block to the
// pool when its last holder drops it, and the next request of a similar size
// gets that block back with its pages still mapped.
//
// Unlike a cache that keeps a reference to the storage, the pool holds none
// while the tensor lives, so the storage's use count stays 1: autograd can
// steal such a tensor into .grad() and add gradients into it in place.
#pragma once
#include <ATen/ATen.h>

#include <cstddef>
#include <cstdint>

namespace ddhgs::core {

// A contiguous tensor of the given sizes with unspecified contents. Below
// kPoolMinBytes it is a plain at::empty.
at::Tensor pooled_empty(at::IntArrayRef sizes, at::ScalarType dtype = at::kFloat);

// Smaller requests are left to malloc, which already reuses them.
constexpr size_t kPoolMinBytes = size_t(1) << 20;

// While a CropScope lives on a thread, that thread's requests whose size is
// a whole number of rows of the crop (bytes a multiple of crop_pixels: an
// image [h, w, C] or [P, C] of the crop, any C and type) are served as the
// same image of the whole view (full_pixels rows) would be: they take and
// make blocks of the whole view's size. A training step on a random crop of
// its view (a crop's area is anything from a sliver to the whole view) then
// meets the same few blocks whatever its size, instead of faulting in fresh
// pages whenever its size class was freed. Scopes nest; the innermost wins.
class CropScope {
 public:
  CropScope(int64_t crop_pixels, int64_t full_pixels);
  ~CropScope();
  CropScope(const CropScope&) = delete;
  CropScope& operator=(const CropScope&) = delete;

 private:
  int64_t previous_crop_, previous_full_;
};

// Bytes of the blocks waiting in the pool (not in use).
size_t pool_idle_bytes();
// Frees every block waiting in the pool (in-use blocks return later).
void pool_release_idle();

}  // namespace ddhgs::core
