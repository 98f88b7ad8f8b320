#include "render/blend.h"

#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#include "core/parallel.h"
#include "render/aligned.h"
#include "render/channel_kernels.h"
#include "render/lane_blend.h"
#include "render/pair_grads.h"
#include "render/ranked.h"
#include "render/recycle.h"
#include "render/splat_row.h"

namespace ddhgs::render {
namespace {

#if defined(__AVX512F__)
std::atomic<bool> wide_on{true};
bool wide() {
  return wide_on.load(std::memory_order_relaxed);
}
#else
bool wide() {
  return false;
}
#endif

std::atomic<bool> lanes_allowed{true};
// Whether an image of n channels takes the lane path (lane_blend.h).
bool lanes_on(int64_t n) {
  return kLanePathBuilt && n >= 1 && n <= kLaneChannels &&
         lanes_allowed.load(std::memory_order_relaxed);
}

constexpr int kPixels = kTileSize * kTileSize;
constexpr int kChunk = 64;  // Gaussians per chunk: one bit each in a 64-bit pixel mask
constexpr int kGroupsPerRow = kTileSize / kRowLanes;
constexpr int kGroups = kPixels / kRowLanes;  // 8-pixel groups of a tile, row-major

// Per-thread scratch for one tile; thread_local in the OpenMP workers, so it
// is allocated once and reused by every later call. Per-pair values of a
// chunk are stored densely, [Gaussian][pixel], as whole 8-pixel groups (no
// per-pair scalar work while blending); bit masks say which entries are real.
struct TileScratch {
  int x0, y0, x1, y1, ndone, npix;
  alignas(32) float T[kPixels];
  alignas(32) uint64_t pmask[kPixels];         // bit k: chunk Gaussian k blends pixel p
  alignas(32) float weight[kChunk * kPixels];  // alpha * T
  alignas(32) float raw[kChunk * kPixels];     // backward: o exp(-power) before the 0.99 clamp
  alignas(32) float trans[kChunk * kPixels];   // backward: T before the pair
  alignas(32) float gdot[kChunk * kPixels];    // backward: colour . dL/dpixel of the pair
  alignas(32) SlotLanes geo[kChunk];           // backward: gradient slots, lane partial sums
  uint64_t gmask[kChunk][kPixels / 64];        // backward: pixels each chunk Gaussian blends
  uint8_t live[kGroups];                       // per group: lanes not stopped and inside the image
  const float* col_rows[kChunk];               // colour row of each chunk Gaussian
  float depth[kChunk];                         // camera z of each chunk Gaussian
  const float* pix_rows[kPixels];              // row of acc for each pixel
  AlignedVector<float> acc;  // [kPixels, np] colour sums (forward) or dL/dimage (backward)
  uint8_t touched[kPixels];  // forward: acc row holds a sum (rows are not zeroed up front)
  // The lane path (lane_blend.h): per group, channel-major [group][channel][lane],
  // the colour sums (forward) or dL/dpixel (backward); the depth sums; the
  // backward's dL/dcolour lane sums per chunk Gaussian.
  alignas(32) float lanes[kGroups * kLaneChannels * kRowLanes];
  alignas(32) float lane_depth[kPixels];
  alignas(32) ColourLanes colour_lanes[kChunk];

  void start(const TileBins& bins, int tile, int width, int height, int np) {
    x0 = (tile % bins.tiles_x) * kTileSize, y0 = (tile / bins.tiles_x) * kTileSize;
    x1 = std::min(width, x0 + kTileSize), y1 = std::min(height, y0 + kTileSize);
    npix = (x1 - x0) * (y1 - y0);
    ndone = 0;
    std::fill(T, T + kPixels, 1.0f);
    for (int g = 0; g < kGroups; ++g) {
      const int y = y0 + g / kGroupsPerRow, x = x0 + g % kGroupsPerRow * kRowLanes;
      const int lanes = y < y1 ? std::clamp(x1 - x, 0, kRowLanes) : 0;
      live[g] = uint8_t((1u << lanes) - 1);
    }
    acc.resize(size_t(kPixels) * np);
    std::fill(touched, touched + kPixels, uint8_t(0));
    for (int p = 0; p < kPixels; ++p) pix_rows[p] = acc.data() + size_t(p) * np;
  }
  int pixel(int x, int y) const { return (y - y0) * kTileSize + x - x0; }
};

// Tile lists jump through the rank-ordered arrays (a tile holds a small
// fraction of all Gaussians), so splat records are requested a fixed distance
// ahead of their use, and the head of the next tile's list while the current
// tile is blended. Colour rows are requested only for Gaussians that blend at
// least one pixel (see blend_chunk): most of a tile's list misses its pixels,
// and prefetching every row stalls on fill buffers.
constexpr int kSplatLookahead = 32;  // Gaussians

// Pixels added to each side of a row span. The span's float rounding and that
// of the per-pixel dx are ~1e-4 px at 640 px wide images; the 1e-3 of power
// margin already covers most of it.
constexpr float kSpanSlack = 1.0f / 16;

void prefetch_tile_head(const Ranked& ranked, const TileBins& bins, int tile) {
  const int32_t begin = bins.offsets[tile];
  const int32_t end = std::min(bins.offsets[tile + 1], begin + kSplatLookahead);
  for (int32_t b = begin; b < end; ++b) __builtin_prefetch(&ranked.splats[bins.ranks[b]]);
}

void prefetch_row(const float* row, int np) {
  constexpr int kLineFloats = 16;  // 64-byte cache lines
  for (int c = 0; c < np; c += kLineFloats) __builtin_prefetch(row + c);
}

TileScratch& scratch() {
  // On the heap: a ~300 KB thread_local object would be reserved in the
  // static TLS of every thread of the process, not just the render workers.
  thread_local std::unique_ptr<TileScratch> s;
  if (!s) s = std::make_unique<TileScratch>();
  return *s;
}

int clip(float v, int lo, int hi) {
  return v < float(lo) ? lo : v > float(hi) ? hi : int(v);
}

// The chunk's splats and, per 8-pixel group, the chunk Gaussians whose
// ellipse may reach it (bit k of members[group]), from each splat's row
// spans (span_groups); colour rows (and the backward's colour gradient rows
// grad_rows, [V, np] in rank order, may be null) of the splats that reach a
// group are prefetched. ranks[0, remaining) are valid (the rest of the
// tile's list), ranks[0, m) form this chunk.
void chunk_members(TileScratch& s, const Ranked& ranked, const int32_t* ranks, int m, int remaining,
                   int np, const float* grad_rows, uint64_t* members, const Splat** splats) {
  std::fill(members, members + kGroups, uint64_t(0));
  for (int k = 0; k < m; ++k) {
    if (k + kSplatLookahead < remaining)
      __builtin_prefetch(&ranked.splats[ranks[k + kSplatLookahead]]);
    const Splat& g = ranked.splats[ranks[k]];
    splats[k] = &g;
    s.col_rows[k] = ranked.row(ranks[k], np);
    s.depth[k] = g.depth;
    if (g.ext_x < 0) continue;
    // Pixel y has its centre at y + 0.5.
    const int ya = clip(std::floor(g.my - g.ext_y - 0.5f), s.y0, s.y1);
    const int yb = clip(std::ceil(g.my + g.ext_y - 0.5f) + 1, s.y0, s.y1);
    uint64_t groups = 0;  // bit 2 r + h: tile row r, half h
    for (int y = ya; y < yb; y += kRowLanes)
      groups |= uint64_t(span_groups(g, y, std::min(kRowLanes, yb - y), s.x0, s.x1, kSpanSlack))
                << (2 * (y - s.y0));
    const uint64_t kbit = uint64_t(1) << k;
    for (uint64_t bits = groups; bits; bits &= bits - 1) members[__builtin_ctzll(bits)] |= kbit;
    if (groups) {
      prefetch_row(s.col_rows[k], np);
      if (grad_rows) prefetch_row(grad_rows + size_t(ranks[k]) * np, np);
    }
  }
}

// Centres of group gr's first pixel (x) and row (y).
float group_x(const TileScratch& s, int gr) {
  return float(s.x0 + gr % kGroupsPerRow * kRowLanes) + 0.5f;
}
float group_y(const TileScratch& s, int gr) {
  return float(s.y0 + gr / kGroupsPerRow) + 0.5f;
}

// A chunk of a tile's depth list: its ranks and, from chunk_members, its
// splats and the groups they may reach.
struct Chunk {
  const int32_t* ranks;  // [m] depth ranks
  int m;
  uint64_t members[kGroups];
  const Splat* splats[kChunk];
};

// Calls f(chunk) for each chunk of the (started) tile's depth list, front to
// back, until every pixel of the tile has stopped. grad_rows as in
// chunk_members.
template <class F>
void each_chunk(TileScratch& s, const Ranked& ranked, const TileBins& bins, int tile, int np,
                const float* grad_rows, F&& f) {
  const int32_t end = bins.offsets[tile + 1];
  for (int32_t b = bins.offsets[tile]; b < end && s.ndone < s.npix; b += kChunk) {
    Chunk c;
    c.ranks = bins.ranks.data() + b;
    c.m = std::min<int32_t>(kChunk, end - b);
    chunk_members(s, ranked, c.ranks, c.m, end - b, np, grad_rows, c.members, c.splats);
    f(c);
  }
}

// Updates the tile's stopped-pixel count and live lanes of group gr after a
// pass over it left st.
void book_group(TileScratch& s, int gr, const GroupState& st) {
  s.ndone += __builtin_popcount(s.live[gr] & ~st.live);
  s.live[gr] = uint8_t(st.live);
}

// The row path's per-pixel recurrence for one chunk: each group runs through
// its splats in depth order (blend_group). One function for forward and
// backward, so the backward replays exactly the same float operations.
void blend_chunk(TileScratch& s, const Chunk& c, bool backward) {
  if (backward) std::memset(s.gmask, 0, sizeof s.gmask);
  for (int gr = 0; gr < kGroups; ++gr) {
    const int p = gr * kRowLanes;
    if (c.members[gr] == 0 || s.live[gr] == 0) {
      std::fill(s.pmask + p, s.pmask + p + kRowLanes, uint64_t(0));
      continue;
    }
    GroupState st{s.T + p, s.live[gr], s.pmask + p};
    const PairStores out{s.weight + p,
                         backward ? s.raw + p : nullptr,
                         s.trans + p,
                         kPixels,
                         backward ? &s.gmask[0][0] : nullptr,
                         kPixels / 64,
                         p / 64,
                         p % 64};
    blend_group(c.splats, c.members[gr], group_x(s, gr), group_y(s, gr), st, out);
    book_group(s, gr, st);
  }
}

// Adds chunk Gaussian k's lane partial sums of the gradient slots to its
// rank's row of ggeo ([V, kSlots]).
void add_geo(const TileScratch& s, const Ranked& ranked, const int32_t* ranks, int k, float* ggeo) {
  float geo[kSlots];
  for (int q = 0; q < kSlots; ++q) {
    float sum = 0;
    for (int i = 0; i < kRowLanes; ++i) sum += s.geo[k][q][i];
    geo[q] = sum;
  }
  // d alpha / d o = exp(-power) = raw / o; Gaussians without pairs
  // (possibly o = 0) keep their zero.
  if (geo[kOpacity] != 0) geo[kOpacity] /= ranked.splats[ranks[k]].opacity;
  for (int q = 0; q < kSlots; ++q) ggeo[int64_t(ranks[k]) * kSlots + q] += geo[q];
}

#if defined(__AVX2__) && defined(__FMA__)
// The lane path's forward of one tile (started): colour and depth sums in
// s.lanes and s.lane_depth; returns the pairs blended.
template <int C>
int64_t lane_forward_tile(TileScratch& s, const Ranked& ranked, const TileBins& bins, int tile,
                          int np) {
  std::fill(s.lanes, s.lanes + kGroups * C * kRowLanes, 0.0f);
  std::fill(s.lane_depth, s.lane_depth + kPixels, 0.0f);
  int64_t pairs = 0;
  each_chunk(s, ranked, bins, tile, np, nullptr, [&](const Chunk& c) {
    for (int gr = 0; gr < kGroups; ++gr) {
      if (c.members[gr] == 0 || s.live[gr] == 0) continue;
      const int p = gr * kRowLanes;
      GroupState st{s.T + p, s.live[gr], nullptr};
      pairs +=
          lane_forward_group<C>(c.splats, s.col_rows, c.members[gr], group_x(s, gr), group_y(s, gr),
                                st, s.lanes + gr * C * kRowLanes, s.lane_depth + p);
      book_group(s, gr, st);
    }
  });
  return pairs;
}

// The lane path's backward of one tile (started, s.lanes holding dL/dpixel):
// every gradient in the replay pass, into gcol ([V, np]) and ggeo ([V,
// kSlots]) in rank order.
template <int C>
void lane_backward_tile(TileScratch& s, const Ranked& ranked, const TileBins& bins, int tile,
                        int np, const float* dd, const float* tf, const float* dtf,
                        const double* total, double* prefix, float* gcol, float* ggeo) {
  each_chunk(s, ranked, bins, tile, np, gcol, [&](const Chunk& c) {
    std::memset(s.geo, 0, sizeof(SlotLanes) * size_t(c.m));
    std::memset(s.colour_lanes, 0, sizeof(ColourLanes) * size_t(c.m));
    for (int gr = 0; gr < kGroups; ++gr) {
      if (c.members[gr] == 0 || s.live[gr] == 0) continue;
      const int p = gr * kRowLanes;
      GroupState st{s.T + p, s.live[gr], nullptr};
      const LaneGroupGrads in{
          s.lanes + gr * C * kRowLanes, dd + p, tf + p, dtf + p, total + p, prefix + p};
      lane_backward_group<C>(c.splats, s.col_rows, c.members[gr], group_x(s, gr), group_y(s, gr),
                             st, in, s.geo, s.colour_lanes);
      book_group(s, gr, st);
    }
    for (int k = 0; k < c.m; ++k) {
      add_geo(s, ranked, c.ranks, k, ggeo);
      float* row = gcol + int64_t(c.ranks[k]) * np;
      for (int ch = 0; ch < C; ++ch) {
        float sum = 0;
        for (int i = 0; i < kRowLanes; ++i) sum += s.colour_lanes[k][ch][i];
        row[ch] += sum;
      }
    }
  });
}
#endif

// The chunk Gaussians that blend pixel p, in depth order.
int pixel_gaussians(const TileScratch& s, int p, uint8_t* gauss) {
  int c = 0;
  for (uint64_t bits = s.pmask[p]; bits; bits &= bits - 1)
    gauss[c++] = uint8_t(__builtin_ctzll(bits));
  return c;
}

// Sum over the set bits k of bits of weight[k * kPixels] * depth[k], with two
// independent partial sums instead of one dependent chain of adds.
float depth_sum(uint64_t bits, const float* weight, const float* depth) {
  float part0 = 0, part1 = 0;
  while (bits) {
    int k = __builtin_ctzll(bits);
    part0 += weight[k * kPixels] * depth[k];
    bits &= bits - 1;
    if (!bits) break;
    k = __builtin_ctzll(bits);
    part1 += weight[k * kPixels] * depth[k];
    bits &= bits - 1;
  }
  return part0 + part1;
}

// Calls f(k, w) for each chunk Gaussian k (of m) that blends pixels of
// quarter w of the tile (64 pixels, mask word w), quarter by quarter: a
// quarter's dL/dpixel rows (64 x 576 bytes at 141 bands) stay in the 48 KB
// L1 cache while every Gaussian of the chunk passes over them; walking the
// whole tile per Gaussian read them from L2 each time (9 % more backward
// time, measured with the 512-bit loops; 5 % with the 256-bit ones).
template <class F>
void each_quarter_gaussian(const TileScratch& s, int m, F&& f) {
  for (int w = 0; w < kPixels / 64; ++w)
    for (int k = 0; k < m; ++k)
      if (s.gmask[k][w] != 0) f(k, w);
}

// The backward's two colour terms of a chunk: dL/dcolours = W^T dL/dimage
// into gcol ([V, np] in rank order) and each pair's colour . dL/dpixel into
// the [k][p] table s.gdot. Two passes: Gaussian-major for the first, with
// register accumulators, and pixel-major for the second.
void colour_terms(TileScratch& s, const int32_t* ranks, int m, int np, float* gcol) {
  each_quarter_gaussian(s, m, [&](int k, int w) {
    const int p0 = 64 * w;
    kernels::mask_axpy(gcol + int64_t(ranks[k]) * np, s.pix_rows + p0, np, &s.gmask[k][w], 1,
                       s.weight + k * kPixels + p0, 1);
  });
  for (int p = 0; p < kPixels; ++p) {
    if (s.pmask[p] == 0) continue;
    uint8_t gauss[kChunk];
    const int c = pixel_gaussians(s, p, gauss);
    float gdot[kChunk] = {};
    kernels::gather_dot(s.pix_rows[p], s.col_rows, np, gauss, c, gdot);
    for (int j = 0; j < c; ++j) s.gdot[gauss[j] * kPixels + p] = gdot[j];
  }
}

#if defined(__AVX512F__)
// colour_terms in one Gaussian-major pass of 512-bit vectors: each
// Gaussian's colour row and gradient accumulators stay in registers while
// its pixels' dL/dpixel rows stream past, each loaded once for both terms.
void wide_colour_terms(TileScratch& s, const int32_t* ranks, int m, int np, float* gcol) {
  each_quarter_gaussian(s, m, [&](int k, int w) {
    const int p0 = 64 * w;
    kernels::wide_colour_grads(gcol + int64_t(ranks[k]) * np, s.col_rows[k], s.pix_rows + p0, np,
                               &s.gmask[k][w], 1, s.weight + k * kPixels + p0,
                               s.gdot + k * kPixels + p0);
  });
}
#endif

}  // namespace

bool wide_kernels_built() {
#if defined(__AVX512F__)
  return true;
#else
  return false;
#endif
}

bool lane_path_built() {
  return kLanePathBuilt;
}

void set_lane_path(bool on) {
  lanes_allowed.store(on, std::memory_order_relaxed);
}

void set_wide_kernels([[maybe_unused]] bool on) {
#if defined(__AVX512F__)
  wide_on.store(on, std::memory_order_relaxed);
#endif
}

BlendForward blend_forward(const Projected& projected, const torch::Tensor& colors,
                           const torch::Tensor& background, const TileBins& bins, int width,
                           int height, bool keep_final_T) {
  const int64_t n = colors.size(1);
  const int np = kernels::padded_channels(n);
  BlendForward out;
  thread_local c10::Storage image_cache;
  out.image = recycled_empty(image_cache, {height, width, n});
  out.alpha = torch::empty({height, width}, torch::kFloat32);
  out.depth = torch::empty({height, width}, torch::kFloat32);
  if (keep_final_T) out.final_T = torch::empty({height, width}, torch::kFloat32);
  const Ranked& ranked = rank_gaussians(projected, colors, bins, np);
  const float* bg = background.data_ptr<float>();
  float* img = out.image.data_ptr<float>();
  float* alpha = out.alpha.data_ptr<float>();
  float* depth = out.depth.data_ptr<float>();
  float* final_T = keep_final_T ? out.final_T.data_ptr<float>() : nullptr;
  const int lists = int(bins.thread_tiles.size());
  [[maybe_unused]] const bool use_wide = wide();
  [[maybe_unused]] const bool lane_path = lanes_on(n);

  std::atomic<int64_t> total_pairs{0};
  // One chunk per tile list: any thread may run any list.
  core::parallel_for(0, lists, 1, [&](int64_t list_begin, int64_t list_end) {
    for (int64_t list = list_begin; list < list_end; ++list) {
      int64_t pairs = 0;
      TileScratch& s = scratch();
      const std::vector<int32_t>& tiles = bins.thread_tiles[list];
      for (size_t i = 0; i < tiles.size(); ++i) {
        const int tile = tiles[i];
        if (i + 1 < tiles.size()) prefetch_tile_head(ranked, bins, tiles[i + 1]);
        s.start(bins, tile, width, height, np);
#if defined(__AVX2__) && defined(__FMA__)
        if (lane_path) {
          with_lane_channels(int(n), [&](auto channels) {
            constexpr int C = decltype(channels)::value;
            pairs += lane_forward_tile<C>(s, ranked, bins, tile, np);
            for (int y = s.y0; y < s.y1; ++y)
              for (int x = s.x0; x < s.x1; ++x) {
                const int p = s.pixel(x, y);
                const int64_t o = int64_t(y) * width + x;
                const float* sums = s.lanes + p / kRowLanes * C * kRowLanes + p % kRowLanes;
                alignas(32) float row[kLaneChannels];
                for (int c = 0; c < C; ++c) row[c] = sums[c * kRowLanes];
                const float t = s.T[p];
                kernels::write_pixel(img + o * n, row, t, bg, n);
                alpha[o] = 1.0f - t;
                depth[o] = s.lane_depth[p];
                if (final_T) final_T[o] = t;
              }
          });
          continue;
        }
#endif
        float dsum[kPixels] = {};
        each_chunk(s, ranked, bins, tile, np, nullptr, [&](const Chunk& c) {
          blend_chunk(s, c, false);
          for (int p = 0; p < kPixels; ++p) {
            const uint64_t bits = s.pmask[p];
            if (bits == 0) continue;
            pairs += __builtin_popcountll(bits);
#if defined(__AVX512F__)
            if (use_wide)
              kernels::wide_mask_axpy(s.acc.data() + size_t(p) * np, s.col_rows, np, &bits, 1,
                                      s.weight + p, kPixels, s.touched[p]);
            else
#endif
              kernels::mask_axpy(s.acc.data() + size_t(p) * np, s.col_rows, np, &bits, 1,
                                 s.weight + p, kPixels, s.touched[p]);
            s.touched[p] = 1;
            dsum[p] += depth_sum(bits, s.weight + p, s.depth);
          }
        });
        for (int y = s.y0; y < s.y1; ++y)
          for (int x = s.x0; x < s.x1; ++x) {
            const int p = s.pixel(x, y);
            const int64_t o = int64_t(y) * width + x;
            float* dst = img + o * n;
            const float t = s.T[p];
            kernels::write_pixel(dst, s.touched[p] ? s.pix_rows[p] : nullptr, t, bg, n);
            alpha[o] = 1.0f - t;
            depth[o] = dsum[p];
            if (final_T) final_T[o] = t;
          }
      }
      kernels::end_streaming_writes();
      total_pairs += pairs;
    }
  });
  out.pairs = total_pairs;
  return out;
}

BlendGrads blend_backward(const Projected& projected, const torch::Tensor& colors,
                          const torch::Tensor& background, const TileBins& bins, int width,
                          int height, const BlendForward& fwd, const torch::Tensor& d_image,
                          const torch::Tensor& d_alpha, const torch::Tensor& d_depth) {
  const int64_t count = colors.size(0), n = colors.size(1);
  const int np = kernels::padded_channels(n);
  const int lists = int(bins.thread_tiles.size());
  const int64_t visible = int64_t(bins.order.size());
  const Ranked& ranked = rank_gaussians(projected, colors, bins, np);
  // One gradient buffer set per tile list, in rank order; they are summed in
  // list order at the end, so results do not depend on OS scheduling.
  thread_local std::vector<AlignedVector<float>> col_bufs;
  thread_local std::vector<std::vector<float>> geo_bufs, bg_bufs;
  col_bufs.resize(lists), geo_bufs.resize(lists), bg_bufs.resize(lists);
  std::vector<float*> col_buf(lists), geo_buf(lists), bg_buf(lists);
  for (int l = 0; l < lists; ++l) {
    col_bufs[l].resize(size_t(visible) * np);
    geo_bufs[l].resize(size_t(visible) * kSlots);
    bg_bufs[l].resize(size_t(n));
    col_buf[l] = col_bufs[l].data(), geo_buf[l] = geo_bufs[l].data(), bg_buf[l] = bg_bufs[l].data();
  }
  const float* bg = background.data_ptr<float>();
  const float* dimg = d_image.data_ptr<float>();
  const float* dalpha = d_alpha.defined() ? d_alpha.data_ptr<float>() : nullptr;
  const float* ddepth = d_depth.defined() ? d_depth.data_ptr<float>() : nullptr;
  const float* img = fwd.image.data_ptr<float>();
  const float* dep = fwd.depth.data_ptr<float>();
  const float* final_T = fwd.final_T.data_ptr<float>();
  [[maybe_unused]] const bool use_wide = wide();
  [[maybe_unused]] const bool lane_path = lanes_on(n);

  core::parallel_for(0, lists, 1, [&](int64_t list_begin, int64_t list_end) {
    for (int64_t list = list_begin; list < list_end; ++list) {
      TileScratch& s = scratch();
      float* gcol = col_buf[list];
      float* ggeo = geo_buf[list];
      float* gbg = bg_buf[list];
      std::fill(gcol, gcol + visible * np, 0.0f);
      std::fill(ggeo, ggeo + visible * kSlots, 0.0f);
      std::fill(gbg, gbg + n, 0.0f);
      const std::vector<int32_t>& tiles = bins.thread_tiles[list];
      for (size_t i = 0; i < tiles.size(); ++i) {
        const int tile = tiles[i];
        if (i + 1 < tiles.size()) prefetch_tile_head(ranked, bins, tiles[i + 1]);
        s.start(bins, tile, width, height, np);
        // Per pixel: dL/dD, final T, dL/dT_final and the total sum_j g_j w_j,
        // so the suffix sum each pair needs is total - prefix (no reverse pass).
        alignas(32) float dd[kPixels] = {}, tf[kPixels] = {}, dtf[kPixels] = {};
        alignas(32) double total[kPixels] = {}, prefix[kPixels] = {};
        if (lane_path) std::fill(s.lanes, s.lanes + kGroups * n * kRowLanes, 0.0f);
        for (int y = s.y0; y < s.y1; ++y)
          for (int x = s.x0; x < s.x1; ++x) {
            const int p = s.pixel(x, y);
            const int64_t o = int64_t(y) * width + x;
            const float* dc = dimg + o * n;
            if (lane_path) {
              // Channel-major per group; lanes outside the image stay zero.
              float* lanes = s.lanes + p / kRowLanes * n * kRowLanes + p % kRowLanes;
              for (int64_t c = 0; c < n; ++c) lanes[c * kRowLanes] = dc[c];
            } else {
              float* row = s.acc.data() + size_t(p) * np;
              std::copy(dc, dc + n, row);
              std::fill(row + n, row + np, 0.0f);  // padding meets zero colour padding
            }
            tf[p] = final_T[o];
            dd[p] = ddepth ? ddepth[o] : 0.0f;
            const kernels::PixelSums sums = kernels::pixel_sums(dc, img + o * n, tf[p], bg, n, gbg);
            total[p] = double(dd[p]) * dep[o] + sums.dot_image;
            dtf[p] = float((dalpha ? -double(dalpha[o]) : 0.0) + sums.dot_background);
          }
#if defined(__AVX2__) && defined(__FMA__)
        if (lane_path) {
          with_lane_channels(int(n), [&](auto channels) {
            lane_backward_tile<decltype(channels)::value>(s, ranked, bins, tile, np, dd, tf, dtf,
                                                          total, prefix, gcol, ggeo);
          });
          continue;
        }
#endif
        each_chunk(s, ranked, bins, tile, np, gcol, [&](const Chunk& c) {
          blend_chunk(s, c, true);
#if defined(__AVX512F__)
          if (use_wide)
            wide_colour_terms(s, c.ranks, c.m, np, gcol);
          else
#endif
            colour_terms(s, c.ranks, c.m, np, gcol);
          uint64_t group_members[kGroups];
          for (int gr = 0; gr < kGroups; ++gr) {
            uint64_t members = 0;
            for (int i = 0; i < kRowLanes; ++i) members |= s.pmask[gr * kRowLanes + i];
            group_members[gr] = members;
          }
          // The geometry gradients, one 8-pixel group at a time.
          std::memset(s.geo, 0, sizeof(SlotLanes) * size_t(c.m));
          for (int gr = 0; gr < kGroups; ++gr) {
            const int p = gr * kRowLanes;
            if (group_members[gr] == 0) continue;
            const GroupPairs in{s.weight + p, s.raw + p,      s.trans + p,    s.gdot + p,
                                kPixels,      &s.gmask[0][0], kPixels / 64,   p / 64,
                                p % 64,       dd + p,         tf + p,         dtf + p,
                                total + p,    prefix + p,     group_x(s, gr), group_y(s, gr)};
            group_pair_grads(c.splats, group_members[gr], in, s.geo);
          }
          for (int k = 0; k < c.m; ++k) add_geo(s, ranked, c.ranks, k, ggeo);
        });
      }
    }
  });

  // Sum the lists in a fixed order and scatter ranks back to Gaussian order.
  thread_local c10::Storage d_colors_cache;
  torch::Tensor d_colors = recycled_empty(d_colors_cache, {count, n}).zero_();
  torch::Tensor d_geo = torch::zeros({count, kSlots}, torch::kFloat32);
  torch::Tensor d_bg = torch::zeros({n}, torch::kFloat32);
  float* dcol = d_colors.data_ptr<float>();
  float* dgeo = d_geo.data_ptr<float>();
  const int32_t* order = bins.order.data();
  core::parallel_for(0, visible, 1024, [&](int64_t begin, int64_t end) {
    for (int64_t r = begin; r < end; ++r) {
      float* dc = dcol + int64_t(order[r]) * n;
      float* dg = dgeo + int64_t(order[r]) * kSlots;
      for (int l = 0; l < lists; ++l) {
        const float* src = col_buf[l] + r * np;
        for (int64_t c = 0; c < n; ++c) dc[c] += src[c];
        for (int q = 0; q < kSlots; ++q) dg[q] += geo_buf[l][r * kSlots + q];
      }
    }
  });
  float* dbg = d_bg.data_ptr<float>();
  for (int l = 0; l < lists; ++l)
    for (int64_t c = 0; c < n; ++c) dbg[c] += bg_buf[l][c];
  using torch::indexing::Slice;
  return {d_geo.index({Slice(), Slice(kMx, kMy + 1)}).contiguous(),
          d_geo.index({Slice(), Slice(kConA, kConC + 1)}).contiguous(),
          d_geo.index({Slice(), kOpacity}).contiguous(),
          d_geo.index({Slice(), kDepth}).contiguous(),
          d_colors,
          d_bg};
}

}  // namespace ddhgs::render
