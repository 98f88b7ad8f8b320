#include "render/ranked.h"

#include "core/parallel.h"

#include <algorithm>
#include <cmath>

namespace ddhgs::render {

const Ranked& rank_gaussians(const Projected& p, const torch::Tensor& colors, const TileBins& bins,
                             int np) {
  thread_local Ranked cache;
  const int64_t visible = int64_t(bins.order.size()), n = colors.size(1);
  cache.splats.resize(visible);
  const bool copy = np != n;
  cache.padded.resize(copy ? size_t(visible) * np : 0);
  // Workers must write the caller's buffers, not their own thread_local ones.
  Splat* splats = cache.splats.data();
  float* ranked_colors = cache.padded.data();
  const int32_t* order = bins.order.data();
  const float* m = p.means2d.data_ptr<float>();
  const float* con = p.conics.data_ptr<float>();
  const float* op = p.opacities.data_ptr<float>();
  const float* dep = p.depths.data_ptr<float>();
  const float* col = colors.data_ptr<float>();
  // Records are filled in Gaussian order, reading the projection sequentially
  // and writing whole 64-byte records at their ranks (in rank order the reads
  // of five input arrays missed the cache).
  thread_local std::vector<int32_t> rank_of;
  rank_of.assign(size_t(colors.size(0)), -1);
  for (int32_t r = 0; r < int32_t(visible); ++r) rank_of[order[r]] = r;
  const int32_t* rank = rank_of.data();
  const SplatExtent* extents = bins.extents.data();
  core::parallel_for(0, colors.size(0), 2048, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const int64_t r = rank[i];
      if (r < 0) continue;
      if (copy) {
        std::copy(col + i * n, col + (i + 1) * n, ranked_colors + r * np);
        std::fill(ranked_colors + r * np + n, ranked_colors + (r + 1) * np, 0.0f);
      }
      Splat s;
      s.mx = m[2 * i], s.my = m[2 * i + 1];
      s.a = con[3 * i], s.b = con[3 * i + 1], s.c = con[3 * i + 2];
      s.opacity = op[i], s.depth = dep[i];
      set_extent(s, extents[i]);
      splats[r] = s;
    }
  });
  cache.rows = copy ? ranked_colors : col;
  cache.row_of_rank = copy ? nullptr : order;
  return cache;
}

}  // namespace ddhgs::render
