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
// Its input rows are copied, band block padded with zeros, into a ring of 11
// rows; each valid-window row is a vertical pass over the ring (five moments
// at once) followed by a horizontal pass; its coefficients go to a second
// ring from which each gradient row is gathered the same way. Everything a
// row needs stays in a few hundred KB, and the inner loops run over the kB
// bands, which the compiler vectorises.
#include "model/ssim_kernel.h"

#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "model/ssim.h"

namespace ddhgs::model::ssim_kernel {
namespace {

constexpr int kR = kSsimWindow;
constexpr int kMoments = 5;  // x, y, x^2, y^2, x y
constexpr int kCoeffs = 3;   // dS/dmu_x, dS/ds_xx, dS/ds_xy
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

// kB: bands per block (template parameter below).
struct Scratch {
  std::vector<float> x, y;   // [kR][W][kB] input rows, ring indexed by row % kR
  std::vector<float> v;      // [W][kMoments][kB] vertical moment sums of one window row
  std::vector<float> coeff;  // [kR][Wv][kCoeffs][kB] coefficient rows, ring by row % kR
  std::vector<float> u;      // [Wv][kCoeffs][kB] vertical coefficient sums of one gradient row
};

Scratch& scratch() {
  thread_local Scratch s;
  return s;
}

template <int kB>
struct Item {
  const Images& im;
  const Window& win;
  float* grad;
  int64_t c0;  // first band of the block
  int bw;      // bands in the block (<= kB)
  int64_t wv, hv;
  float inv_m;  // 1 / (N Hv Wv)
  Scratch& s;

  float* xrow(int64_t r) const { return s.x.data() + (r % kR) * im.width * kB; }
  float* yrow(int64_t r) const { return s.y.data() + (r % kR) * im.width * kB; }
  float* crow(int64_t i) const { return s.coeff.data() + (i % kR) * wv * kCoeffs * kB; }

  // Copies row r's band block into the ring, shifted by -kShift (padding
  // lanes hold 0); returns sum |x - y| over it, from the unshifted values.
  double load_row(int64_t r) const {
    const int64_t stride = im.bands;
    const float* a = im.render + r * im.width * stride + c0;
    const float* b = im.target + r * im.width * stride + c0;
    float* xd = xrow(r);
    float* yd = yrow(r);
    double l1 = 0;
    for (int64_t j = 0; j < im.width; ++j) {
      float* xj = xd + j * kB;
      float* yj = yd + j * kB;
      const float* aj = a + j * stride;
      const float* bj = b + j * stride;
      float pixel = 0;
      if (bw == kB) {
        for (int c = 0; c < kB; ++c) {
          pixel += std::abs(aj[c] - bj[c]);
          xj[c] = aj[c] - kShift, yj[c] = bj[c] - kShift;
        }
      } else {
        for (int c = 0; c < kB; ++c) {
          pixel += c < bw ? std::abs(aj[c] - bj[c]) : 0.0f;
          xj[c] = c < bw ? aj[c] - kShift : 0.0f;
          yj[c] = c < bw ? bj[c] - kShift : 0.0f;
        }
      }
      l1 += pixel;
    }
    return l1;
  }

  // Moments of window row i: vertical sums into v, then horizontal sums and
  // SSIM per window; coefficients into the ring when grad is wanted.
  // Returns the sum of SSIM over the row's windows and the block's bands.
  double window_row(int64_t i) const {
    const float* xs[kR];
    const float* ys[kR];
    for (int k = 0; k < kR; ++k) xs[k] = xrow(i + k), ys[k] = yrow(i + k);
    float* v = s.v.data();
    for (int64_t j = 0; j < im.width; ++j) {
      float m[kMoments][kB] = {};
      for (int k = 0; k < kR; ++k) {
        const float wk = win.w[k];
        const float* xj = xs[k] + j * kB;
        const float* yj = ys[k] + j * kB;
        for (int c = 0; c < kB; ++c) {
          const float xc = xj[c], yc = yj[c];
          m[0][c] += wk * xc;
          m[1][c] += wk * yc;
          m[2][c] += wk * (xc * xc);
          m[3][c] += wk * (yc * yc);
          m[4][c] += wk * (xc * yc);
        }
      }
      std::copy(&m[0][0], &m[0][0] + kMoments * kB, v + j * kMoments * kB);
    }
    float* co = grad ? crow(i) : nullptr;
    double row_sum = 0;
    for (int64_t j = 0; j < wv; ++j) {
      float mu[kMoments][kB] = {};
      for (int k = 0; k < kR; ++k) {
        const float wk = win.w[k];
        const float* vj = v + (j + k) * kMoments * kB;
        for (int q = 0; q < kMoments; ++q)
          for (int c = 0; c < kB; ++c) mu[q][c] += wk * vj[q * kB + c];
      }
      float ssim[kB];
      float* out = co ? co + j * kCoeffs * kB : nullptr;
      for (int c = 0; c < kB; ++c) {
        // Shifted means (m) and the true ones (mu): variances and covariance
        // are shift invariant, the luminance term is not.
        const float sx = mu[0][c], sy = mu[1][c];
        const float mx = sx + kShift, my = sy + kShift;
        const float sxy = sx * sy;
        const float a1 = 2 * mx * my + kC1, a2 = 2 * (mu[4][c] - sxy) + kC2;
        const float b1 = mx * mx + my * my + kC1;
        const float b2 = (mu[2][c] - sx * sx) + (mu[3][c] - sy * sy) + kC2;
        const float inv_d = 1.0f / (b1 * b2);
        const float value = a1 * a2 * inv_d;
        ssim[c] = value;
        if (out) {
          // dS/dmu_x with dA1 = 2 mu_y, dA2 = -2 m_y, dB1 = 2 mu_x, dB2 = -2 m_x;
          // 1 / B1 = B2 / D and 1 / B2 = B1 / D.
          out[c] = 2 * (my * a2 - sy * a1 - value * (mx * b2 - sx * b1)) * inv_d;
          out[kB + c] = -value * b1 * inv_d;
          out[2 * kB + c] = 2 * a1 * inv_d;
        }
      }
      float sum = 0;
      for (int c = 0; c < bw; ++c) sum += ssim[c];
      row_sum += sum;
    }
    return row_sum;
  }

  // Gradient row r from the coefficient rows r-10..r (those that exist); the
  // ring holds x - kShift and y - kShift, the variables of s_xx and s_xy.
  void gradient_row(int64_t r) const {
    const int64_t ilo = std::max<int64_t>(0, r - (kR - 1)), ihi = std::min(hv - 1, r);
    float* u = s.u.data();
    for (int64_t j = 0; j < wv; ++j) {
      float acc[kCoeffs * kB] = {};
      for (int64_t i = ilo; i <= ihi; ++i) {
        const float wk = win.w[r - i];
        const float* cj = crow(i) + j * kCoeffs * kB;
        for (int c = 0; c < kCoeffs * kB; ++c) acc[c] += wk * cj[c];
      }
      std::copy(acc, acc + kCoeffs * kB, u + j * kCoeffs * kB);
    }
    const float* xs = xrow(r);
    const float* ys = yrow(r);
    float* out = grad + r * im.width * im.bands + c0;
    for (int64_t col = 0; col < im.width; ++col) {
      const int64_t jlo = std::max<int64_t>(0, col - (kR - 1)), jhi = std::min(wv - 1, col);
      float acc[kCoeffs][kB] = {};
      for (int64_t j = jlo; j <= jhi; ++j) {
        const float wk = win.w[col - j];
        const float* uj = u + j * kCoeffs * kB;
        for (int q = 0; q < kCoeffs; ++q)
          for (int c = 0; c < kB; ++c) acc[q][c] += wk * uj[q * kB + c];
      }
      const float* xc = xs + col * kB;
      const float* yc = ys + col * kB;
      float g[kB];
      for (int c = 0; c < kB; ++c)
        g[c] = (acc[0][c] + 2 * xc[c] * acc[1][c] + yc[c] * acc[2][c]) * inv_m;
      float* dst = out + col * im.bands;
      for (int c = 0; c < bw; ++c) dst[c] = g[c];
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
    for (int64_t i = first; i < last; ++i) {
      load_through(i + kR - 1);
      const double row_ssim = window_row(i);
      if (i < r0) continue;  // halo row: owned by the strip above
      sums.ssim += row_ssim;
      if (grad) gradient_row(i);
    }
    load_through(r1 - 1);
    if (grad)
      for (int64_t r = std::max(r0, last); r < r1; ++r) gradient_row(r);
    return sums;
  }
};

template <int kB>
Sums run_blocks(const Images& im, float* grad) {
  static const Window window;
  const int64_t blocks = (im.bands + kB - 1) / kB;
  const int64_t wanted = std::max<int64_t>(1, (kItems + blocks - 1) / blocks);
  const int64_t strips = std::max<int64_t>(1, std::min(wanted, im.height / kMinStripRows));
  const int64_t strip_rows = (im.height + strips - 1) / strips;
  const int64_t items = strips * blocks;
  const int64_t wv = im.width - (kR - 1), hv = im.height - (kR - 1);
  const float inv_m = float(1.0 / (double(im.bands) * double(hv) * double(wv)));
  std::vector<Sums> partial(static_cast<size_t>(items));
  at::parallel_for(0, items, 1, [&](int64_t begin, int64_t end) {
    Scratch& s = scratch();
    s.x.resize(size_t(kR * im.width * kB));
    s.y.resize(s.x.size());
    s.v.resize(size_t(im.width * kMoments * kB));
    if (grad) {
      s.coeff.resize(size_t(kR * wv * kCoeffs * kB));
      s.u.resize(size_t(wv * kCoeffs * kB));
    }
    for (int64_t item = begin; item < end; ++item) {
      const int64_t strip = item / blocks, block = item % blocks;
      const int64_t c0 = block * kB;
      const Item<kB> work{im, window, grad,  c0, int(std::min<int64_t>(kB, im.bands - c0)),
                          wv, hv,     inv_m, s};
      const int64_t r0 = strip * strip_rows, r1 = std::min(im.height, r0 + strip_rows);
      if (r0 < r1) partial[size_t(item)] = work.run(r0, r1);
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
  if (im.bands <= 8) return run_blocks<8>(im, grad);
  return run_blocks<16>(im, grad);
}

}  // namespace ddhgs::model::ssim_kernel
