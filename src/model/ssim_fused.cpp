#include "model/ssim_fused.h"

#include <string>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/stage_timer.h"
#include "model/ssim.h"
#include "model/ssim_kernel.h"

namespace ddhgs::model {
namespace {

using torch::Tensor;
using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

ssim_kernel::Images images_of(const Tensor& render, const Tensor& target) {
  return {render.data_ptr<float>(), target.data_ptr<float>(), render.size(0), render.size(1),
          render.size(2)};
}

// grad <- ssim_weight * grad + l1_weight * sign(render - target), in place.
void combine(float* grad, const float* render, const float* target, int64_t n, float ssim_weight,
             float l1_weight) {
  core::parallel_for(0, n, 1 << 16, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const float d = render[i] - target[i];
      // sign(0) = 0, as the derivative LibTorch gives abs at 0.
      const float sign = float(d > 0) - float(d < 0);
      grad[i] = ssim_weight * grad[i] + l1_weight * sign;
    }
  });
}

class L1SsimFunction : public torch::autograd::Function<L1SsimFunction> {
 public:
  // render, target: contiguous float32 [H, W, N]. Returns {l1, ssim}, 0-d.
  static variable_list forward(AutogradContext* ctx, const Tensor& render, const Tensor& target) {
    core::StageScope stage("l1+ssim forward");
    // Written by the kernel, scaled and handed to autograd by backward.
    Tensor grad = core::pooled_empty(render.sizes());
    const ssim_kernel::Sums sums =
        ssim_kernel::run(images_of(render, target), grad.data_ptr<float>());
    ctx->save_for_backward({render, target, grad});
    ctx->saved_data["consumed"] = false;
    const double pixels = double(render.numel());
    const double windows =
        double(render.size(2)) * double(render.size(0) - 10) * double(render.size(1) - 10);
    return {torch::tensor(float(sums.l1 / pixels)), torch::tensor(float(sums.ssim / windows))};
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    core::StageScope stage("l1+ssim backward");
    // The SSIM gradient buffer is scaled in place, so it serves one backward.
    core::require(!ctx->saved_data["consumed"].toBool(),
                  "l1_and_ssim: backward through the graph a second time is not supported");
    ctx->saved_data["consumed"] = true;
    const variable_list saved = ctx->get_saved_variables();
    const Tensor &render = saved[0], &target = saved[1];
    Tensor grad = saved[2];
    auto weight = [](const Tensor& g) { return g.defined() ? g.item<float>() : 0.0f; };
    combine(grad.data_ptr<float>(), render.data_ptr<float>(), target.data_ptr<float>(),
            grad.numel(), weight(grads[1]), weight(grads[0]) / float(render.numel()));
    return {grad, Tensor()};
  }
};

}  // namespace

PhotometricValues l1_and_ssim(const Tensor& render, const Tensor& target) {
  core::require(render.dim() == 3 && render.sizes() == target.sizes(),
                "l1_and_ssim: expected two [H, W, N] images of the same shape");
  core::require(render.size(0) >= kSsimWindow && render.size(1) >= kSsimWindow,
                "l1_and_ssim: images must be at least 11 x 11 pixels, got " +
                    std::to_string(render.size(1)) + " x " + std::to_string(render.size(0)));
  core::require(!target.requires_grad(),
                "l1_and_ssim: the target must not require a gradient (use model::ssim)");
  auto f32 = [](const Tensor& t) { return t.to(torch::kFloat32).contiguous(); };
  const Tensor a = f32(render), b = f32(target.detach());
  if (torch::GradMode::is_enabled() && a.requires_grad()) {
    const variable_list out = L1SsimFunction::apply(a, b);
    return {out[0], out[1]};
  }
  const ssim_kernel::Sums sums = ssim_kernel::run(images_of(a, b), nullptr);
  const double windows = double(a.size(2)) * double(a.size(0) - 10) * double(a.size(1) - 10);
  return {torch::tensor(float(sums.l1 / double(a.numel()))),
          torch::tensor(float(sums.ssim / windows))};
}

}  // namespace ddhgs::model
