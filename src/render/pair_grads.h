// The backward's per-pair geometry gradients (means2d, conic, opacity,
// depth) for one 8-pixel group of a tile, vectorised over the group's
// pixels: the chunk Gaussians that blend any of them are walked in depth
// order, as the forward blended them, while the pixels' running prefix sums
// advance lane by lane. Internal to the render layer; blend.cpp's backward
// calls it after the blend replay (blend_chunk) and the colour dot products.
#pragma once
#include <cstdint>

#include "render/splat_row.h"

namespace ddhgs::render {

// Per-Gaussian gradient slots accumulated by the blender.
enum Slot { kMx, kMy, kConA, kConB, kConC, kOpacity, kDepth, kSlots = 8 };

// One group's per-pair tables and per-pixel sums. Tables hold chunk Gaussian
// k's 8 values at base + k * stride (the group's lanes); the per-pixel
// arrays hold the group's 8 pixels.
struct GroupPairs {
  const float* weight;     // alpha * T before the pair
  const float* raw;        // o exp(-power) before the 0.99 clamp
  const float* trans;      // T before the pair
  const float* gdot;       // colour . dL/dpixel
  int stride;              // floats between chunk Gaussians in the tables
  const uint64_t* gmask;   // [64][words]: pixels each chunk Gaussian blends
  int words, word, shift;  // gmask row length, the group's word and bit offset
  const float* dd;         // [8] dL/d depth image
  const float* tf;         // [8] final transmittance
  const float* dtf;        // [8] dL/d final transmittance
  const double* total;     // [8] sum over the pixel's pairs of g w, plus the background term
  double* prefix;          // [8] running sum of g w over the pairs so far, advanced in place
  float px0, py;           // centres of the group's first pixel (x) and row (y)
};

// Lane partial sums of the gradient slots: [chunk Gaussian][slot][lane].
using SlotLanes = float[kSlots][kRowLanes];

// Adds the group's pair gradients of the chunk Gaussians in members (bit k:
// splats[k], depth order) to geo[k]. Per pair j of pixel p, with g = colour
// . dL/dpixel + depth dL/dD and suffix = total - prefix (prefix including
// j): dL/dalpha = T g - (suffix + dL/dT_final T_final) / (1 - alpha); where
// the forward clamped alpha to 0.99 only the depth slot gets a gradient. The
// opacity slot holds sum dL/dalpha * raw (divided by o once per Gaussian by
// the caller).
inline void group_pair_grads(const Splat* const* splats, uint64_t members, const GroupPairs& in,
                             SlotLanes* geo);

#if defined(__AVX2__) && defined(__FMA__)
// A group's per-pixel values as its pair loop holds them in registers:
// dL/dD, dL/dT_final * T_final, the totals and the running prefix.
struct GroupSums {
  __m256 dd, tail;
  __m256d total_lo, total_hi, prefix_lo, prefix_hi;
};

inline GroupSums load_group_sums(const float* dd, const float* tf, const float* dtf,
                                 const double* total, const double* prefix) {
  return {_mm256_loadu_ps(dd),     _mm256_mul_ps(_mm256_loadu_ps(dtf), _mm256_loadu_ps(tf)),
          _mm256_loadu_pd(total),  _mm256_loadu_pd(total + 4),
          _mm256_loadu_pd(prefix), _mm256_loadu_pd(prefix + 4)};
}

inline void store_prefix(const GroupSums& s, double* prefix) {
  _mm256_storeu_pd(prefix, s.prefix_lo);
  _mm256_storeu_pd(prefix + 4, s.prefix_hi);
}

// One pair's gradients (the formula above) for the group's lanes: on, the
// lanes where it blends; w = alpha T, raw and t (T before it) from its
// pair_step; gdot = colour . dL/dpixel. Adds to slots (the Gaussian's
// SlotLanes) and advances the prefix. The row path's group_pair_grads and
// the lane path's lane_backward_group share it.
inline void add_pair_grads(const Splat& sp, __m256 on, __m256 w, __m256 raw, __m256 t, __m256 gdot,
                           __m256 xs, float py, GroupSums& s, float* slots) {
  const __m256 one = _mm256_set1_ps(1.0f), max_alpha = _mm256_set1_ps(kMaxAlpha);
  // Pixels the pair does not blend get g = 0: nothing reaches the prefix.
  const __m256 g = _mm256_and_ps(on, _mm256_fmadd_ps(_mm256_set1_ps(sp.depth), s.dd, gdot));
  auto add = [&](int slot, __m256 v) {
    float* dst = slots + slot * kRowLanes;
    _mm256_store_ps(dst, _mm256_add_ps(_mm256_load_ps(dst), v));
  };
  add(kDepth, _mm256_and_ps(on, _mm256_mul_ps(w, s.dd)));
  s.prefix_lo = _mm256_fmadd_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(g)),
                                _mm256_cvtps_pd(_mm256_castps256_ps128(w)), s.prefix_lo);
  s.prefix_hi = _mm256_fmadd_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(g, 1)),
                                _mm256_cvtps_pd(_mm256_extractf128_ps(w, 1)), s.prefix_hi);
  const __m256 suffix = _mm256_set_m128(_mm256_cvtpd_ps(_mm256_sub_pd(s.total_hi, s.prefix_hi)),
                                        _mm256_cvtpd_ps(_mm256_sub_pd(s.total_lo, s.prefix_lo)));
  const __m256 alpha = _mm256_min_ps(raw, max_alpha);
  const __m256 d_alpha = _mm256_sub_ps(
      _mm256_mul_ps(t, g), _mm256_div_ps(_mm256_add_ps(suffix, s.tail), _mm256_sub_ps(one, alpha)));
  // Clamped pairs (raw > 0.99) pass no gradient to the opacity or power.
  const __m256 open = _mm256_and_ps(on, _mm256_cmp_ps(raw, max_alpha, _CMP_NGT_UQ));
  const __m256 d_alpha_raw = _mm256_and_ps(open, _mm256_mul_ps(d_alpha, raw));
  const __m256 dx = _mm256_sub_ps(_mm256_set1_ps(sp.mx), xs);
  const __m256 dy = _mm256_set1_ps(sp.my - py);
  const __m256 d_power = _mm256_sub_ps(_mm256_setzero_ps(), d_alpha_raw);
  add(kOpacity, d_alpha_raw);
  add(kMx, _mm256_mul_ps(d_power, _mm256_fmadd_ps(_mm256_set1_ps(sp.a), dx,
                                                  _mm256_mul_ps(_mm256_set1_ps(sp.b), dy))));
  add(kMy, _mm256_mul_ps(d_power, _mm256_fmadd_ps(_mm256_set1_ps(sp.b), dx,
                                                  _mm256_mul_ps(_mm256_set1_ps(sp.c), dy))));
  const __m256 half_power = _mm256_mul_ps(_mm256_set1_ps(0.5f), d_power);
  add(kConA, _mm256_mul_ps(_mm256_mul_ps(half_power, dx), dx));
  add(kConB, _mm256_mul_ps(_mm256_mul_ps(d_power, dx), dy));
  add(kConC, _mm256_mul_ps(_mm256_mul_ps(half_power, dy), dy));
}

inline void group_pair_grads(const Splat* const* splats, uint64_t members, const GroupPairs& in,
                             SlotLanes* geo) {
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  const __m256 xs = group_xs(in.px0);
  GroupSums sums = load_group_sums(in.dd, in.tf, in.dtf, in.total, in.prefix);
  for (; members; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const unsigned lanes = unsigned(in.gmask[k * in.words + in.word] >> in.shift) & 0xffu;
    if (lanes == 0) continue;
    const __m256 on = _mm256_castsi256_ps(
        _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(int(lanes)), lane_bit), lane_bit));
    const size_t at = size_t(k) * in.stride;
    add_pair_grads(*splats[k], on, _mm256_load_ps(in.weight + at), _mm256_load_ps(in.raw + at),
                   _mm256_load_ps(in.trans + at), _mm256_load_ps(in.gdot + at), xs, in.py, sums,
                   &geo[k][0][0]);
  }
  store_prefix(sums, in.prefix);
}
#else
inline void group_pair_grads(const Splat* const* splats, uint64_t members, const GroupPairs& in,
                             SlotLanes* geo) {
  for (; members; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const unsigned lanes = unsigned(in.gmask[k * in.words + in.word] >> in.shift) & 0xffu;
    const Splat& sp = *splats[k];
    const size_t at = size_t(k) * in.stride;
    for (int i = 0; i < kRowLanes; ++i) {
      if (!(lanes >> i & 1)) continue;
      const float w = in.weight[at + i], raw = in.raw[at + i], t = in.trans[at + i];
      const float g = in.gdot[at + i] + sp.depth * in.dd[i];
      geo[k][kDepth][i] += w * in.dd[i];
      in.prefix[i] += double(g) * w;
      const float suffix = float(in.total[i] - in.prefix[i]);
      const float alpha = raw < kMaxAlpha ? raw : kMaxAlpha;
      const float d_alpha = t * g - (suffix + in.dtf[i] * in.tf[i]) / (1.0f - alpha);
      if (raw > kMaxAlpha) continue;
      const float dx = sp.mx - (in.px0 + float(i)), dy = sp.my - in.py;
      const float d_power = -d_alpha * raw;
      geo[k][kOpacity][i] += d_alpha * raw;
      geo[k][kMx][i] += d_power * (sp.a * dx + sp.b * dy);
      geo[k][kMy][i] += d_power * (sp.b * dx + sp.c * dy);
      geo[k][kConA][i] += 0.5f * d_power * dx * dx;
      geo[k][kConB][i] += d_power * dx * dy;
      geo[k][kConC][i] += 0.5f * d_power * dy * dy;
    }
  }
}
#endif

}  // namespace ddhgs::render
