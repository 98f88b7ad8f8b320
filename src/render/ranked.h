// Visible Gaussians in depth-rank order, the blender's per-call view of the
// projected scene. Internal to the render layer.
#pragma once
#include "core/tensor.h"

#include <cstdint>
#include <vector>

#include "render/aligned.h"
#include "render/project.h"
#include "render/splat_row.h"
#include "render/tiles.h"

namespace ddhgs::render {

// Visible Gaussians in depth-rank order: tiles walk the splat records
// forwards through memory instead of jumping between random rows. Colour rows
// are read in place when N is already a multiple of the vector width (copying
// [G, N] costs ~8 % of a forward at N = 128) and otherwise copied into padded
// rows in rank order.
struct Ranked {
  std::vector<Splat> splats;    // [V]
  AlignedVector<float> padded;  // [V, np] when colours are copied
  const float* rows;            // colour rows, np floats apart
  const int32_t* row_of_rank;   // [V] row of each rank; null: row = rank

  const float* row(int32_t rank, int np) const {
    return rows + size_t(row_of_rank ? row_of_rank[rank] : rank) * np;
  }
};

// Fills a thread_local Ranked (capacity reused between calls) from the
// projection; colors: [G, N] contiguous float32, np: N padded to the vector
// width.
const Ranked& rank_gaussians(const Projected& p, const torch::Tensor& colors, const TileBins& bins,
                             int np);

}  // namespace ddhgs::render
