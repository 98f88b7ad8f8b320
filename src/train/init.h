// Initial Gaussians for a scene: one per sparse point (colours from the
// points' spectra, else from the training views they project into, else
// grey), or random points inside the cameras' view volume.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <vector>

#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::train {

struct InitOptions {
  bool random = false;  // ignore the scene's points
  int64_t random_points = 100000;
  double opacity = 0.1;
  int neighbours = 3;    // for the initial scale
  int colour_views = 8;  // training views sampled to colour points without spectra
  int sh_degree = 3;     // size of sh_rest
  uint64_t seed = 0;
};

// Throws core::Error when the scene has no points and random is false.
model::Gaussians initialise_gaussians(const io::Scene& scene, const InitOptions& options);

// 3DGS's scene extent: 1.1 x the largest distance of a camera centre from
// their mean (scene units). Scales position learning rates and densification.
double scene_extent(const io::Scene& scene, const std::vector<int>& views);

// Uniform points along random pixel rays of the given views, at depths
// between 0.5 and 1.5 times the camera's distance to the point the cameras
// look at (least-squares closest point to their optical axes): [count, 3].
torch::Tensor sample_view_volume(const io::Scene& scene, const std::vector<int>& views,
                                 int64_t count, at::Generator& generator);

// Per-point values from the first sampled view that sees each point (pixel the
// point projects to, in front of the camera): [P, N], and a [P] bool "seen" mask.
std::pair<torch::Tensor, torch::Tensor> colours_from_views(const io::Scene& scene,
                                                           const std::vector<int>& views,
                                                           const torch::Tensor& xyz);  // [P, 3]

}  // namespace ddhgs::train
