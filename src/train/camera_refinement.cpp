#include "train/camera_refinement.h"

#include "core/error.h"
#include "model/rigid_motion.h"

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

std::pair<torch::Tensor, torch::Tensor> CameraRefinementImpl::move(int view,
                                                                   const core::Camera& camera,
                                                                   const torch::Tensor& means,
                                                                   const torch::Tensor& quats,
                                                                   double extent) const {
  const auto [r, t] = correction(view);
  return model::move_rigidly(means, quats, r, extent * t, camera.center());
}

}  // namespace ddhgs::train
