// Kept apart from gaussians.cpp so code that only needs the parameters (PLY
// conversion, optimizers) links without the rasterizer.
#include "model/gaussians.h"

namespace ddhgs::model {

render::RenderOutput render_gaussians(const Gaussians& gaussians, const core::Camera& camera,
                                      const torch::Tensor& background,
                                      const torch::Tensor& encoder_output,
                                      const torch::Tensor& means2d_grad_sink,
                                      const render::ShRestSink& sh_rest_sink) {
  core::Vec3 c = camera.center();
  auto center = torch::tensor({float(c.x), float(c.y), float(c.z)});
  // A degree-0 model has an empty rest tensor; eval_sh takes that as undefined.
  torch::Tensor rest = gaussians.sh_rest.defined() && gaussians.sh_rest.size(2) > 0
                           ? gaussians.sh_rest
                           : torch::Tensor();
  const ColourModel colour = gaussians.colour.with_encoder(encoder_output);
  torch::Tensor colors =
      render::eval_sh(gaussians.sh_dc, rest, gaussians.means, center, gaussians.active_sh_degree,
                      colour.sh_offsets(encoder_output),
                      rest.defined() ? sh_rest_sink : render::ShRestSink(), colour.linear_sh());
  render::RenderOutput out = render::rasterize(
      gaussians.means, gaussians.log_scales, gaussians.quats, gaussians.logit_opacities, colors,
      render::RenderCamera::from(camera), colour.blend_background(background), means2d_grad_sink);
  out.image = colour.decode(out.image, out.alpha, background);
  return out;
}

}  // namespace ddhgs::model
