// Nearest-neighbour distances of a point cloud through a uniform grid, for
// initial Gaussian scales: O(P) on surface-like clouds instead of O(P^2).
#pragma once
#include "core/tensor.h"

namespace ddhgs::model {

// Mean squared distance from each point to its k nearest other points,
// [P] float32 (as 3DGS initialises scales: sqrt of this). Points with fewer
// than k others use what there is; a single point gets 0.
torch::Tensor mean_sq_distance_to_neighbours(const torch::Tensor& xyz,  // [P, 3]
                                             int k = 3);

}  // namespace ddhgs::model
