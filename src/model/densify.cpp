#include "model/densify.h"

#include <cmath>

namespace ddhgs::model {

namespace {

// Rebuilds every parameter from rows of the current ones (index[i] >= 0) and
// appended rows (`extra`, in order, where index[i] < 0), moving Adam moments.
void rebuild(Gaussians& gaussians, Adam& adam, const torch::Tensor& index,
             const std::vector<torch::Tensor>& extra) {
  torch::NoGradGuard no_grad;
  auto params = gaussians.tensors();
  const auto& names = Gaussians::tensor_names();
  auto kept = index.masked_select(index >= 0);
  for (size_t i = 0; i < params.size(); ++i) {
    torch::Tensor base = params[i]->detach().index_select(0, kept);
    torch::Tensor next = extra.empty() ? base : torch::cat({base, extra[i]}, 0);
    next = next.contiguous().requires_grad_(true);
    adam.remap_rows(names[i], next, index);
    *params[i] = next;
  }
}

torch::Tensor repeat_rows(const torch::Tensor& t, int64_t times) {
  std::vector<int64_t> reps(size_t(t.dim()), 1);
  reps[0] = times;
  return t.repeat(reps);
}

}  // namespace

void DensifyStats::reset(int64_t size) {
  grad_sum = torch::zeros({size}, torch::kFloat32);
  count = torch::zeros({size}, torch::kFloat32);
  max_radii = torch::zeros({size}, torch::kFloat32);
}

void DensifyStats::accumulate(const torch::Tensor& radii, const torch::Tensor& means2d_grad,
                              int width, int height) {
  torch::NoGradGuard no_grad;
  auto visible = radii > 0;
  auto scale = torch::tensor({0.5f * float(width), 0.5f * float(height)});
  auto norm = (means2d_grad.to(torch::kFloat32) * scale).norm(2, 1);
  auto v = visible.to(torch::kFloat32);
  grad_sum += norm * v;
  count += v;
  max_radii =
      torch::where(visible, torch::maximum(max_radii, radii.to(torch::kFloat32)), max_radii);
}

torch::Tensor quat_to_matrix(const torch::Tensor& quats) {
  auto q = quats / quats.norm(2, 1, true).clamp_min(1e-12);
  auto w = q.select(1, 0), x = q.select(1, 1), y = q.select(1, 2), z = q.select(1, 3);
  auto rows = torch::stack({1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)},
                           1);
  return rows.view({-1, 3, 3});
}

DensifyResult densify_and_prune(Gaussians& gaussians, Adam& adam, DensifyStats& stats,
                                const DensifyOptions& options, double scene_extent,
                                bool prune_large, at::Generator& generator) {
  torch::NoGradGuard no_grad;
  DensifyResult result;
  const int64_t g = gaussians.size();
  auto grads = stats.grad_sum / stats.count.clamp_min(1);
  auto max_scale = gaussians.log_scales.detach().exp().amax(1);
  auto candidate = grads >= options.grad_threshold;
  const double boundary = options.percent_dense * scene_extent;

  // Under a cap, grow the highest-gradient candidates first (a split adds one
  // Gaussian net, like a clone).
  if (options.max_gaussians > 0) {
    const int64_t budget = std::max<int64_t>(0, options.max_gaussians - g);
    const int64_t wanted = candidate.sum().item<int64_t>();
    if (wanted > budget) {
      auto ranked = std::get<1>(torch::where(candidate, grads, -1.0f).sort(0, true));
      candidate = torch::zeros_like(candidate);
      candidate.index_fill_(0, ranked.slice(0, 0, budget), true);
    }
  }
  auto clone = candidate & (max_scale <= boundary);
  auto split = candidate & (max_scale > boundary);
  auto clone_idx = clone.nonzero().squeeze(1);
  auto split_idx = split.nonzero().squeeze(1);
  result.cloned = clone_idx.size(0);
  result.split = split_idx.size(0);

  if (result.cloned + result.split > 0) {
    auto params = gaussians.tensors();
    std::vector<torch::Tensor> extra(params.size());
    for (size_t i = 0; i < params.size(); ++i) {
      auto cloned = params[i]->detach().index_select(0, clone_idx);
      auto children = repeat_rows(params[i]->detach().index_select(0, split_idx), 2);
      extra[i] = torch::cat({cloned, children}, 0);
    }
    // Children are drawn from the parent's Gaussian: mean + R (s * eps).
    const int64_t s = result.split;
    if (s > 0) {
      auto stds = repeat_rows(gaussians.log_scales.detach().index_select(0, split_idx).exp(), 2);
      auto rot =
          repeat_rows(quat_to_matrix(gaussians.quats.detach().index_select(0, split_idx)), 2);
      auto eps = torch::randn({2 * s, 3}, generator, torch::kFloat32);
      auto offsets = torch::bmm(rot, (eps * stds).unsqueeze(2)).squeeze(2);
      auto child_means = extra[0].slice(0, result.cloned);
      child_means.add_(offsets);
      extra[1].slice(0, result.cloned).sub_(std::log(1.6));
    }
    auto keep = ~split;
    auto index = torch::cat(
        {keep.nonzero().squeeze(1), torch::full({result.cloned + 2 * s}, -1, torch::kInt64)});
    rebuild(gaussians, adam, index, extra);
    // New rows have not been seen on screen yet; old rows keep their maxima.
    auto radii = torch::cat({stats.max_radii.masked_select(keep),
                             torch::zeros({result.cloned + 2 * s}, torch::kFloat32)});
    stats.max_radii = radii;
  }

  auto opacity = torch::sigmoid(gaussians.logit_opacities.detach().squeeze(1));
  auto prune = opacity < options.min_opacity;
  result.pruned_transparent = prune.sum().item<int64_t>();
  if (prune_large) {
    if (options.max_screen_px > 0) {
      auto screen = stats.max_radii > options.max_screen_px;
      result.pruned_screen = screen.sum().item<int64_t>();
      prune |= screen;
    }
    auto world =
        gaussians.log_scales.detach().exp().amax(1) > options.max_world_fraction * scene_extent;
    result.pruned_world = world.sum().item<int64_t>();
    prune |= world;
  }
  result.pruned = prune.sum().item<int64_t>();
  if (result.pruned > 0) keep_gaussians(gaussians, adam, ~prune);
  stats.reset(gaussians.size());
  return result;
}

void keep_gaussians(Gaussians& gaussians, Adam& adam, const torch::Tensor& keep) {
  rebuild(gaussians, adam, keep.nonzero().squeeze(1), {});
}

void reset_opacity(Gaussians& gaussians, Adam& adam, double max_opacity) {
  torch::NoGradGuard no_grad;
  const float cap = float(std::log(max_opacity / (1 - max_opacity)));
  gaussians.logit_opacities.clamp_max_(cap);
  adam.reset_moments("logit_opacities");
}

}  // namespace ddhgs::model
