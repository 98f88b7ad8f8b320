#include "train/camera_refinement.h"

#include "core/error.h"
#include "model/densify.h"

namespace ddhgs::train {

CameraRefinementImpl::CameraRefinementImpl(int64_t views, std::vector<int> train) {
  core::require(views > 0 && !train.empty(), "camera refinement: no training views");
  rotation = register_parameter("rotation", torch::zeros({views, 3}));
  translation = register_parameter("translation", torch::zeros({views, 3}));
  for (int v : train) core::require(v >= 0 && v < views, "camera refinement: view out of range");
  train_ = torch::tensor(std::vector<int64_t>(train.begin(), train.end()), torch::kInt64);
}

std::pair<torch::Tensor, torch::Tensor> CameraRefinementImpl::correction(int view) const {
  return {rotation[view], translation[view]};
}

void CameraRefinementImpl::recentre() {
  torch::NoGradGuard no_grad;
  for (torch::Tensor* p : {&rotation, &translation})
    p->index_add_(0, train_, -p->index_select(0, train_).mean(0, true).expand({train_.size(0), 3}));
}

torch::Tensor rotation_vector_quat(const torch::Tensor& r) {
  // sqrt(|r|^2 + tiny) keeps the gradient finite at r = 0, where
  // sin(theta / 2) / theta tends to 1/2.
  const torch::Tensor theta = (r.pow(2).sum() + 1e-20).sqrt();
  return torch::cat({(0.5 * theta).cos().view({1}), r * ((0.5 * theta).sin() / theta)});
}

torch::Tensor quat_multiply(const torch::Tensor& a, const torch::Tensor& b) {
  const auto aw = a[0], ax = a[1], ay = a[2], az = a[3];
  const auto bw = b.select(1, 0), bx = b.select(1, 1), by = b.select(1, 2), bz = b.select(1, 3);
  return torch::stack(
      {aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
       aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw},
      1);
}

std::pair<torch::Tensor, torch::Tensor> CameraRefinementImpl::move(int view,
                                                                   const core::Camera& camera,
                                                                   const torch::Tensor& means,
                                                                   const torch::Tensor& quats,
                                                                   double extent) const {
  const auto [r, t] = correction(view);
  const torch::Tensor q = rotation_vector_quat(r);
  const torch::Tensor rot = model::quat_to_matrix(q.unsqueeze(0))[0];  // [3, 3]
  const core::Vec3 c = camera.center();
  const torch::Tensor centre = torch::tensor({float(c.x), float(c.y), float(c.z)});
  const torch::Tensor moved = torch::matmul(means - centre, rot.t()) + (centre + extent * t);
  return {moved, quat_multiply(q, quats)};
}

}  // namespace ddhgs::train
