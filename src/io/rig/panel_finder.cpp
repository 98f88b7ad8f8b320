#include "io/rig/panel_finder.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>

#include "core/error.h"

namespace ddhgs::io {

namespace {

// Sums of a [h, w] grid over (2r + 1)^2 windows clipped at the borders:
// window mean at each cell from an integral image.
std::vector<double> window_means(const std::vector<double>& grid, int64_t h, int64_t w, int64_t r) {
  std::vector<double> integral(size_t((h + 1) * (w + 1)), 0.0);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      integral[size_t((y + 1) * (w + 1) + x + 1)] =
          grid[size_t(y * w + x)] + integral[size_t(y * (w + 1) + x + 1)] +
          integral[size_t((y + 1) * (w + 1) + x)] - integral[size_t(y * (w + 1) + x)];
  std::vector<double> mean(grid.size());
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      const int64_t y0 = std::max<int64_t>(0, y - r), y1 = std::min(h, y + r + 1);
      const int64_t x0 = std::max<int64_t>(0, x - r), x1 = std::min(w, x + r + 1);
      const double sum = integral[size_t(y1 * (w + 1) + x1)] - integral[size_t(y0 * (w + 1) + x1)] -
                         integral[size_t(y1 * (w + 1) + x0)] + integral[size_t(y0 * (w + 1) + x0)];
      mean[size_t(y * w + x)] = sum / double((y1 - y0) * (x1 - x0));
    }
  return mean;
}

struct Candidate {
  int64_t cells = 0;
  double cx = 0, cy = 0;                   // centroid, grid cells
  double level = 0;                        // mean of its cells
  int64_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // bounding box, grid cells (inclusive)
};

// Extreme points of a mask along the diagonals: (x, y) top-left, top-right,
// bottom-right, bottom-left.
std::array<std::array<double, 2>, 4> diagonal_corners(const torch::Tensor& mask) {
  const torch::Tensor at = mask.nonzero().to(torch::kDouble);  // [n, 2] rows y, x
  const torch::Tensor y = at.select(1, 0), x = at.select(1, 1);
  auto point = [&](const torch::Tensor& score, bool largest) {
    const int64_t i = (largest ? score.argmax() : score.argmin()).item<int64_t>();
    return std::array<double, 2>{x[i].item<double>(), y[i].item<double>()};
  };
  return {point(x + y, false), point(x - y, true), point(x + y, true), point(x - y, false)};
}

}  // namespace

std::optional<PanelRegion> find_panel(const torch::Tensor& signal_in) {
  const torch::Tensor signal = signal_in.to(torch::kFloat).contiguous();
  const int64_t height = signal.size(0), width = signal.size(1);
  const float* s = signal.data_ptr<float>();
  // Blocks of f x f pixels, about 240 across the shorter side.
  const int64_t f = std::max<int64_t>(1, std::min(height, width) / 240);
  const int64_t h = height / f, w = width / f;
  if (h < 12 || w < 12) return std::nullopt;
  std::vector<double> grid(size_t(h * w), 0.0), squares(size_t(h * w));
  for (int64_t y = 0; y < h * f; ++y)
    for (int64_t x = 0; x < w * f; ++x) grid[size_t((y / f) * w + x / f)] += s[y * width + x];
  for (size_t i = 0; i < grid.size(); ++i) {
    grid[i] /= double(f * f);
    squares[i] = grid[i] * grid[i];
  }
  constexpr int64_t kRadius = 2;  // 5 x 5 blocks
  const std::vector<double> mean = window_means(grid, h, w, kRadius);
  const std::vector<double> mean_sq = window_means(squares, h, w, kRadius);
  std::vector<double> sorted = grid;
  const size_t top = std::min(sorted.size() - 1, size_t(0.995 * double(sorted.size())));
  std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(top), sorted.end());
  const double bright = sorted[top];
  if (!(bright > 0)) return std::nullopt;
  std::vector<uint8_t> even(grid.size(), 0);
  for (size_t i = 0; i < grid.size(); ++i) {
    const double spread = std::sqrt(std::max(0.0, mean_sq[i] - mean[i] * mean[i]));
    even[i] = mean[i] > 0.25 * bright && spread < 0.03 * mean[i];
  }

  // Connected regions of even, bright windows; the largest compact one.
  std::vector<int32_t> label(grid.size(), 0);
  std::optional<Candidate> best;
  std::deque<int64_t> queue;
  int32_t next = 0;
  for (int64_t start = 0; start < h * w; ++start) {
    if (!even[size_t(start)] || label[size_t(start)]) continue;
    label[size_t(start)] = ++next;
    queue.push_back(start);
    Candidate c;
    c.x0 = c.x1 = start % w;
    c.y0 = c.y1 = start / w;
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, level = 0;
    while (!queue.empty()) {
      const int64_t at = queue.front();
      queue.pop_front();
      const int64_t x = at % w, y = at / w;
      ++c.cells;
      sx += double(x), sy += double(y);
      sxx += double(x * x), syy += double(y * y), sxy += double(x * y);
      level += grid[size_t(at)];
      c.x0 = std::min(c.x0, x), c.x1 = std::max(c.x1, x);
      c.y0 = std::min(c.y0, y), c.y1 = std::max(c.y1, y);
      const int64_t next_cells[4] = {x > 0 ? at - 1 : -1, x + 1 < w ? at + 1 : -1,
                                     y > 0 ? at - w : -1, y + 1 < h ? at + w : -1};
      for (int64_t n : next_cells)
        if (n >= 0 && even[size_t(n)] && !label[size_t(n)]) {
          label[size_t(n)] = next;
          queue.push_back(n);
        }
    }
    // Too small to be the panel of a panel capture: under 6 x 6 blocks, or a
    // side under 6 % of the image's shorter side (a panel is shot from
    // about a metre and fills a fifth of the frame or more).
    const double min_side = std::max(6.0, 0.06 * double(std::min(h, w)));
    if (double(c.cells) < min_side * min_side) continue;
    const double n = double(c.cells);
    c.cx = sx / n, c.cy = sy / n, c.level = level / n;
    // Second moments of the region (each cell a unit square: + 1/12).
    const double vxx = sxx / n - c.cx * c.cx + 1.0 / 12;
    const double vyy = syy / n - c.cy * c.cy + 1.0 / 12;
    const double vxy = sxy / n - c.cx * c.cy;
    const double det = vxx * vyy - vxy * vxy;
    const double half_trace = 0.5 * (vxx + vyy);
    const double root = std::sqrt(std::max(0.0, half_trace * half_trace - det));
    const double major = half_trace + root, minor = half_trace - root;
    if (!(det > 0 && minor > 0)) continue;
    const double rectangle_fill = n / (12 * std::sqrt(det));  // 1 for any rectangle
    const double aspect = std::sqrt(major / minor);
    if (aspect > 1.5 || rectangle_fill < 0.85 || rectangle_fill > 1.15) continue;
    if (!best || c.cells > best->cells) best = c;
  }
  if (!best) return std::nullopt;

  // Grow the panel at full resolution from the candidate's centre, within its
  // box and a margin of two windows.
  const double level = best->level;
  const int64_t margin = 2 * (2 * kRadius + 1) * f;
  const int64_t bx0 = std::max<int64_t>(0, best->x0 * f - margin);
  const int64_t by0 = std::max<int64_t>(0, best->y0 * f - margin);
  const int64_t bx1 = std::min(width, (best->x1 + 1) * f + margin);
  const int64_t by1 = std::min(height, (best->y1 + 1) * f + margin);
  auto like_panel = [&](int64_t i) { return std::abs(s[i] - level) <= 0.25 * level; };
  int64_t seed = int64_t(std::lround((best->cy + 0.5) * double(f))) * width +
                 int64_t(std::lround((best->cx + 0.5) * double(f)));
  if (!like_panel(seed)) {  // a speck at the centre: start from the nearest like pixel
    double nearest = 1e300;
    for (int64_t y = by0; y < by1; ++y)
      for (int64_t x = bx0; x < bx1; ++x) {
        const double d = std::hypot(double(x) - (best->cx + 0.5) * double(f),
                                    double(y) - (best->cy + 0.5) * double(f));
        if (d < nearest && like_panel(y * width + x)) nearest = d, seed = y * width + x;
      }
    if (!like_panel(seed)) return std::nullopt;
  }
  torch::Tensor panel = torch::zeros({height, width}, torch::kUInt8);
  uint8_t* p = panel.data_ptr<uint8_t>();
  p[seed] = 1;
  queue.assign(1, seed);
  int64_t panel_pixels = 0;
  while (!queue.empty()) {
    const int64_t at = queue.front();
    queue.pop_front();
    ++panel_pixels;
    const int64_t x = at % width, y = at / width;
    const int64_t around[4] = {x > bx0 ? at - 1 : -1, x + 1 < bx1 ? at + 1 : -1,
                               y > by0 ? at - width : -1, y + 1 < by1 ? at + width : -1};
    for (int64_t n : around)
      if (n >= 0 && !p[n] && like_panel(n)) {
        p[n] = 1;
        queue.push_back(n);
      }
  }
  // Its middle two thirds: pixels whose (2m + 1)^2 neighbourhood is all
  // panel, from an integral image of the panel's pixels.
  const double side = std::sqrt(double(panel_pixels));
  const int64_t m = std::max<int64_t>(1, int64_t(std::lround(side / 6)));
  std::vector<int32_t> integral(size_t((height + 1) * (width + 1)), 0);
  for (int64_t y = 0; y < height; ++y)
    for (int64_t x = 0; x < width; ++x)
      integral[size_t((y + 1) * (width + 1) + x + 1)] =
          int32_t(p[y * width + x]) + integral[size_t(y * (width + 1) + x + 1)] +
          integral[size_t((y + 1) * (width + 1) + x)] - integral[size_t(y * (width + 1) + x)];
  torch::Tensor inner = torch::zeros({height, width}, torch::kBool);
  bool* in = inner.data_ptr<bool>();
  const int32_t full_window = int32_t((2 * m + 1) * (2 * m + 1));
  for (int64_t y = std::max<int64_t>(m, by0); y < std::min(height - m, by1); ++y)
    for (int64_t x = std::max<int64_t>(m, bx0); x < std::min(width - m, bx1); ++x) {
      const int64_t y0 = y - m, y1 = y + m + 1, x0 = x - m, x1 = x + m + 1;
      const int32_t sum =
          integral[size_t(y1 * (width + 1) + x1)] - integral[size_t(y0 * (width + 1) + x1)] -
          integral[size_t(y1 * (width + 1) + x0)] + integral[size_t(y0 * (width + 1) + x0)];
      in[y * width + x] = sum == full_window;
    }
  PanelRegion region;
  region.mask = inner;
  region.pixels = region.mask.sum().item<int64_t>();
  if (region.pixels < 50) return std::nullopt;
  region.panel_side_px = side;
  region.corners = diagonal_corners(region.mask);
  return region;
}

std::string panel_region_source(const PanelRegion& region) {
  return !region.found           ? "given (--panel-region)"
         : !region.label.empty() ? "placed from its QR label"
                                 : "found";
}

PanelRegion panel_region_from_box(int64_t height, int64_t width, const std::array<int64_t, 4>& box,
                                  const std::string& what) {
  const auto [x, y, w, h] = box;
  if (w <= 0 || h <= 0 || x < 0 || y < 0 || x + w > width || y + h > height)
    throw core::Error(what, "the region " + std::to_string(x) + "," + std::to_string(y) + "," +
                                std::to_string(w) + "," + std::to_string(h) +
                                " (x, y, width, height) does not lie inside the " +
                                std::to_string(width) + " x " + std::to_string(height) + " image");
  PanelRegion region;
  region.mask = torch::zeros({height, width}, torch::kBool);
  region.mask.slice(0, y, y + h).slice(1, x, x + w).fill_(true);
  region.pixels = w * h;
  region.corners = {std::array<double, 2>{double(x), double(y)},
                    {double(x + w - 1), double(y)},
                    {double(x + w - 1), double(y + h - 1)},
                    {double(x), double(y + h - 1)}};
  region.found = false;
  return region;
}

}  // namespace ddhgs::io
