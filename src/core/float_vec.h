// Vectors of floats for hand-vectorised loops over bands (the fused SSIM
// kernel, the latent decode): GCC/Clang vector extensions, whose arithmetic
// is element-wise, and unaligned loads and stores of them.
#pragma once
#include <cstring>

namespace ddhgs::core {

// kN floats: one AVX-512 register for kN = 16 where the build has AVX-512,
// two AVX2 ones otherwise.
template <int kN>
struct FloatVec {
  typedef float type __attribute__((vector_size(sizeof(float) * kN)));
};

template <typename V>
inline V load_vec(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <typename V>
inline void store_vec(float* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}

}  // namespace ddhgs::core
