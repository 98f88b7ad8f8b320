// One splat blended into a run of up to 8 pixels of a row: the scalar heart
// of blending (power, exp, alpha, the 1/255 test, the transmittance step),
// vectorised over pixels. Internal to the render layer; forward and backward
// share it, so the backward replays the forward's decisions bit for bit.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace ddhgs::render {

constexpr int kRowLanes = 8;  // pixels of a row evaluated together
constexpr float kMinAlpha = 1.0f / 255.0f;
constexpr float kMaxAlpha = 0.99f;
constexpr float kMinTransmittance = 1e-4f;

// Per-Gaussian screen data the inner loop reads, one cache line each.
struct alignas(64) Splat {
  float mx, my, a, b, c, opacity, depth;
  float skip_power;    // power beyond which alpha < 1/255 for sure
  float ext_x, ext_y;  // half extents (px) of the region with alpha >= 1/255
  // Row span where power <= skip_power + 1e-3, from double (see row_span):
  // span_k0 = 2 (skip_power + 1e-3) / a, span_k1 = det / a^2, span_k2 = b / a.
  float span_k0, span_k1, span_k2;
};

// Where a splat can reach alpha >= 1/255: o exp(-power) >= 1/255 <=> power <=
// ln(255 o); the ellipse power = thr has half extents sqrt(2 thr cov_xx),
// cov = conic^-1. Shared by the binning and the blender, so that both skip the
// same tiles and pixels. empty: the splat never reaches 1/255.
struct SplatExtent {
  float skip_power;    // power beyond which alpha < 1/255 for sure
  float ext_x, ext_y;  // half extents (px), widened by a pixel
  bool empty;
};

inline SplatExtent splat_extent(float a, float b, float c, float opacity) {
  const double thr = std::log(255.0 * opacity);
  const double det = double(a) * c - double(b) * b;
  if (!(thr >= 0) || !(det > 0)) return {-1, -1, -1, true};
  const double power = thr + 1e-3;  // margin well above float rounding
  return {float(power), float(std::sqrt(2 * power * c / det) + 1),
          float(std::sqrt(2 * power * a / det) + 1), false};
}

// Fills a splat's extent and span coefficients; s.a, s.b, s.c and s.opacity
// must be set. A splat that never reaches 1/255 gets ext_x = -1.
inline void set_extent(Splat& s) {
  const SplatExtent e = splat_extent(s.a, s.b, s.c, s.opacity);
  if (e.empty) {
    s.skip_power = s.ext_x = s.ext_y = -1;
    s.span_k0 = s.span_k1 = s.span_k2 = 0;
    return;
  }
  s.skip_power = e.skip_power, s.ext_x = e.ext_x, s.ext_y = e.ext_y;
  // The extra 1e-3 of power keeps the float rounding of the span (~1e-6 / a
  // in hw^2) on the safe side.
  const double inv_a = 1.0 / double(s.a);
  const double det = double(s.a) * s.c - double(s.b) * s.b;
  s.span_k0 = float(2 * (double(e.skip_power) + 1e-3) * inv_a);
  s.span_k1 = float(det * inv_a * inv_a);
  s.span_k2 = float(double(s.b) * inv_a);
}

// Per-pixel state of a run of 8 pixels, each pointer at the run's first
// pixel. All 8 lanes are read and written whatever the run length: lanes past
// the run keep their T, and their weight / raw / trans values are never read.
struct RowState {
  float* T;             // [8] transmittance, advanced in place
  const uint8_t* done;  // [8] pixels that already stopped
  float* weight;        // [8] out: alpha * T before the splat
  float* raw;           // [8] out, may be null: o exp(-power) before the 0.99 clamp
  float* trans;         // [8] out, with raw: T before the splat
};

struct RowBits {
  unsigned blend;  // lanes that blend this splat
  unsigned stop;   // lanes where it would take T below 1e-4: they stop instead
};

#if defined(__AVX2__) && defined(__FMA__)
// exp(x) for x <= 0 (Cephes expf: Cody-Waite reduction and a degree-5
// polynomial, about 1 ulp): 8 lanes for the price of one libm call.
inline __m256 exp_nonpositive(__m256 x) {
  x = _mm256_max_ps(x, _mm256_set1_ps(-87.0f));
  const __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)),
                                   _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693359375f), x);
  r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-2.12194440e-4f), r);
  __m256 p = _mm256_set1_ps(1.9875691500e-4f);
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.3981999507e-3f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(8.3334519073e-3f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(4.1665795894e-2f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.6666665459e-1f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(5.0000001201e-1f));
  p = _mm256_fmadd_ps(p, _mm256_mul_ps(r, r), _mm256_add_ps(r, _mm256_set1_ps(1.0f)));
  const __m256i scale =
      _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(p, _mm256_castsi256_ps(scale));
}

// Pixels x .. x+count-1 of one row (count <= 8) against splat g: a pixel
// blends where it is not done, alpha >= 1/255 and T stays >= 1e-4.
inline RowBits blend_row(const Splat& g, int x, int count, float dy, const RowState& st) {
  const __m256 xs =
      _mm256_add_ps(_mm256_set1_ps(float(x) + 0.5f), _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256 dx = _mm256_sub_ps(_mm256_set1_ps(g.mx), xs);
  const __m256 dyv = _mm256_set1_ps(dy);
  // power = 0.5 (a dx^2 + c dy^2) + b dx dy
  const __m256 quad =
      _mm256_fmadd_ps(_mm256_mul_ps(_mm256_set1_ps(g.a), dx), dx, _mm256_set1_ps(g.c * dy * dy));
  const __m256 power = _mm256_fmadd_ps(_mm256_set1_ps(0.5f), quad,
                                       _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(g.b), dx), dyv));
  const __m256 r = _mm256_mul_ps(_mm256_set1_ps(g.opacity),
                                 exp_nonpositive(_mm256_sub_ps(_mm256_setzero_ps(), power)));
  const __m256 alpha = _mm256_min_ps(r, _mm256_set1_ps(kMaxAlpha));
  const __m256 keep = _mm256_and_ps(_mm256_cmp_ps(power, _mm256_set1_ps(g.skip_power), _CMP_LE_OQ),
                                    _mm256_cmp_ps(alpha, _mm256_set1_ps(kMinAlpha), _CMP_GE_OQ));
  uint64_t done8;
  std::memcpy(&done8, st.done, sizeof done8);
  const __m256i live = _mm256_cmpeq_epi32(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(int64_t(done8))),
                                          _mm256_setzero_si256());
  const unsigned keep_bits =
      unsigned(_mm256_movemask_ps(_mm256_and_ps(keep, _mm256_castsi256_ps(live)))) &
      ((1u << count) - 1);
  const __m256 t = _mm256_loadu_ps(st.T);
  const __m256 next = _mm256_mul_ps(t, _mm256_sub_ps(_mm256_set1_ps(1.0f), alpha));
  const unsigned low_bits = unsigned(
      _mm256_movemask_ps(_mm256_cmp_ps(next, _mm256_set1_ps(kMinTransmittance), _CMP_LT_OQ)));
  const RowBits bits{keep_bits & ~low_bits, keep_bits & low_bits};
  // Lane i of the blend mask: bit i of bits.blend.
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  const __m256 blend = _mm256_castsi256_ps(
      _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(bits.blend)), lane_bit), lane_bit));
  _mm256_storeu_ps(st.T, _mm256_blendv_ps(t, next, blend));
  _mm256_storeu_ps(st.weight, _mm256_mul_ps(alpha, t));
  if (st.raw) {
    _mm256_storeu_ps(st.raw, r);
    _mm256_storeu_ps(st.trans, t);
  }
  return bits;
}
#else
inline RowBits blend_row(const Splat& g, int x, int count, float dy, const RowState& st) {
  RowBits bits{0, 0};
  for (int i = 0; i < kRowLanes; ++i) {
    const float dx = g.mx - (float(x + i) + 0.5f);
    const float power = 0.5f * (g.a * dx * dx + g.c * dy * dy) + g.b * dx * dy;
    const float raw = g.opacity * std::exp(-power);
    const float alpha = raw < kMaxAlpha ? raw : kMaxAlpha;
    const float t = st.T[i], next = t * (1.0f - alpha);
    st.weight[i] = alpha * t;
    if (st.raw) st.raw[i] = raw, st.trans[i] = t;
    if (i >= count || st.done[i] || !(power <= g.skip_power) || !(alpha >= kMinAlpha)) continue;
    if (next < kMinTransmittance) {
      bits.stop |= 1u << i;
      continue;
    }
    bits.blend |= 1u << i;
    st.T[i] = next;
  }
  return bits;
}
#endif

// Per-pixel masks of a run: dst[i] |= value for each bit i of bits (i < 8).
inline void or_lane_bits(uint64_t* dst, unsigned bits, uint64_t value) {
#if defined(__AVX2__) && defined(__FMA__)
  const __m256i b = _mm256_set1_epi64x(bits), v = _mm256_set1_epi64x(int64_t(value));
  const __m256i lo = _mm256_setr_epi64x(1, 2, 4, 8), hi = _mm256_setr_epi64x(16, 32, 64, 128);
  auto* d = reinterpret_cast<__m256i*>(dst);
  const __m256i m_lo = _mm256_and_si256(_mm256_cmpeq_epi64(_mm256_and_si256(b, lo), lo), v);
  const __m256i m_hi = _mm256_and_si256(_mm256_cmpeq_epi64(_mm256_and_si256(b, hi), hi), v);
  _mm256_storeu_si256(d, _mm256_or_si256(_mm256_loadu_si256(d), m_lo));
  _mm256_storeu_si256(d + 1, _mm256_or_si256(_mm256_loadu_si256(d + 1), m_hi));
#else
  for (int i = 0; i < kRowLanes; ++i)
    if (bits >> i & 1) dst[i] |= value;
#endif
}

}  // namespace ddhgs::render
