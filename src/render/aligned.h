// Cache-line aligned float buffers for the blender's rows. With a 64-byte
// aligned start, a row whose length is a multiple of 16 floats never has a
// 512-bit load straddle two cache lines (malloc's large blocks start 16 bytes
// into a page, which splits every such load in two). Internal to the render
// layer.
#pragma once
#include <cstddef>
#include <new>
#include <vector>

namespace ddhgs::render {

constexpr std::size_t kCacheLine = 64;

template <class T>
struct CacheAligned {
  using value_type = T;
  CacheAligned() = default;
  template <class U>
  CacheAligned(const CacheAligned<U>&) {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(kCacheLine)));
  }
  void deallocate(T* p, std::size_t) { ::operator delete(p, std::align_val_t(kCacheLine)); }
  template <class U>
  bool operator==(const CacheAligned<U>&) const {
    return true;
  }
  template <class U>
  bool operator!=(const CacheAligned<U>&) const {
    return false;
  }
};

template <class T>
using AlignedVector = std::vector<T, CacheAligned<T>>;

}  // namespace ddhgs::render
