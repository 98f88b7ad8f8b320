// Fused L1 + SSIM over channels-last images, value and gradient.
//
// Per band and valid window q (top-left corner), with the 11 x 11 Gaussian
// window w and moments mu_x, mu_y, s_xx, s_yy, s_xy (window sums of x, y,
// x^2, y^2, x y; computed about kShift, see below):
//   S = A1 A2 / (B1 B2), A1 = 2 mu_x mu_y + C1, A2 = 2 (s_xy - mu_x mu_y) + C2,
//   B1 = mu_x^2 + mu_y^2 + C1, B2 = s_xx - mu_x^2 + s_yy - mu_y^2 + C2.
// Its derivative w.r.t. the render pixel x_p is
//   sum_q w(p - q) (dS/dmu_x(q) + 2 x_p dS/ds_xx(q) + y_p dS/ds_xy(q)),
// i.e. three more separable blurs ("full" correlation, the window is
// symmetric) of per-window coefficient maps.
//
// Layout: a work item is one strip of image rows and one block of kB bands.
// Its input rows go, band block padded with zeros, into a ring of 12 rows;
// each valid-window row is a vertical pass over the ring (five moments at
// once) followed by a horizontal pass; its coefficients go to a second ring
// from which each gradient row is gathered the same way. Rows go in pairs
// where they can: one vertical pass over 12 ring rows serves two output rows
// (the ring loads are what the kernel waits on), each output summing its
// taps in the same order as alone (the compiler may fuse multiply-adds
// differently, so the last bits can differ from unpaired rows; the pairing
// depends on the image's shape only, never on the thread count). The inner
// loops run over vectors of kB bands. At kB = 16 a column costs the rings
// about 4.9 KB (3.1 MB at 640 columns), so images wider than kTileColumns
// are cut into column tiles, each with the 10 columns either side that its
// windows and gradients reach (as a strip has the 10 rows above it): a
// tile's rings fit a 2 MB L2 cache, and a half crop of a 640x512 view runs
// 1.3-1.4x faster, a whole view 2x. A tile computes exactly the windows and
// gradients the whole row would; only the partial sums of L1 and SSIM are
// grouped by tile.
#include "model/ssim_kernel.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/float_vec.h"
#include "core/parallel.h"
#include "model/ssim.h"

namespace ddhgs::model::ssim_kernel {
namespace {

constexpr int kR = kSsimWindow;
constexpr int kRing = kR + 1;  // ring rows: a pair of output rows needs 12
constexpr int kMoments = 5;    // x, y, x^2, y^2, x y
constexpr int kCoeffs = 3;     // dS/dmu_x, dS/ds_xx, dS/ds_xy
constexpr float kC1 = 0.01f * 0.01f, kC2 = 0.03f * 0.03f;
// Moments are taken about the middle of the [0, 1] data range: the rounding
// error of E[x^2] - E[x]^2 scales with (x - kShift)^2 instead of x^2, which
// matters where the variances are near zero (flat backgrounds) and only
// C2 = 9e-4 keeps SSIM finite.
constexpr float kShift = 0.5f;
// Work items wanted per image: enough for two threads to balance. Strips are
// only cut when there are fewer band blocks than this, since each strip
// recomputes the 10 window rows above it.
constexpr int64_t kItems = 16;
constexpr int64_t kMinStripRows = 24;
// Owned columns per tile at most (tiles are balanced, so most are narrower).
constexpr int64_t kTileColumns = 192;

struct Window {
  float w[kR];
  Window() {
    double d[kR], sum = 0;
    for (int k = 0; k < kR; ++k) {
      const double x = double(k - kR / 2);
      d[k] = std::exp(-(x * x) / (2 * kSsimSigma * kSsimSigma));
      sum += d[k];
    }
    for (int k = 0; k < kR; ++k) w[k] = float(d[k] / sum);
  }
};

// A vector of kB bands: one AVX-512 register for kB = 16, two AVX2 ones.
template <int kB>
using VecOf = core::FloatVec<kB>;
using core::load_vec;
using core::store_vec;

// Ring and row buffers of one thread, in vectors of kB bands.
template <typename V>
struct Scratch {
  std::vector<V> in;     // [kRing][W][2] x, y (about kShift), ring by row % kRing
  std::vector<V> v;      // [2][W][kMoments] vertical moment sums of two window rows
  std::vector<V> coeff;  // [kRing][Wv][kCoeffs] coefficient rows, ring by row % kRing
  std::vector<V> u;      // [2][Wv][kCoeffs] vertical coefficient sums of two gradient rows

  static Scratch& get() {
    thread_local Scratch s;
    return s;
  }
};

template <typename V>
V lane_mask(int bw) {
  V m = {};
  for (int c = 0; c < bw; ++c) m[c] = 1.0f;
  return m;
}

template <int kB>
struct Item {
  using V = typename VecOf<kB>::type;
  const Images& im;
  const Window& win;
  float* grad;
  int64_t c0;          // first band of the block
  int bw;              // bands in the block (<= kB)
  int64_t x0, tw;      // the tile's first image column and its width, halo included
  int64_t own0, own1;  // the tile's own pixel (and window) columns, tile-local
  int64_t wv, hv;      // valid windows of the tile's columns, of the image's rows
  float inv_m;         // 1 / (N Hv Wv)
  Scratch<V>& s;
  V lanes;  // 1 in the block's bands, 0 in the padding lanes

  V* in_row(int64_t r) const { return s.in.data() + (r % kRing) * tw * 2; }
  V* coeff_row(int64_t i) const { return s.coeff.data() + (i % kRing) * wv * kCoeffs; }

  // Copies row r's band block into the ring, about kShift (padding lanes
  // hold 0); returns sum |x - y| over it, from the unshifted values.
  double load_row(int64_t r) const {
    const int64_t stride = im.bands;
    const float* a = im.render + (r * im.width + x0) * stride + c0;
    const float* b = im.target + (r * im.width + x0) * stride + c0;
    V* dst = in_row(r);
    V l1 = {};
    // The block's values sit 4 * N bytes apart, a stride the hardware
    // prefetchers do not follow across pages: ask for the next row's while
    // this one is read (1.15-1.2x at 640x512x141).
    const int64_t next = r + 1 < im.height ? im.width * stride : 0;
    for (int64_t j = 0; j < tw; ++j) {
      __builtin_prefetch(a + j * stride + next);
      __builtin_prefetch(b + j * stride + next);
      V x = {}, y = {};
      if (bw == kB) {
        x = load_vec<V>(a + j * stride), y = load_vec<V>(b + j * stride);
      } else {
        for (int c = 0; c < bw; ++c) x[c] = a[j * stride + c], y[c] = b[j * stride + c];
      }
      const V d = x - y;
      if (j >= own0 && j < own1) l1 += d < 0 ? -d : d;
      dst[2 * j] = (x - kShift) * lanes;
      dst[2 * j + 1] = (y - kShift) * lanes;
    }
    double sum = 0;
    for (int c = 0; c < kB; ++c) sum += l1[c];
    return sum;
  }

  // Adds tap k of ring row x, y to moments m.
  static inline void add_tap(V* m, float wk, const V& x, const V& y) {
    const V wx = wk * x, wy = wk * y;
    m[0] += wx, m[1] += wy, m[2] += wx * x, m[3] += wy * y, m[4] += wx * y;
  }

  // Vertical moment sums of window row i into v.
  void vertical_moments(int64_t i, V* v) const {
    const V* rows[kR];
    for (int k = 0; k < kR; ++k) rows[k] = in_row(i + k);
    for (int64_t j = 0; j < tw; ++j) {
      V m[kMoments] = {};
      for (int k = 0; k < kR; ++k) add_tap(m, win.w[k], rows[k][2 * j], rows[k][2 * j + 1]);
      std::memcpy(v + j * kMoments, m, sizeof m);
    }
  }

  // The same for window rows i and i + 1 in one pass over ring rows
  // i..i+11: each ring row is loaded once for both.
  void vertical_moments2(int64_t i, V* v0, V* v1) const {
    const V* rows[kRing];
    for (int k = 0; k < kRing; ++k) rows[k] = in_row(i + k);
    for (int64_t j = 0; j < tw; ++j) {
      V a[kMoments] = {}, b[kMoments] = {};
      add_tap(a, win.w[0], rows[0][2 * j], rows[0][2 * j + 1]);
      for (int k = 1; k < kR; ++k) {
        const V x = rows[k][2 * j], y = rows[k][2 * j + 1];
        add_tap(a, win.w[k], x, y);
        add_tap(b, win.w[k - 1], x, y);
      }
      add_tap(b, win.w[kR - 1], rows[kR][2 * j], rows[kR][2 * j + 1]);
      std::memcpy(v0 + j * kMoments, a, sizeof a);
      std::memcpy(v1 + j * kMoments, b, sizeof b);
    }
  }

  // Window row i from its vertical sums v: horizontal sums and SSIM per
  // window; coefficients into the ring when grad is wanted. Returns the sum
  // of SSIM over the row's windows and the block's bands.
  double window_row(int64_t i, const V* v) const {
    V* co = grad ? coeff_row(i) : nullptr;
    V row_sum = {};
    for (int64_t j = 0; j < wv; ++j) {
      V mu[kMoments] = {};
      for (int k = 0; k < kR; ++k) {
        const float wk = win.w[k];
        const V* vj = v + (j + k) * kMoments;
        for (int q = 0; q < kMoments; ++q) mu[q] += wk * vj[q];
      }
      // Shifted means (s) and the true ones (m): variances and covariance
      // are shift invariant, the luminance term is not.
      const V sx = mu[0], sy = mu[1];
      const V mx = sx + kShift, my = sy + kShift;
      const V a1 = 2 * mx * my + kC1, a2 = 2 * (mu[4] - sx * sy) + kC2;
      const V b1 = mx * mx + my * my + kC1;
      const V b2 = (mu[2] - sx * sx) + (mu[3] - sy * sy) + kC2;
      const V inv_d = 1.0f / (b1 * b2);
      const V value = a1 * a2 * inv_d;
      if (j >= own0 && j < own1) row_sum += value;
      if (co) {
        // dS/dmu_x with dA1 = 2 mu_y, dA2 = -2 s_y, dB1 = 2 mu_x, dB2 = -2 s_x;
        // 1 / B1 = B2 / D and 1 / B2 = B1 / D.
        V* out = co + j * kCoeffs;
        out[0] = 2 * (my * a2 - sy * a1 - value * (mx * b2 - sx * b1)) * inv_d;
        out[1] = -value * b1 * inv_d;
        out[2] = 2 * a1 * inv_d;
      }
    }
    double sum = 0;
    for (int c = 0; c < bw; ++c) sum += row_sum[c];
    return sum;
  }

  // Vertical sums for gradient row r of the coefficient rows r-10..r (those
  // that exist) into u.
  void vertical_coeffs(int64_t r, V* u) const {
    const int64_t ilo = std::max<int64_t>(0, r - (kR - 1)), ihi = std::min(hv - 1, r);
    const V* rows[kR];
    float weights[kR];
    int taps = 0;
    for (int64_t i = ilo; i <= ihi; ++i, ++taps)
      rows[taps] = coeff_row(i), weights[taps] = win.w[r - i];
    for (int64_t j = 0; j < wv * kCoeffs; ++j) {
      V sum = {};
      for (int k = 0; k < taps; ++k) sum += weights[k] * rows[k][j];
      u[j] = sum;
    }
  }

  // The same for rows r and r + 1 where both have all 11 coefficient rows
  // (10 <= r, r + 1 < hv): one pass over rows r-10..r+1, summed in the same
  // order as vertical_coeffs.
  void vertical_coeffs2(int64_t r, V* u0, V* u1) const {
    const V* rows[kRing];
    for (int k = 0; k < kRing; ++k) rows[k] = coeff_row(r - (kR - 1) + k);
    for (int64_t j = 0; j < wv * kCoeffs; ++j) {
      V a = {}, b = {};
      a += win.w[kR - 1] * rows[0][j];
      for (int k = 1; k < kR; ++k) {
        const V c = rows[k][j];
        a += win.w[kR - 1 - k] * c;
        b += win.w[kR - k] * c;
      }
      b += win.w[0] * rows[kR][j];
      u0[j] = a, u1[j] = b;
    }
  }

  // Gradient row r from its vertical sums u; x and y are the ring's values
  // about kShift, the variables of s_xx and s_xy.
  void gradient_row(int64_t r, const V* u) const {
    const V* xy = in_row(r);
    float* out = grad + (r * im.width + x0) * im.bands + c0;
    const int64_t next = r + 1 < im.height ? im.width * im.bands : 0;  // as in load_row
    for (int64_t col = own0; col < own1; ++col) {
      __builtin_prefetch(out + col * im.bands + next, 1);
      const int64_t jlo = std::max<int64_t>(0, col - (kR - 1)), jhi = std::min(wv - 1, col);
      V a0 = {}, a1 = {}, a2 = {};
      for (int64_t j = jlo; j <= jhi; ++j) {
        const float wk = win.w[col - j];
        const V* uj = u + j * kCoeffs;
        a0 += wk * uj[0], a1 += wk * uj[1], a2 += wk * uj[2];
      }
      const V* m = xy + col * 2;
      const V g = (a0 + 2 * m[0] * a1 + m[1] * a2) * inv_m;
      float* dst = out + col * im.bands;
      if (bw == kB) {
        store_vec(dst, g);
      } else {
        for (int c = 0; c < bw; ++c) dst[c] = g[c];
      }
    }
  }

  // Rows [r0, r1) of the block: their L1, the SSIM of the windows starting
  // in them and, when wanted, their gradient.
  Sums run(int64_t r0, int64_t r1) const {
    Sums sums;
    const int64_t first = std::max<int64_t>(0, r0 - (kR - 1));  // first window row needed
    const int64_t last = std::min(r1, hv);                      // window rows [first, last)
    int64_t loaded = first;
    auto load_through = [&](int64_t row) {
      for (; loaded <= row; ++loaded) {
        const double l1 = load_row(loaded);
        if (loaded >= r0 && loaded < r1) sums.l1 += l1;
      }
    };
    V* v0 = s.v.data();
    V* v1 = v0 + tw * kMoments;
    V* u0 = grad ? s.u.data() : nullptr;  // s.u is sized only when grad is wanted
    V* u1 = grad ? u0 + wv * kCoeffs : nullptr;
    // Gradient rows r (and r + 1 when pair), once their coefficient rows exist.
    auto gradients = [&](int64_t r, bool pair) {
      if (pair && r >= kR - 1 && r + 1 < hv) {
        vertical_coeffs2(r, u0, u1);
        gradient_row(r, u0);
        gradient_row(r + 1, u1);
        return;
      }
      for (int64_t q = r; q <= r + int64_t(pair); ++q) {
        vertical_coeffs(q, u0);
        gradient_row(q, u0);
      }
    };
    for (int64_t i = first; i < last;) {
      if (i + 1 < last) {
        load_through(i + kR);
        vertical_moments2(i, v0, v1);
        const double ssim0 = window_row(i, v0), ssim1 = window_row(i + 1, v1);
        // Halo rows (above r0) belong to the strip above.
        if (i >= r0) sums.ssim += ssim0;
        if (i + 1 >= r0) sums.ssim += ssim1;
        if (grad && i + 1 >= r0) gradients(i >= r0 ? i : i + 1, i >= r0);
        i += 2;
      } else {
        load_through(i + kR - 1);
        vertical_moments(i, v0);
        const double row_ssim = window_row(i, v0);
        if (i >= r0) {
          sums.ssim += row_ssim;
          if (grad) gradients(i, false);
        }
        i += 1;
      }
    }
    load_through(r1 - 1);
    if (grad)
      for (int64_t r = std::max(r0, last); r < r1; ++r) gradients(r, false);
    return sums;
  }
};

template <int kB>
Sums run_blocks(const Images& im, float* grad) {
  using V = typename VecOf<kB>::type;
  static const Window window;
  const int64_t blocks = (im.bands + kB - 1) / kB;
  const int64_t tiles = (im.width + kTileColumns - 1) / kTileColumns;
  const int64_t tile_columns = (im.width + tiles - 1) / tiles;
  const int64_t halo = kR - 1;
  const int64_t max_tw = std::min(im.width, tile_columns + 2 * halo);
  const int64_t wanted = std::max<int64_t>(1, (kItems + blocks * tiles - 1) / (blocks * tiles));
  const int64_t strips = std::max<int64_t>(1, std::min(wanted, im.height / kMinStripRows));
  const int64_t strip_rows = (im.height + strips - 1) / strips;
  const int64_t items = strips * tiles * blocks;
  const int64_t wv = im.width - (kR - 1), hv = im.height - (kR - 1);
  const float inv_m = float(1.0 / (double(im.bands) * double(hv) * double(wv)));
  std::vector<Sums> partial(static_cast<size_t>(items));
  core::parallel_for(0, items, 1, [&](int64_t begin, int64_t end) {
    Scratch<V>& s = Scratch<V>::get();
    s.in.resize(size_t(kRing * max_tw * 2));
    s.v.resize(size_t(2 * max_tw * kMoments));
    if (grad) {
      s.coeff.resize(size_t(kRing * max_tw * kCoeffs));
      s.u.resize(size_t(2 * max_tw * kCoeffs));
    }
    for (int64_t item = begin; item < end; ++item) {
      const int64_t strip = item / (tiles * blocks), tile = item / blocks % tiles;
      const int64_t block = item % blocks;
      const int64_t c0 = block * kB;
      const int bw = int(std::min<int64_t>(kB, im.bands - c0));
      const int64_t r0 = strip * strip_rows, r1 = std::min(im.height, r0 + strip_rows);
      // Own columns [t0, t1); windows start in [x0, t1) (those of [x0, t0)
      // feed the own gradients and belong to the tile on the left), and read
      // columns to t1 + 10.
      const int64_t t0 = tile * tile_columns, t1 = std::min(im.width, t0 + tile_columns);
      const int64_t x0 = std::max<int64_t>(0, t0 - halo), x1 = std::min(im.width, t1 + halo);
      const Item<kB> work{im,      window,  grad,           c0, bw,    x0, x1 - x0,
                          t0 - x0, t1 - x0, x1 - x0 - halo, hv, inv_m, s,  lane_mask<V>(bw)};
      if (r0 < r1 && t0 < t1) partial[size_t(item)] = work.run(r0, r1);
    }
  });
  Sums total;
  for (const Sums& p : partial) total.l1 += p.l1, total.ssim += p.ssim;
  return total;
}

}  // namespace

Sums run(const Images& im, float* grad) {
  // Narrow blocks for few bands, so RGB does not compute 13 empty lanes.
  if (im.bands <= 4) return run_blocks<4>(im, grad);
#if defined(__AVX512F__)
  if (im.bands > 8) return run_blocks<16>(im, grad);
#endif
  // One 256-bit register per vector: with two (16 bands on AVX2) the paired
  // vertical pass's 20 accumulators do not fit the 16 registers and spill on
  // every tap (2.3-2.8x slower at 640x512x141, one thread).
  return run_blocks<8>(im, grad);
}

}  // namespace ddhgs::model::ssim_kernel
