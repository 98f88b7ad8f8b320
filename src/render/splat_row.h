// A group of 8 pixels of a row blended with a list of splats: the scalar
// heart of blending (power, exp, alpha, the 1/255 test, the transmittance
// step, pair_step), vectorised over pixels. Internal to the render layer;
// every blender path, forward and backward, takes its decisions from it, so a
// backward replays its forward's decisions bit for bit.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace ddhgs::render {

constexpr int kRowLanes = 8;  // pixels of a group, evaluated together
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

// Fills a splat's extent (e = splat_extent of its conic and opacity) and
// span coefficients; s.a, s.b and s.c must be set. A splat that never
// reaches 1/255 gets ext_x = -1.
inline void set_extent(Splat& s, const SplatExtent& e) {
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

// One group of 8 horizontally adjacent pixels (8-aligned within its tile
// row) against the chunk Gaussians that may reach it, in depth order. The
// group's transmittance and stopped lanes stay in registers across the whole
// list, and every store is 8 aligned floats, so consecutive splats never wait
// on a partially overlapping store.
struct GroupState {
  float* T;         // [8] transmittance, advanced in place
  unsigned live;    // lanes not stopped and inside the image, updated in place
  uint64_t* pmask;  // [8] out: bit k where chunk Gaussian k blends the pixel
};

// Where per-pair values go: chunk Gaussian k's 8 values at base + k * stride.
struct PairStores {
  float* weight;           // alpha * T before the splat
  float* raw;              // may be null: o exp(-power) before the 0.99 clamp
  float* trans;            // with raw: T before the splat
  int stride;              // floats
  uint64_t* gmask;         // may be null: [64][words] pixels each Gaussian blends
  int words, word, shift;  // gmask row length, the group's word and bit offset
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

// Bits 0-7 of x moved to the even bits 0, 2, .., 14.
inline uint32_t spread_even(uint32_t x) {
  x = (x | x << 4) & 0x0f0fu;
  x = (x | x << 2) & 0x3333u;
  return (x | x << 1) & 0x5555u;
}

// Which 8-pixel groups of a tile the row spans of g reach, for the rows
// y .. y + count - 1 (count <= 8) and the tile columns [x0, x1): bit 2 i + h
// for row y + i and half h (pixels x0 + 8 h .. x0 + 8 h + 7). The span of a
// row is where power <= skip_power + 1e-3: the roots in dx of
// 0.5 a dx^2 + b dy dx + 0.5 c dy^2 - power, i.e. dx = -(b / a) dy +- hw,
// hw^2 = 2 power / a - (det / a^2) dy^2 (coefficients from set_extent),
// widened by slack pixels so that the exact per-pixel test, not float
// rounding here, decides.
inline uint32_t span_groups(const Splat& g, int y, int count, int x0, int x1, float slack) {
  const __m256 lane = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 dy =
      _mm256_sub_ps(_mm256_set1_ps(g.my), _mm256_add_ps(_mm256_set1_ps(float(y) + 0.5f), lane));
  const __m256 hw2 =
      _mm256_fnmadd_ps(_mm256_mul_ps(_mm256_set1_ps(g.span_k1), dy), dy, _mm256_set1_ps(g.span_k0));
  const __m256 hw =
      _mm256_add_ps(_mm256_sqrt_ps(_mm256_max_ps(hw2, _mm256_setzero_ps())), _mm256_set1_ps(slack));
  // Pixel x (centre x + 0.5) where power is least along the row.
  const __m256 centre = _mm256_fmadd_ps(_mm256_set1_ps(g.span_k2), dy, _mm256_set1_ps(g.mx - 0.5f));
  const __m256 left = _mm256_set1_ps(float(x0)), right = _mm256_set1_ps(float(x1));
  const __m256 lo = _mm256_min_ps(
      _mm256_max_ps(
          _mm256_round_ps(_mm256_sub_ps(centre, hw), _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC),
          left),
      right);
  const __m256 hi = _mm256_min_ps(
      _mm256_max_ps(_mm256_add_ps(_mm256_round_ps(_mm256_add_ps(centre, hw),
                                                  _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC),
                                  _mm256_set1_ps(1.0f)),
                    left),
      right);
  const __m256 valid =
      _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(hw2, _mm256_setzero_ps(), _CMP_GE_OQ),
                                  _mm256_cmp_ps(lo, hi, _CMP_LT_OQ)),
                    _mm256_cmp_ps(lane, _mm256_set1_ps(float(count)), _CMP_LT_OQ));
  const __m256 mid = _mm256_set1_ps(float(x0 + kRowLanes));
  const unsigned first =
      unsigned(_mm256_movemask_ps(_mm256_and_ps(valid, _mm256_cmp_ps(lo, mid, _CMP_LT_OQ))));
  const unsigned second =
      unsigned(_mm256_movemask_ps(_mm256_and_ps(valid, _mm256_cmp_ps(hi, mid, _CMP_GT_OQ))));
  return spread_even(first) | spread_even(second) << 1;
}

// Lanes 0-7 as all-ones / all-zero 32-bit masks from the low 8 bits.
inline __m256 lane_mask(unsigned bits) {
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  return _mm256_castsi256_ps(
      _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(bits)), lane_bit), lane_bit));
}

// One splat against a group's 8 pixels (centres xs, row centre py), with
// transmittance t and live lanes before it: the 3DGS per-pair arithmetic.
// Every blender path (the row path's blend_group, the lane paths of
// lane_blend.h, forward and backward) takes its decisions from this one
// function, so a backward replays its forward bit for bit.
struct PairStep {
  __m256 raw;     // o exp(-power), before the 0.99 clamp
  __m256 weight;  // alpha * t
  __m256 next;    // t (1 - alpha)
  __m256 blend;   // lanes where the pair blends
  __m256 stop;    // lanes that stop here (transmittance would fall below 1e-4)
};

inline PairStep pair_step(const Splat& g, __m256 xs, float py, __m256 t, __m256 live) {
  const float dy = g.my - py;
  const __m256 dx = _mm256_sub_ps(_mm256_set1_ps(g.mx), xs);
  // power = 0.5 (a dx^2 + c dy^2) + b dx dy
  const __m256 quad =
      _mm256_fmadd_ps(_mm256_mul_ps(_mm256_set1_ps(g.a), dx), dx, _mm256_set1_ps(g.c * dy * dy));
  const __m256 power =
      _mm256_fmadd_ps(_mm256_set1_ps(0.5f), quad, _mm256_mul_ps(_mm256_set1_ps(g.b * dy), dx));
  PairStep p;
  p.raw = _mm256_mul_ps(_mm256_set1_ps(g.opacity),
                        exp_nonpositive(_mm256_sub_ps(_mm256_setzero_ps(), power)));
  const __m256 alpha = _mm256_min_ps(p.raw, _mm256_set1_ps(kMaxAlpha));
  const __m256 keep = _mm256_and_ps(_mm256_cmp_ps(power, _mm256_set1_ps(g.skip_power), _CMP_LE_OQ),
                                    _mm256_cmp_ps(alpha, _mm256_set1_ps(kMinAlpha), _CMP_GE_OQ));
  p.next = _mm256_mul_ps(t, _mm256_sub_ps(_mm256_set1_ps(1.0f), alpha));
  const __m256 low = _mm256_cmp_ps(p.next, _mm256_set1_ps(kMinTransmittance), _CMP_LT_OQ);
  const __m256 pass = _mm256_and_ps(keep, live);
  p.blend = _mm256_andnot_ps(low, pass);
  p.stop = _mm256_and_ps(pass, low);
  p.weight = _mm256_mul_ps(alpha, t);
  return p;
}

// The group's state after the pair.
inline void advance(const PairStep& p, __m256& t, __m256& live) {
  t = _mm256_blendv_ps(t, p.next, p.blend);
  live = _mm256_andnot_ps(p.stop, live);
}

// The group's 8 pixel centres in x, from the first one's.
inline __m256 group_xs(float px0) {
  return _mm256_add_ps(_mm256_set1_ps(px0), _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
}

// Pixels with centres px0 + i (i < 8) in the row with centre py against the
// chunk Gaussians in members (bit k: splats[k]): a pixel blends where it is
// live, alpha >= 1/255 and T stays >= 1e-4; where T would fall below 1e-4 it
// stops instead.
inline void blend_group(const Splat* const* splats, uint64_t members, float px0, float py,
                        GroupState& st, const PairStores& out) {
  const __m256 xs = group_xs(px0);
  __m256 t = _mm256_load_ps(st.T);
  __m256 live = lane_mask(st.live);
  __m256i pm_lo = _mm256_setzero_si256(), pm_hi = _mm256_setzero_si256();
  for (; members; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const PairStep p = pair_step(*splats[k], xs, py, t, live);
    const size_t at = size_t(k) * out.stride;
    _mm256_store_ps(out.weight + at, p.weight);
    if (out.raw) {
      _mm256_store_ps(out.raw + at, p.raw);
      _mm256_store_ps(out.trans + at, t);
    }
    advance(p, t, live);
    const __m256i kbit = _mm256_set1_epi64x(int64_t(uint64_t(1) << k));
    const __m256i b = _mm256_castps_si256(p.blend);
    pm_lo = _mm256_or_si256(
        pm_lo, _mm256_and_si256(kbit, _mm256_cvtepi32_epi64(_mm256_castsi256_si128(b))));
    pm_hi = _mm256_or_si256(
        pm_hi, _mm256_and_si256(kbit, _mm256_cvtepi32_epi64(_mm256_extracti128_si256(b, 1))));
    if (out.gmask)
      out.gmask[k * out.words + out.word] |= uint64_t(unsigned(_mm256_movemask_ps(p.blend)))
                                             << out.shift;
    if (_mm256_movemask_ps(live) == 0) break;
  }
  _mm256_store_ps(st.T, t);
  _mm256_store_si256(reinterpret_cast<__m256i*>(st.pmask), pm_lo);
  _mm256_store_si256(reinterpret_cast<__m256i*>(st.pmask + 4), pm_hi);
  st.live = unsigned(_mm256_movemask_ps(live));
}
#else
inline uint32_t span_groups(const Splat& g, int y, int count, int x0, int x1, float slack) {
  uint32_t bits = 0;
  for (int i = 0; i < count; ++i) {
    const float dy = g.my - (float(y + i) + 0.5f);
    const float hw2 = g.span_k0 - g.span_k1 * dy * dy;
    if (!(hw2 >= 0)) continue;
    const float hw = std::sqrt(hw2) + slack;
    const float centre = g.mx - 0.5f + g.span_k2 * dy;
    const float lo = std::fmin(std::fmax(std::ceil(centre - hw), float(x0)), float(x1));
    const float hi = std::fmin(std::fmax(std::floor(centre + hw) + 1, float(x0)), float(x1));
    if (!(lo < hi)) continue;
    if (lo < float(x0 + kRowLanes)) bits |= 1u << (2 * i);
    if (hi > float(x0 + kRowLanes)) bits |= 2u << (2 * i);
  }
  return bits;
}

inline void blend_group(const Splat* const* splats, uint64_t members, float px0, float py,
                        GroupState& st, const PairStores& out) {
  for (int i = 0; i < 8; ++i) st.pmask[i] = 0;
  for (; members && st.live; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const Splat& g = *splats[k];
    const float dy = g.my - py;
    const size_t at = size_t(k) * out.stride;
    unsigned bits = 0;
    for (int i = 0; i < 8; ++i) {
      const float dx = g.mx - (px0 + float(i));
      const float power = 0.5f * (g.a * dx * dx + g.c * dy * dy) + g.b * dy * dx;
      const float raw = g.opacity * std::exp(-power);
      const float alpha = raw < kMaxAlpha ? raw : kMaxAlpha;
      const float t = st.T[i], next = t * (1.0f - alpha);
      out.weight[at + i] = alpha * t;
      if (out.raw) out.raw[at + i] = raw, out.trans[at + i] = t;
      if (!(st.live >> i & 1) || !(power <= g.skip_power) || !(alpha >= kMinAlpha)) continue;
      if (next < kMinTransmittance) {
        st.live &= ~(1u << i);
        continue;
      }
      bits |= 1u << i;
      st.T[i] = next;
      st.pmask[i] |= uint64_t(1) << k;
    }
    if (out.gmask) out.gmask[k * out.words + out.word] |= uint64_t(bits) << out.shift;
  }
}
#endif

}  // namespace ddhgs::render
