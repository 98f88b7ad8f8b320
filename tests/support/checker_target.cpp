#include "support/checker_target.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace ddhgs::test {

namespace {

// The checker's template at pixel (row, col) for a centre (cx, cy): +1
// white, -1 dark, the pixel's area average across the axes, and the
// weight of the pixel (1 inside the target, falling to 0 at its edge).
struct Tap {
  double sign = 0, weight = 0;
};
Tap checker_tap(int64_t row, int64_t col, double cx, double cy, double half) {
  const double dx = double(col) + 0.5 - cx, dy = double(row) + 0.5 - cy;
  const double east = std::clamp(2 * dx, -1.0, 1.0), north = std::clamp(-2 * dy, -1.0, 1.0);
  return {-east * north, std::clamp(half - std::max(std::abs(dx), std::abs(dy)), 0.0, 1.0)};
}

}  // namespace

TargetFix find_checker_target(const std::function<double(int64_t row, int64_t col)>& value,
                              int64_t width, int64_t height, double col0, double row0, double half,
                              double search) {
  // Every candidate's score; the centre is the mean of those that tie with
  // the best (a target whose edges are resolved only to a fraction of a
  // pixel scores the same over that fraction).
  struct Candidate {
    double cx, cy, score, contrast;
  };
  std::vector<Candidate> candidates;
  double best_score = -std::numeric_limits<double>::max();
  const double step = 0.05;
  const int64_t steps = int64_t(std::ceil(search / step));
  for (int64_t iy = -steps; iy <= steps; ++iy)
    for (int64_t ix = -steps; ix <= steps; ++ix) {
      const double cx = col0 + double(ix) * step, cy = row0 + double(iy) * step;
      double score = 0, white = 0, dark = 0, white_w = 0, dark_w = 0;
      bool whole = true;
      for (int64_t row = int64_t(std::floor(cy - half)); row <= int64_t(cy + half) && whole; ++row)
        for (int64_t col = int64_t(std::floor(cx - half)); col <= int64_t(cx + half); ++col) {
          const Tap tap = checker_tap(row, col, cx, cy, half);
          if (tap.weight <= 0) continue;
          const double v =
              row < 0 || col < 0 || row >= height || col >= width ? NAN : value(row, col);
          if (std::isnan(v)) {
            whole = false;
            break;
          }
          score += tap.weight * tap.sign * v;
          if (std::abs(tap.sign) > 0.99) {
            (tap.sign > 0 ? white : dark) += tap.weight * v;
            (tap.sign > 0 ? white_w : dark_w) += tap.weight;
          }
        }
      if (!whole) continue;
      candidates.push_back(
          {cx, cy, score, white / std::max(white_w, 1e-12) - dark / std::max(dark_w, 1e-12)});
      best_score = std::max(best_score, score);
    }
  TargetFix best;
  double n = 0;
  for (const Candidate& c : candidates)
    if (c.score >= best_score - 1e-6 * std::abs(best_score)) {
      best.col += c.cx;
      best.row += c.cy;
      best.contrast += c.contrast;
      n += 1;
    }
  if (n == 0) return best;
  best.col /= n;
  best.row /= n;
  best.contrast /= n;
  best.found = true;
  return best;
}

}  // namespace ddhgs::test
