// Output buffers recycled between renders. A fresh 100+ MB image costs one
// page fault per 4 KB page on first touch (about 15 % of a forward at
// 640x512x128); once the previous call's result has been dropped by every
// holder, its storage is handed out again instead. Internal to the render
// layer.
#pragma once
#include "core/tensor.h"

namespace ddhgs::render {

// A float32 tensor of the given sizes with unspecified contents. Reuses the
// storage kept in `cache` when nothing else refers to it any more (refcount
// 1: no tensor, view or saved autograd variable); otherwise allocates and
// keeps the new storage in `cache` for the next call. The returned tensor is
// a fresh TensorImpl, so no autograd history travels with the storage.
inline torch::Tensor recycled_empty(c10::Storage& cache, at::IntArrayRef sizes) {
  int64_t numel = 1;
  for (int64_t d : sizes) numel *= d;
  const size_t bytes = size_t(numel) * sizeof(float);
  if (cache && cache.use_count() == 1 && cache.nbytes() >= bytes)
    return torch::empty({0}, torch::kFloat32).set_(cache, 0, sizes);
  torch::Tensor fresh = torch::empty(sizes, torch::kFloat32);
  cache = fresh.storage();
  return fresh;
}

}  // namespace ddhgs::render
