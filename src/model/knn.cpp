#include "model/knn.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"

namespace ddhgs::model {

namespace {

// Points bucketed by cell, cells in x-fastest order: cell c holds
// order[start[c] .. start[c + 1]).
struct Grid {
  std::array<double, 3> lo{};
  double cell = 1;
  std::array<int64_t, 3> dims{1, 1, 1};
  std::vector<int64_t> start, order;

  int64_t coord(double v, int axis) const {
    auto c = int64_t(std::floor((v - lo[axis]) / cell));
    return std::clamp<int64_t>(c, 0, dims[axis] - 1);
  }
  int64_t index(int64_t x, int64_t y, int64_t z) const { return (z * dims[1] + y) * dims[0] + x; }
};

Grid build_grid(const float* p, int64_t n) {
  Grid g;
  std::array<double, 3> hi{};
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = std::numeric_limits<double>::max();
    hi[a] = std::numeric_limits<double>::lowest();
  }
  for (int64_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      g.lo[a] = std::min(g.lo[a], double(p[i * 3 + a]));
      hi[a] = std::max(hi[a], double(p[i * 3 + a]));
    }
  double extent = std::max({hi[0] - g.lo[0], hi[1] - g.lo[1], hi[2] - g.lo[2], 1e-12});
  // About two points per occupied cell for a cloud spread over a surface
  // (cells ~ n^(2/3) along a 2D sheet); the search widens where it is sparser.
  const double cells_per_axis = std::clamp(std::sqrt(double(n) / 2.0), 1.0, 1024.0);
  g.cell = extent / cells_per_axis;
  int64_t total = 1;
  for (int a = 0; a < 3; ++a) {
    g.dims[a] = std::max<int64_t>(1, int64_t(std::ceil((hi[a] - g.lo[a]) / g.cell)) + 1);
    total *= g.dims[a];
  }
  // A 3D-filling cloud with a fine grid would waste memory: coarsen.
  while (total > 8 * n + 64) {
    g.cell *= 2;
    total = 1;
    for (int a = 0; a < 3; ++a) {
      g.dims[a] = std::max<int64_t>(1, int64_t(std::ceil((hi[a] - g.lo[a]) / g.cell)) + 1);
      total *= g.dims[a];
    }
  }
  std::vector<int64_t> cell_of(n);
  g.start.assign(total + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    cell_of[i] = g.index(g.coord(p[i * 3], 0), g.coord(p[i * 3 + 1], 1), g.coord(p[i * 3 + 2], 2));
    ++g.start[cell_of[i] + 1];
  }
  for (int64_t c = 0; c < total; ++c) g.start[c + 1] += g.start[c];
  g.order.resize(n);
  std::vector<int64_t> fill(g.start.begin(), g.start.end() - 1);
  for (int64_t i = 0; i < n; ++i) g.order[fill[cell_of[i]]++] = i;
  return g;
}

}  // namespace

torch::Tensor mean_sq_distance_to_neighbours(const torch::Tensor& xyz_in, int k) {
  core::require(xyz_in.dim() == 2 && xyz_in.size(1) == 3, "knn: expected points [P, 3]");
  core::require(k >= 1, "knn: k must be positive");
  auto xyz = xyz_in.to(torch::kFloat32).contiguous();
  const int64_t n = xyz.size(0);
  auto out = torch::zeros({n}, torch::kFloat32);
  if (n < 2) return out;
  const float* p = xyz.data_ptr<float>();
  float* result = out.data_ptr<float>();
  const Grid g = build_grid(p, n);
  const int64_t kk = std::min<int64_t>(k, n - 1);
  const int64_t max_ring = std::max({g.dims[0], g.dims[1], g.dims[2]});

  core::parallel_for(0, n, 256, [&](int64_t begin, int64_t end) {
    std::vector<double> best;  // sorted ascending, at most kk squared distances
    for (int64_t i = begin; i < end; ++i) {
      best.clear();
      const double x = p[i * 3], y = p[i * 3 + 1], z = p[i * 3 + 2];
      const int64_t cx = g.coord(x, 0), cy = g.coord(y, 1), cz = g.coord(z, 2);
      for (int64_t ring = 0; ring <= max_ring; ++ring) {
        // Visit the shell of cells at Chebyshev distance `ring`.
        for (int64_t dz = -ring; dz <= ring; ++dz)
          for (int64_t dy = -ring; dy <= ring; ++dy)
            for (int64_t dx = -ring; dx <= ring; ++dx) {
              if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
              const int64_t ux = cx + dx, uy = cy + dy, uz = cz + dz;
              if (ux < 0 || uy < 0 || uz < 0 || ux >= g.dims[0] || uy >= g.dims[1] ||
                  uz >= g.dims[2])
                continue;
              const int64_t c = g.index(ux, uy, uz);
              for (int64_t s = g.start[c]; s < g.start[c + 1]; ++s) {
                const int64_t j = g.order[s];
                if (j == i) continue;
                const double ex = p[j * 3] - x, ey = p[j * 3 + 1] - y, ez = p[j * 3 + 2] - z;
                const double d2 = ex * ex + ey * ey + ez * ez;
                if (int64_t(best.size()) < kk || d2 < best.back()) {
                  best.insert(std::upper_bound(best.begin(), best.end(), d2), d2);
                  if (int64_t(best.size()) > kk) best.pop_back();
                }
              }
            }
        // Cells beyond this ring are at least ring * cell away from the point.
        const double reach = double(ring) * g.cell;
        if (int64_t(best.size()) == kk && best.back() <= reach * reach) break;
      }
      double sum = 0;
      for (double d : best) sum += d;
      result[i] = float(sum / double(best.size()));
    }
  });
  return out;
}

}  // namespace ddhgs::model
