// Channel-loop kernels of the blender. Rows are padded to a multiple of 8
// floats so one AVX register holds 8 channels; the accumulators of a 64-channel
// block stay in registers across a whole list of (row, weight) pairs, so each
// FMA costs one load instead of a load, a load and a store.
#pragma once
#include <algorithm>
#include <cstdint>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace ddhgs::render::kernels {

constexpr int kLanes = 8;  // channels per vector; padded row length is a multiple

inline int padded_channels(int64_t n) {
  return int((n + kLanes - 1) / kLanes * kLanes);
}

// Per-pixel sums the backward starts from, in double (they are later
// differenced against running prefixes): sum_c d[c] (image[c] - t bg[c]) and
// sum_c d[c] bg[c]; also adds t d[c] to the background gradient gbg[c].
struct PixelSums {
  double dot_image, dot_background;
};

#if defined(__AVX2__) && defined(__FMA__)

inline double horizontal_sum(__m256d v) {
  const __m128d h = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
  return _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)));
}

inline PixelSums pixel_sums(const float* d, const float* image, float t, const float* bg, int64_t n,
                            float* gbg) {
  constexpr int kDoubles = 4;
  const __m256 tv = _mm256_set1_ps(t);
  __m256d di = _mm256_setzero_pd(), db = _mm256_setzero_pd();
  int64_t c = 0;
  for (; c + kDoubles <= n; c += kDoubles) {
    const __m128 d4 = _mm_loadu_ps(d + c), bg4 = _mm_loadu_ps(bg + c);
    const __m128 rest = _mm_fnmadd_ps(_mm256_castps256_ps128(tv), bg4, _mm_loadu_ps(image + c));
    const __m256d dd = _mm256_cvtps_pd(d4);
    di = _mm256_fmadd_pd(dd, _mm256_cvtps_pd(rest), di);
    db = _mm256_fmadd_pd(dd, _mm256_cvtps_pd(bg4), db);
    _mm_storeu_ps(gbg + c, _mm_fmadd_ps(_mm256_castps256_ps128(tv), d4, _mm_loadu_ps(gbg + c)));
  }
  PixelSums s{horizontal_sum(di), horizontal_sum(db)};
  for (; c < n; ++c) {
    s.dot_image += double(d[c]) * (image[c] - t * bg[c]);
    s.dot_background += double(d[c]) * bg[c];
    gbg[c] += t * d[c];
  }
  return s;
}

// row + c, opaque to the optimiser: otherwise GCC hoists the V offsets
// c + 8 v out of the loop as separate registers and, short of registers,
// spills them to vector registers and moves them back for every row.
inline const float* row_at(const float* row, int c) {
  const float* r = row + c;
  __asm__("" : "+r"(r));
  return r;
}

template <int V>
inline void gather_axpy_block(float* acc, const float* const* rows, int c, const uint8_t* idx,
                              const float* w, int count, bool accumulate) {
  __m256 a[V];
  for (int v = 0; v < V; ++v)
    a[v] = accumulate ? _mm256_loadu_ps(acc + kLanes * v) : _mm256_setzero_ps();
  for (int j = 0; j < count; ++j) {
    const float* r = row_at(rows[idx[j]], c);
    const __m256 wj = _mm256_set1_ps(w[j]);
    for (int v = 0; v < V; ++v) a[v] = _mm256_fmadd_ps(wj, _mm256_loadu_ps(r + kLanes * v), a[v]);
  }
  for (int v = 0; v < V; ++v) _mm256_storeu_ps(acc + kLanes * v, a[v]);
}

// As gather_axpy_block, with the pairs given as the set bits k of a mask of
// nwords 64-bit words and their weights at w[k * w_stride] (no decoded index
// or weight lists).
template <int V>
inline void mask_axpy_block(float* acc, const float* const* rows, int c, const uint64_t* words,
                            int nwords, const float* w, int w_stride, bool accumulate) {
  __m256 a[V];
  for (int v = 0; v < V; ++v)
    a[v] = accumulate ? _mm256_loadu_ps(acc + kLanes * v) : _mm256_setzero_ps();
  for (int word = 0; word < nwords; ++word)
    for (uint64_t bits = words[word]; bits; bits &= bits - 1) {
      const int k = word * 64 + __builtin_ctzll(bits);
      const float* r = row_at(rows[k], c);
      const __m256 wk = _mm256_broadcast_ss(w + size_t(k) * w_stride);
      for (int v = 0; v < V; ++v) a[v] = _mm256_fmadd_ps(wk, _mm256_loadu_ps(r + kLanes * v), a[v]);
    }
  for (int v = 0; v < V; ++v) _mm256_storeu_ps(acc + kLanes * v, a[v]);
}

// Sums of the lanes of s[0..8), as one vector: lane u holds sum(s[u]).
inline __m256 lane_sums8(const __m256* s) {
  const __m256 a = _mm256_hadd_ps(_mm256_hadd_ps(s[0], s[1]), _mm256_hadd_ps(s[2], s[3]));
  const __m256 b = _mm256_hadd_ps(_mm256_hadd_ps(s[4], s[5]), _mm256_hadd_ps(s[6], s[7]));
  return _mm256_add_ps(_mm256_permute2f128_ps(a, b, 0x20), _mm256_permute2f128_ps(a, b, 0x31));
}

template <int V>
inline void gather_dot_block(const float* x, const float* const* rows, int c, const uint8_t* idx,
                             int count, float* out) {
  __m256 xv[V];
  for (int v = 0; v < V; ++v) xv[v] = _mm256_loadu_ps(x + kLanes * v);
  auto dot = [&](int j) {
    const float* r = row_at(rows[idx[j]], c);
    __m256 s = _mm256_mul_ps(xv[0], _mm256_loadu_ps(r));
    for (int v = 1; v < V; ++v) s = _mm256_fmadd_ps(xv[v], _mm256_loadu_ps(r + kLanes * v), s);
    return s;
  };
  int j = 0;
  // Eight rows at a time share one transposing horizontal sum.
  for (; j + 8 <= count; j += 8) {
    __m256 s[8];
    for (int u = 0; u < 8; ++u) s[u] = dot(j + u);
    _mm256_storeu_ps(out + j, _mm256_add_ps(_mm256_loadu_ps(out + j), lane_sums8(s)));
  }
  for (; j < count; ++j) {
    const __m256 s = dot(j);
    const __m128 h = _mm_add_ps(_mm256_castps256_ps128(s), _mm256_extractf128_ps(s, 1));
    const __m128 h2 = _mm_add_ps(h, _mm_movehl_ps(h, h));
    out[j] += _mm_cvtss_f32(_mm_add_ss(h2, _mm_shuffle_ps(h2, h2, 1)));
  }
}

// Calls block<V>(offset) over a padded row of n channels in blocks of at most
// 8 vectors, so every block size is a compile-time constant.
template <template <int> class Op, typename... Args>
inline void over_blocks(int n, Args... args) {
  int c = 0;
  for (; c + 8 * kLanes <= n; c += 8 * kLanes) Op<8>::run(c, args...);
  switch ((n - c) / kLanes) {
    case 1:
      Op<1>::run(c, args...);
      break;
    case 2:
      Op<2>::run(c, args...);
      break;
    case 3:
      Op<3>::run(c, args...);
      break;
    case 4:
      Op<4>::run(c, args...);
      break;
    case 5:
      Op<5>::run(c, args...);
      break;
    case 6:
      Op<6>::run(c, args...);
      break;
    case 7:
      Op<7>::run(c, args...);
      break;
    default:
      break;
  }
}

template <int V>
struct AxpyOp {
  static void run(int c, float* acc, const float* const* rows, const uint8_t* idx, const float* w,
                  int count, bool accumulate) {
    gather_axpy_block<V>(acc + c, rows, c, idx, w, count, accumulate);
  }
};

template <int V>
struct MaskAxpyOp {
  static void run(int c, float* acc, const float* const* rows, const uint64_t* words, int nwords,
                  const float* w, int w_stride, bool accumulate) {
    mask_axpy_block<V>(acc + c, rows, c, words, nwords, w, w_stride, accumulate);
  }
};

template <int V>
struct DotOp {
  static void run(int c, const float* x, const float* const* rows, const uint8_t* idx, int count,
                  float* out) {
    gather_dot_block<V>(x + c, rows, c, idx, count, out);
  }
};

// acc[0, n) (+)= sum_j w[j] * rows[idx[j]][0, n); n is a multiple of kLanes.
// accumulate = false overwrites acc, which saves zeroing it beforehand.
inline void gather_axpy(float* acc, const float* const* rows, int n, const uint8_t* idx,
                        const float* w, int count, bool accumulate = true) {
  over_blocks<AxpyOp>(n, acc, rows, idx, w, count, accumulate);
}

// acc[0, n) (+)= sum over set bits k of words[0, nwords) (bit k % 64 of word
// k / 64) of w[k * w_stride] * rows[k][0, n); n is a multiple of kLanes.
inline void mask_axpy(float* acc, const float* const* rows, int n, const uint64_t* words,
                      int nwords, const float* w, int w_stride, bool accumulate = true) {
  over_blocks<MaskAxpyOp>(n, acc, rows, words, nwords, w, w_stride, accumulate);
}

// out[j] += dot(x[0, n), rows[idx[j]][0, n)) for each j; n a multiple of kLanes.
inline void gather_dot(const float* x, const float* const* rows, int n, const uint8_t* idx,
                       int count, float* out) {
  over_blocks<DotOp>(n, x, rows, idx, count, out);
}

// dst[0, n) = acc[0, n) + t * bg[0, n) (acc may be null: zeros). The image
// is written once and not read again by this pass, so whole-vector rows go
// to memory with streaming stores, skipping the read-for-ownership of each
// destination line. Call end_streaming_writes() before other threads read.
inline void write_pixel(float* dst, const float* acc, float t, const float* bg, int64_t n) {
  if (n % kLanes == 0 && reinterpret_cast<uintptr_t>(dst) % 32 == 0) {
    const __m256 tv = _mm256_set1_ps(t);
    for (int64_t c = 0; c < n; c += kLanes) {
      const __m256 b = _mm256_mul_ps(tv, _mm256_loadu_ps(bg + c));
      _mm256_stream_ps(dst + c, acc ? _mm256_add_ps(_mm256_loadu_ps(acc + c), b) : b);
    }
    return;
  }
  for (int64_t c = 0; c < n; ++c) dst[c] = (acc ? acc[c] : 0.0f) + t * bg[c];
}

inline void end_streaming_writes() {
  _mm_sfence();
}

#if defined(__AVX512F__)
// AVX-512 versions of the two hot loops (compiled only where the build
// targets AVX-512, e.g. -march=native on such a CPU). A 512-bit register holds
// 16 channels, so a 141-band row (144 padded) is 9 registers: a pixel's or
// a Gaussian's whole row stays in registers. Rows are padded to a multiple of
// 8 only; the last vector of a row is loaded and stored with a lane mask
// (masked-off lanes are never touched in memory).
constexpr int kWideLanes = 16;
constexpr int kMaxWideVectors = 12;  // per block: 2 x 12 accumulators + 3 fit in 32 registers

template <int V>
inline __m512 load_wide(const float* p, int v, __mmask16 last) {
  return v == V - 1 ? _mm512_maskz_loadu_ps(last, p + kWideLanes * v)
                    : _mm512_loadu_ps(p + kWideLanes * v);
}

template <int V>
inline void store_wide(float* p, int v, __mmask16 last, __m512 x) {
  if (v == V - 1)
    _mm512_mask_storeu_ps(p + kWideLanes * v, last, x);
  else
    _mm512_storeu_ps(p + kWideLanes * v, x);
}

// Sum of the 16 lanes (GCC 12's _mm512_reduce_add_ps trips
// -Wmaybe-uninitialized in its own header).
inline float wide_sum(__m512 s) {
  // The maskz_ forms with all lanes on: the plain ones trip the same warning.
  constexpr __mmask16 all = 0xffff;
  s = _mm512_add_ps(s, _mm512_maskz_shuffle_f32x4(all, s, s, 0x4e));  // 256-bit halves
  s = _mm512_add_ps(s, _mm512_maskz_shuffle_f32x4(all, s, s, 0xb1));  // 128-bit quarters
  s = _mm512_add_ps(s, _mm512_maskz_permute_ps(all, s, 0x4e));        // pairs of lanes
  s = _mm512_add_ps(s, _mm512_maskz_permute_ps(all, s, 0xb1));        // lanes
  return _mm512_cvtss_f32(s);
}

// As mask_axpy_block, 16 channels per vector.
template <int V>
inline void wide_mask_axpy_block(float* acc, const float* const* rows, int c, const uint64_t* words,
                                 int nwords, const float* w, int w_stride, bool accumulate,
                                 __mmask16 last) {
  __m512 a[V];
  for (int v = 0; v < V; ++v) a[v] = accumulate ? load_wide<V>(acc, v, last) : _mm512_setzero_ps();
  for (int word = 0; word < nwords; ++word)
    for (uint64_t bits = words[word]; bits; bits &= bits - 1) {
      const int k = word * 64 + __builtin_ctzll(bits);
      const float* r = row_at(rows[k], c);
      const __m512 wk = _mm512_set1_ps(w[size_t(k) * w_stride]);
      for (int v = 0; v < V; ++v) a[v] = _mm512_fmadd_ps(wk, load_wide<V>(r, v, last), a[v]);
    }
  for (int v = 0; v < V; ++v) store_wide<V>(acc, v, last, a[v]);
}

// Both colour terms of one Gaussian's backward in one pass over its pixels:
// with x_p the pixel's dL/dpixel row, gcol += sum_p w[p] x_p and
// dots[p] (+)= colour . x_p. The colour row and the gradient accumulators
// stay in registers, so each x_p is loaded once for the two FMAs.
template <int V>
inline void wide_colour_grads_block(float* gcol, const float* colour, const float* const* x_rows,
                                    int c, const uint64_t* words, int nwords, const float* w,
                                    float* dots, bool first, __mmask16 last) {
  __m512 col[V], g[V];
  for (int v = 0; v < V; ++v) {
    col[v] = load_wide<V>(colour, v, last);
    g[v] = load_wide<V>(gcol, v, last);
  }
  for (int word = 0; word < nwords; ++word)
    for (uint64_t bits = words[word]; bits; bits &= bits - 1) {
      const int p = word * 64 + __builtin_ctzll(bits);
      const float* x = row_at(x_rows[p], c);
      const __m512 wp = _mm512_set1_ps(w[p]);
      __m512 s = _mm512_setzero_ps();
      for (int v = 0; v < V; ++v) {
        const __m512 xv = load_wide<V>(x, v, last);
        g[v] = _mm512_fmadd_ps(wp, xv, g[v]);
        s = _mm512_fmadd_ps(col[v], xv, s);
      }
      const float d = wide_sum(s);
      dots[p] = first ? d : dots[p] + d;
    }
  for (int v = 0; v < V; ++v) store_wide<V>(gcol, v, last, g[v]);
}

// Calls Op<V>::run(c, first, last mask, args...) over a row of n channels
// (a multiple of kLanes) in blocks of at most kMaxWideVectors vectors.
template <template <int> class Op, typename... Args>
inline void over_wide_blocks(int n, Args... args) {
  for (int c = 0; c < n; c += kMaxWideVectors * kWideLanes) {
    const int rest = std::min(n - c, kMaxWideVectors * kWideLanes);
    const int vectors = (rest + kWideLanes - 1) / kWideLanes;
    const int tail = rest - (vectors - 1) * kWideLanes;
    const __mmask16 last = __mmask16((1u << tail) - 1);
    const bool first = c == 0;
    switch (vectors) {
#define DDHGS_WIDE_CASE(V)               \
  case V:                                \
    Op<V>::run(c, first, last, args...); \
    break;
      DDHGS_WIDE_CASE(1)
      DDHGS_WIDE_CASE(2)
      DDHGS_WIDE_CASE(3)
      DDHGS_WIDE_CASE(4)
      DDHGS_WIDE_CASE(5)
      DDHGS_WIDE_CASE(6)
      DDHGS_WIDE_CASE(7)
      DDHGS_WIDE_CASE(8)
      DDHGS_WIDE_CASE(9)
      DDHGS_WIDE_CASE(10)
      DDHGS_WIDE_CASE(11)
      DDHGS_WIDE_CASE(12)
#undef DDHGS_WIDE_CASE
      default:
        break;
    }
  }
}

template <int V>
struct WideMaskAxpyOp {
  static void run(int c, bool, __mmask16 last, float* acc, const float* const* rows,
                  const uint64_t* words, int nwords, const float* w, int w_stride,
                  bool accumulate) {
    wide_mask_axpy_block<V>(acc + c, rows, c, words, nwords, w, w_stride, accumulate, last);
  }
};

template <int V>
struct WideColourGradsOp {
  static void run(int c, bool first, __mmask16 last, float* gcol, const float* colour,
                  const float* const* x_rows, const uint64_t* words, int nwords, const float* w,
                  float* dots) {
    wide_colour_grads_block<V>(gcol + c, colour + c, x_rows, c, words, nwords, w, dots, first,
                               last);
  }
};

// mask_axpy with 16-channel vectors (same contract).
inline void wide_mask_axpy(float* acc, const float* const* rows, int n, const uint64_t* words,
                           int nwords, const float* w, int w_stride, bool accumulate = true) {
  over_wide_blocks<WideMaskAxpyOp>(n, acc, rows, words, nwords, w, w_stride, accumulate);
}

// For the set bits p of words[0, nwords): gcol[0, n) += w[p] x_rows[p][0, n)
// and dots[p] = colour[0, n) . x_rows[p][0, n) (overwritten); n a multiple of
// kLanes, rows padded with zeros.
inline void wide_colour_grads(float* gcol, const float* colour, const float* const* x_rows, int n,
                              const uint64_t* words, int nwords, const float* w, float* dots) {
  over_wide_blocks<WideColourGradsOp>(n, gcol, colour, x_rows, words, nwords, w, dots);
}
#endif  // __AVX512F__

#else  // portable fallback: the compiler vectorises the inner loops it can

inline void gather_axpy(float* acc, const float* const* rows, int n, const uint8_t* idx,
                        const float* w, int count, bool accumulate = true) {
  if (!accumulate) std::fill(acc, acc + n, 0.0f);
  for (int j = 0; j < count; ++j) {
    const float* r = rows[idx[j]];
    for (int c = 0; c < n; ++c) acc[c] += w[j] * r[c];
  }
}

inline void mask_axpy(float* acc, const float* const* rows, int n, const uint64_t* words,
                      int nwords, const float* w, int w_stride, bool accumulate = true) {
  if (!accumulate) std::fill(acc, acc + n, 0.0f);
  for (int word = 0; word < nwords; ++word)
    for (uint64_t bits = words[word]; bits; bits &= bits - 1) {
      const int k = word * 64 + __builtin_ctzll(bits);
      const float* r = rows[k];
      for (int c = 0; c < n; ++c) acc[c] += w[size_t(k) * w_stride] * r[c];
    }
}

inline void gather_dot(const float* x, const float* const* rows, int n, const uint8_t* idx,
                       int count, float* out) {
  for (int j = 0; j < count; ++j) {
    const float* r = rows[idx[j]];
    float s = 0;
    for (int c = 0; c < n; ++c) s += x[c] * r[c];
    out[j] += s;
  }
}

inline void write_pixel(float* dst, const float* acc, float t, const float* bg, int64_t n) {
  for (int64_t c = 0; c < n; ++c) dst[c] = (acc ? acc[c] : 0.0f) + t * bg[c];
}

inline void end_streaming_writes() {}

inline PixelSums pixel_sums(const float* d, const float* image, float t, const float* bg, int64_t n,
                            float* gbg) {
  PixelSums s{0, 0};
  for (int64_t c = 0; c < n; ++c) {
    s.dot_image += double(d[c]) * (image[c] - t * bg[c]);
    s.dot_background += double(d[c]) * bg[c];
    gbg[c] += t * d[c];
  }
  return s;
}

#endif

}  // namespace ddhgs::render::kernels
