// The blender's lane path for images of at most 8 channels (a latent colour
// model's K channels, RGB): a group's 8 pixels hold their colour sums and
// dL/dpixel channel by channel in vector lanes, so each pair costs C fused
// multiply-adds in registers, with no per-pixel pair lists, row gathers or
// per-pair tables. The backward computes every gradient in its replay pass:
// the per-pixel totals it needs up front come from the forward's image.
// Internal to the render layer; the decisions come from splat_row.h's
// pair_step, as in the row path.
#pragma once
#include <cstdint>
#include <type_traits>

#include "render/pair_grads.h"
#include "render/splat_row.h"

namespace ddhgs::render {

constexpr int kLaneChannels = 8;  // the most channels the lane path takes

// One group's per-pixel inputs to the lane backward (8 pixels each).
struct LaneGroupGrads {
  const float* d_colour;  // [C][8] dL/dpixel, channel-major
  const float* dd;        // dL/d depth image
  const float* tf;        // final transmittance
  const float* dtf;       // dL/d final transmittance
  const double* total;    // sum over the pixel's pairs of g w, plus the background term
  double* prefix;         // running sum of g w over the pairs so far, advanced in place
};

// Lane partial sums of dL/dcolour: [chunk Gaussian][channel][lane].
using ColourLanes = float[kLaneChannels][8];

#if defined(__AVX2__) && defined(__FMA__)
constexpr bool kLanePathBuilt = true;

// Adds the chunk Gaussians in members (bit k: splats[k], colours[k], depth
// order) to one group: acc ([C][8], channel c of lane i at c * 8 + i) and
// dsum ([8]) gain weight * colour and weight * camera z where a pair blends.
// Returns the pairs blended.
template <int C>
inline int lane_forward_group(const Splat* const* splats, const float* const* colours,
                              uint64_t members, float px0, float py, GroupState& st, float* acc,
                              float* dsum) {
  const __m256 xs = group_xs(px0);
  __m256 t = _mm256_load_ps(st.T);
  __m256 live = lane_mask(st.live);
  __m256 a[C];
  for (int c = 0; c < C; ++c) a[c] = _mm256_load_ps(acc + 8 * c);
  __m256 ds = _mm256_load_ps(dsum);
  int pairs = 0;
  for (; members; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const Splat& g = *splats[k];
    const PairStep p = pair_step(g, xs, py, t, live);
    const __m256 w = _mm256_and_ps(p.blend, p.weight);
    const float* colour = colours[k];
    for (int c = 0; c < C; ++c) a[c] = _mm256_fmadd_ps(w, _mm256_set1_ps(colour[c]), a[c]);
    ds = _mm256_fmadd_ps(w, _mm256_set1_ps(g.depth), ds);
    pairs += __builtin_popcount(unsigned(_mm256_movemask_ps(p.blend)));
    advance(p, t, live);
    if (_mm256_movemask_ps(live) == 0) break;
  }
  for (int c = 0; c < C; ++c) _mm256_store_ps(acc + 8 * c, a[c]);
  _mm256_store_ps(dsum, ds);
  _mm256_store_ps(st.T, t);
  st.live = unsigned(_mm256_movemask_ps(live));
  return pairs;
}

// The replay of lane_forward_group with every gradient of its pairs
// (add_pair_grads, as the row path's group_pair_grads), with colour .
// dL/dpixel from the lanes: adds to geo[k] and to
// colour_lanes[k] (w dL/dpixel) for each chunk Gaussian k that blends a
// pixel of the group.
template <int C>
inline void lane_backward_group(const Splat* const* splats, const float* const* colours,
                                uint64_t members, float px0, float py, GroupState& st,
                                const LaneGroupGrads& in, SlotLanes* geo,
                                ColourLanes* colour_lanes) {
  const __m256 xs = group_xs(px0);
  __m256 t = _mm256_load_ps(st.T);
  __m256 live = lane_mask(st.live);
  GroupSums sums = load_group_sums(in.dd, in.tf, in.dtf, in.total, in.prefix);
  for (; members; members &= members - 1) {
    const int k = __builtin_ctzll(members);
    const Splat& sp = *splats[k];
    const PairStep p = pair_step(sp, xs, py, t, live);
    if (_mm256_movemask_ps(p.blend) != 0) {
      const float* colour = colours[k];
      const __m256 won = _mm256_and_ps(p.blend, p.weight);
      __m256 gdot = _mm256_setzero_ps();
      for (int c = 0; c < C; ++c) {
        const __m256 d = _mm256_load_ps(in.d_colour + 8 * c);
        gdot = _mm256_fmadd_ps(_mm256_set1_ps(colour[c]), d, gdot);
        float* lanes = colour_lanes[k][c];
        _mm256_store_ps(lanes, _mm256_fmadd_ps(won, d, _mm256_load_ps(lanes)));
      }
      add_pair_grads(sp, p.blend, p.weight, p.raw, t, gdot, xs, py, sums, &geo[k][0][0]);
    }
    advance(p, t, live);
    if (_mm256_movemask_ps(live) == 0) break;
  }
  store_prefix(sums, in.prefix);
  _mm256_store_ps(st.T, t);
  st.live = unsigned(_mm256_movemask_ps(live));
}

// Calls f(std::integral_constant<int, C>) for C = channels (1-8).
template <class F>
inline void with_lane_channels(int channels, F&& f) {
  switch (channels) {
    case 1:
      return f(std::integral_constant<int, 1>());
    case 2:
      return f(std::integral_constant<int, 2>());
    case 3:
      return f(std::integral_constant<int, 3>());
    case 4:
      return f(std::integral_constant<int, 4>());
    case 5:
      return f(std::integral_constant<int, 5>());
    case 6:
      return f(std::integral_constant<int, 6>());
    case 7:
      return f(std::integral_constant<int, 7>());
    default:
      return f(std::integral_constant<int, 8>());
  }
}
#else
constexpr bool kLanePathBuilt = false;
#endif

}  // namespace ddhgs::render
