#include "render/blend.h"

#include <ATen/Parallel.h>
#include <omp.h>

#include <cmath>
#include <vector>

#include "render/channel_kernels.h"

namespace ddhgs::render {
namespace {

constexpr int kPixels = kTileSize * kTileSize;
// Gaussians per chunk: their padded colour rows (32 x 144 floats at 141
// bands) stay in L1 while every pixel of the tile reads them.
constexpr int kChunk = 32;
constexpr float kMinAlpha = 1.0f / 255.0f;
constexpr float kMaxAlpha = 0.99f;
constexpr float kMinTransmittance = 1e-4f;
// Per-Gaussian gradient slots accumulated by the blender.
enum Slot { kMx, kMy, kConA, kConB, kConC, kOpacity, kDepth, kSlots = 8 };

// Per-Gaussian screen data the inner loop reads, packed for locality.
struct Splat {
  float mx, my, a, b, c, opacity;
  float skip_power;    // power beyond which alpha < 1/255 for sure
  float ext_x, ext_y;  // half extents (px) of the region with alpha >= 1/255
};

// Splats computed once per call and shared by all tiles.
std::vector<Splat>& splats_for(const Projected& p) {
  thread_local std::vector<Splat> splats;
  const int64_t count = p.means2d.size(0);
  splats.resize(count);
  const float* m = p.means2d.data_ptr<float>();
  const float* con = p.conics.data_ptr<float>();
  const float* op = p.opacities.data_ptr<float>();
  at::parallel_for(0, count, 4096, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      Splat& s = splats[i];
      s = {m[2 * i], m[2 * i + 1], con[3 * i], con[3 * i + 1], con[3 * i + 2], op[i], -1, -1, -1};
      // o exp(-power) >= 1/255  <=>  power <= log(255 o); the ellipse
      // power = thr has half extents sqrt(2 thr cov_xx), cov = conic^-1.
      const double thr = std::log(255.0 * op[i]);
      const double det = double(s.a) * s.c - double(s.b) * s.b;
      if (!(thr >= 0) || !(det > 0)) continue;
      s.skip_power = float(thr + 1e-3);  // margin well above float rounding
      s.ext_x = float(std::sqrt(2 * (thr + 1e-3) * s.c / det) + 1);
      s.ext_y = float(std::sqrt(2 * (thr + 1e-3) * s.a / det) + 1);
    }
  });
  return splats;
}

// Per-thread scratch for one tile; thread_local in the OpenMP workers, so it
// is allocated once and reused by every later call.
struct TileScratch {
  int x0, y0, x1, y1, ndone, npix;
  float T[kPixels];
  uint8_t done[kPixels];
  uint8_t count[kPixels];           // pairs per pixel in this chunk
  uint8_t gauss[kPixels * kChunk];  // chunk-local Gaussian of each pair
  float weight[kPixels * kChunk];   // alpha * T
  float raw[kPixels * kChunk];      // o exp(-power) before the 0.99 clamp
  float trans[kPixels * kChunk];    // T before the pair
  int16_t gcount[kChunk];           // pairs per Gaussian in this chunk
  uint8_t gpix[kChunk * kPixels];
  float gweight[kChunk * kPixels];
  float zc[kChunk];
  std::vector<float> cols;  // [kChunk, np] padded colour rows
  std::vector<float> acc;   // [kPixels, np] colour sums (forward) or dL/dimage (backward)
  std::vector<float> tmp;   // [np]

  void start(const TileBins& bins, int tile, int width, int height, int np) {
    x0 = (tile % bins.tiles_x) * kTileSize, y0 = (tile / bins.tiles_x) * kTileSize;
    x1 = std::min(width, x0 + kTileSize), y1 = std::min(height, y0 + kTileSize);
    npix = (x1 - x0) * (y1 - y0);
    ndone = 0;
    std::fill(T, T + kPixels, 1.0f);
    std::fill(done, done + kPixels, uint8_t(0));
    cols.resize(size_t(kChunk) * np);
    acc.assign(size_t(kPixels) * np, 0.0f);
    tmp.resize(np);
  }
};

TileScratch& scratch() {
  thread_local TileScratch s;
  return s;
}

// Gathers the chunk's colour rows (zero padded) and depths.
void gather_chunk(TileScratch& s, const int32_t* ids, int m, const float* colors, int64_t n, int np,
                  const float* depths) {
  for (int k = 0; k < m; ++k) {
    float* row = s.cols.data() + size_t(k) * np;
    std::copy(colors + ids[k] * n, colors + ids[k] * n + n, row);
    std::fill(row + n, row + np, 0.0f);
    s.zc[k] = depths[ids[k]];
  }
}

// The 3DGS per-pixel recurrence for one chunk, Gaussian-major over each
// splat's clipped bounding box. One function for forward and backward so the
// backward replays exactly the same float operations and decisions.
void blend_chunk(TileScratch& s, const Splat* splats, const int32_t* ids, int m,
                 bool gaussian_lists) {
  std::fill(s.count, s.count + kPixels, uint8_t(0));
  for (int k = 0; k < m; ++k) {
    const Splat& g = splats[ids[k]];
    s.gcount[k] = 0;
    if (g.ext_x < 0) continue;
    auto clip = [](float v, int lo, int hi) { return int(std::fmin(std::fmax(v, lo), hi)); };
    // Pixel x has its centre at x + 0.5.
    const int xa = clip(std::floor(g.mx - g.ext_x - 0.5f), s.x0, s.x1);
    const int xb = clip(std::ceil(g.mx + g.ext_x - 0.5f) + 1, s.x0, s.x1);
    const int ya = clip(std::floor(g.my - g.ext_y - 0.5f), s.y0, s.y1);
    const int yb = clip(std::ceil(g.my + g.ext_y - 0.5f) + 1, s.y0, s.y1);
    for (int y = ya; y < yb; ++y) {
      const float dy = g.my - (float(y) + 0.5f);
      const int row = (y - s.y0) * kTileSize - s.x0;
      for (int x = xa; x < xb; ++x) {
        const int p = row + x;
        if (s.done[p]) continue;
        const float dx = g.mx - (float(x) + 0.5f);
        const float power = 0.5f * (g.a * dx * dx + g.c * dy * dy) + g.b * dx * dy;
        if (power > g.skip_power) continue;
        const float raw = g.opacity * std::exp(-power);
        const float alpha = std::fmin(kMaxAlpha, raw);
        if (alpha < kMinAlpha) continue;
        const float t = s.T[p];
        const float next = t * (1.0f - alpha);
        if (next < kMinTransmittance) {
          s.done[p] = 1;
          ++s.ndone;
          continue;
        }
        const int j = p * kChunk + s.count[p]++;
        s.gauss[j] = uint8_t(k);
        s.weight[j] = alpha * t;
        s.raw[j] = raw;
        s.trans[j] = t;
        s.T[p] = next;
        if (gaussian_lists) {
          const int q = k * kPixels + s.gcount[k]++;
          s.gpix[q] = uint8_t(p);
          s.gweight[q] = alpha * t;
        }
      }
    }
  }
}

int pixel_index(const TileScratch& s, int x, int y) {
  return (y - s.y0) * kTileSize + x - s.x0;
}

}  // namespace

BlendForward blend_forward(const Projected& projected, const torch::Tensor& colors,
                           const torch::Tensor& background, const TileBins& bins, int width,
                           int height, bool keep_final_T) {
  const int64_t n = colors.size(1);
  const int np = kernels::padded_channels(n);
  BlendForward out;
  out.image = torch::empty({height, width, n}, torch::kFloat32);
  out.alpha = torch::empty({height, width}, torch::kFloat32);
  out.depth = torch::empty({height, width}, torch::kFloat32);
  if (keep_final_T) out.final_T = torch::empty({height, width}, torch::kFloat32);
  const Splat* splats = splats_for(projected).data();
  const float* col = colors.data_ptr<float>();
  const float* bg = background.data_ptr<float>();
  const float* depths = projected.depths.data_ptr<float>();
  float* img = out.image.data_ptr<float>();
  float* alpha = out.alpha.data_ptr<float>();
  float* depth = out.depth.data_ptr<float>();
  float* final_T = keep_final_T ? out.final_T.data_ptr<float>() : nullptr;
  const int lists = int(bins.thread_tiles.size());
  int64_t pairs = 0;

#pragma omp parallel num_threads(lists) reduction(+ : pairs)
  for (int list = omp_get_thread_num(); list < lists; list += omp_get_num_threads()) {
    TileScratch& s = scratch();
    for (int tile : bins.thread_tiles[list]) {
      s.start(bins, tile, width, height, np);
      float dsum[kPixels] = {};
      for (int32_t b = bins.offsets[tile]; b < bins.offsets[tile + 1] && s.ndone < s.npix;
           b += kChunk) {
        const int32_t* ids = bins.ids.data() + b;
        const int m = std::min<int32_t>(kChunk, bins.offsets[tile + 1] - b);
        gather_chunk(s, ids, m, col, n, np, depths);
        blend_chunk(s, splats, ids, m, false);
        for (int p = 0; p < kPixels; ++p) {
          const int c = s.count[p];
          if (c == 0) continue;
          pairs += c;
          kernels::gather_axpy(s.acc.data() + size_t(p) * np, s.cols.data(), np,
                               s.gauss + p * kChunk, s.weight + p * kChunk, c);
          for (int j = 0; j < c; ++j)
            dsum[p] += s.weight[p * kChunk + j] * s.zc[s.gauss[p * kChunk + j]];
        }
      }
      for (int y = s.y0; y < s.y1; ++y)
        for (int x = s.x0; x < s.x1; ++x) {
          const int p = pixel_index(s, x, y);
          const int64_t o = int64_t(y) * width + x;
          const float* a = s.acc.data() + size_t(p) * np;
          float* dst = img + o * n;
          const float t = s.T[p];
          for (int64_t c = 0; c < n; ++c) dst[c] = a[c] + t * bg[c];
          alpha[o] = 1.0f - t;
          depth[o] = dsum[p];
          if (final_T) final_T[o] = t;
        }
    }
  }
  out.pairs = pairs;
  return out;
}

BlendGrads blend_backward(const Projected& projected, const torch::Tensor& colors,
                          const torch::Tensor& background, const TileBins& bins, int width,
                          int height, const BlendForward& fwd, const torch::Tensor& d_image,
                          const torch::Tensor& d_alpha, const torch::Tensor& d_depth) {
  const int64_t count = colors.size(0), n = colors.size(1);
  const int np = kernels::padded_channels(n);
  const int lists = int(bins.thread_tiles.size());
  // Buffers of list 0 are the outputs; the others are summed into them in
  // list order at the end, so results do not depend on OS scheduling.
  thread_local std::vector<std::vector<float>> extra_colors, extra_geo, extra_bg;
  extra_colors.resize(lists), extra_geo.resize(lists), extra_bg.resize(lists);
  torch::Tensor d_colors = torch::zeros({count, n}, torch::kFloat32);
  torch::Tensor d_geo = torch::zeros({count, kSlots}, torch::kFloat32);
  torch::Tensor d_bg = torch::zeros({n}, torch::kFloat32);
  std::vector<float*> col_buf(lists), geo_buf(lists), bg_buf(lists);
  col_buf[0] = d_colors.data_ptr<float>(), geo_buf[0] = d_geo.data_ptr<float>();
  bg_buf[0] = d_bg.data_ptr<float>();
  for (int l = 1; l < lists; ++l) {
    extra_colors[l].assign(size_t(count * n), 0.0f);
    extra_geo[l].assign(size_t(count * kSlots), 0.0f);
    extra_bg[l].assign(size_t(n), 0.0f);
    col_buf[l] = extra_colors[l].data(), geo_buf[l] = extra_geo[l].data();
    bg_buf[l] = extra_bg[l].data();
  }
  const Splat* splats = splats_for(projected).data();
  const float* col = colors.data_ptr<float>();
  const float* bg = background.data_ptr<float>();
  const float* depths = projected.depths.data_ptr<float>();
  const torch::Tensor dimg_t = d_image.contiguous();
  const float* dimg = dimg_t.data_ptr<float>();
  const torch::Tensor dalpha_t = d_alpha.defined() ? d_alpha.contiguous() : torch::Tensor();
  const torch::Tensor ddepth_t = d_depth.defined() ? d_depth.contiguous() : torch::Tensor();
  const float* dalpha = dalpha_t.defined() ? dalpha_t.data_ptr<float>() : nullptr;
  const float* ddepth = ddepth_t.defined() ? ddepth_t.data_ptr<float>() : nullptr;
  const float* img = fwd.image.data_ptr<float>();
  const float* dep = fwd.depth.data_ptr<float>();
  const float* final_T = fwd.final_T.data_ptr<float>();

#pragma omp parallel num_threads(lists)
  for (int list = omp_get_thread_num(); list < lists; list += omp_get_num_threads()) {
    TileScratch& s = scratch();
    float* gcol = col_buf[list];
    float* ggeo = geo_buf[list];
    float* gbg = bg_buf[list];
    for (int tile : bins.thread_tiles[list]) {
      s.start(bins, tile, width, height, np);
      // Per pixel: dL/dD, final T, dL/dT_final and the total sum_j g_j w_j,
      // so the suffix sum each pair needs is total - prefix (no reverse pass).
      float dd[kPixels] = {}, tf[kPixels] = {}, dtf[kPixels] = {};
      double total[kPixels] = {}, prefix[kPixels] = {};
      for (int y = s.y0; y < s.y1; ++y)
        for (int x = s.x0; x < s.x1; ++x) {
          const int p = pixel_index(s, x, y);
          const int64_t o = int64_t(y) * width + x;
          const float* dc = dimg + o * n;
          std::copy(dc, dc + n, s.acc.data() + size_t(p) * np);
          tf[p] = final_T[o];
          dd[p] = ddepth ? ddepth[o] : 0.0f;
          double tot = double(dd[p]) * dep[o], dt = dalpha ? -double(dalpha[o]) : 0.0;
          for (int64_t c = 0; c < n; ++c) {
            tot += double(dc[c]) * (img[o * n + c] - tf[p] * bg[c]);
            dt += double(dc[c]) * bg[c];
            gbg[c] += tf[p] * dc[c];
          }
          total[p] = tot;
          dtf[p] = float(dt);
        }
      for (int32_t b = bins.offsets[tile]; b < bins.offsets[tile + 1] && s.ndone < s.npix;
           b += kChunk) {
        const int32_t* ids = bins.ids.data() + b;
        const int m = std::min<int32_t>(kChunk, bins.offsets[tile + 1] - b);
        gather_chunk(s, ids, m, col, n, np, depths);
        blend_chunk(s, splats, ids, m, true);
        // dL/dcolors = W^T dL/dimage, Gaussian-major with register accumulators.
        for (int k = 0; k < m; ++k) {
          if (s.gcount[k] == 0) continue;
          std::fill(s.tmp.begin(), s.tmp.end(), 0.0f);
          kernels::gather_axpy(s.tmp.data(), s.acc.data(), np, s.gpix + k * kPixels,
                               s.gweight + k * kPixels, s.gcount[k]);
          float* dst = gcol + int64_t(ids[k]) * n;
          for (int64_t c = 0; c < n; ++c) dst[c] += s.tmp[c];
        }
        float geo[kChunk][kSlots] = {};
        for (int p = 0; p < kPixels; ++p) {
          const int c = s.count[p];
          if (c == 0) continue;
          float gdot[kChunk] = {};
          const int j0 = p * kChunk;
          kernels::gather_dot(s.acc.data() + size_t(p) * np, s.cols.data(), np, s.gauss + j0, c,
                              gdot);
          const float px = float(s.x0 + p % kTileSize) + 0.5f;
          const float py = float(s.y0 + p / kTileSize) + 0.5f;
          for (int j = 0; j < c; ++j) {
            const int k = s.gauss[j0 + j];
            const float w = s.weight[j0 + j], raw = s.raw[j0 + j], t = s.trans[j0 + j];
            const float g = gdot[j] + s.zc[k] * dd[p];
            geo[k][kDepth] += w * dd[p];
            prefix[p] += double(g) * w;
            const float suffix = float(total[p] - prefix[p]);
            const float alpha = std::fmin(kMaxAlpha, raw);
            const float d_alpha_j = t * g - (suffix + dtf[p] * tf[p]) / (1.0f - alpha);
            if (raw > kMaxAlpha) continue;  // clamped: no gradient to o or power
            const Splat& sp = splats[ids[k]];
            const float dx = sp.mx - px, dy = sp.my - py;
            const float d_power = -d_alpha_j * raw;
            geo[k][kOpacity] += d_alpha_j * raw / sp.opacity;
            geo[k][kMx] += d_power * (sp.a * dx + sp.b * dy);
            geo[k][kMy] += d_power * (sp.b * dx + sp.c * dy);
            geo[k][kConA] += 0.5f * d_power * dx * dx;
            geo[k][kConB] += d_power * dx * dy;
            geo[k][kConC] += 0.5f * d_power * dy * dy;
          }
        }
        for (int k = 0; k < m; ++k)
          for (int q = 0; q < kSlots; ++q) ggeo[int64_t(ids[k]) * kSlots + q] += geo[k][q];
      }
    }
  }

  for (int l = 1; l < lists; ++l) {
    float* dst = col_buf[0];
    const float* src = col_buf[l];
    at::parallel_for(0, count * n, 1 << 16, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) dst[i] += src[i];
    });
    for (int64_t i = 0; i < count * kSlots; ++i) geo_buf[0][i] += geo_buf[l][i];
    for (int64_t c = 0; c < n; ++c) bg_buf[0][c] += bg_buf[l][c];
  }
  using torch::indexing::Slice;
  return {d_geo.index({Slice(), Slice(kMx, kMy + 1)}).contiguous(),
          d_geo.index({Slice(), Slice(kConA, kConC + 1)}).contiguous(),
          d_geo.index({Slice(), kOpacity}).contiguous(),
          d_geo.index({Slice(), kDepth}).contiguous(),
          d_colors,
          d_bg};
}

}  // namespace ddhgs::render
