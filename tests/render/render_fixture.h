// Random Gaussian scenes for the rasterizer tests, including the awkward
// cases: behind the camera, off-screen, needle-thin, huge, nearly transparent,
// and an opaque stack that makes pixels hit the 1e-4 transmittance stop.
#pragma once
#include "core/tensor.h"

#include <algorithm>
#include <string>

#include "core/camera.h"
#include "render/rasterize.h"

namespace ddhgs::test {

struct SplatScene {
  torch::Tensor means, log_scales, quats, logit_opacities, colors, background;
  render::RenderCamera camera;

  std::vector<torch::Tensor> params() const {
    return {means, log_scales, quats, logit_opacities, colors, background};
  }
  // Copies with requires_grad, converted to dtype.
  SplatScene leaves(torch::ScalarType dtype) const {
    SplatScene s = *this;
    for (torch::Tensor* t :
         {&s.means, &s.log_scales, &s.quats, &s.logit_opacities, &s.colors, &s.background})
      *t = t->to(dtype).detach().clone().set_requires_grad(true);
    return s;
  }
};

inline core::Camera test_core_camera(int width, int height) {
  core::Camera cam;
  cam.intrinsics.width = width, cam.intrinsics.height = height;
  cam.intrinsics.fx = 0.9 * width, cam.intrinsics.fy = 0.85 * width;
  cam.intrinsics.cx = 0.47 * width, cam.intrinsics.cy = 0.53 * height;
  cam.world_to_camera = core::look_at({0.3, -0.4, -4.0}, {0, 0, 0}, {0, -1, 0});
  return cam;
}

// g Gaussians (at least 17), n channels, width x height pixels, seeded.
inline SplatScene random_scene(int seed, int g, int n, int width, int height) {
  torch::manual_seed(seed);
  const auto f = torch::kFloat32;
  const core::Camera cam = test_core_camera(width, height);
  auto world = [&](double x, double y, double z) {  // camera-space point -> world tensor
    const core::Vec3 p = cam.camera_to_world().transform_point({x, y, z});
    return torch::tensor({float(p.x), float(p.y), float(p.z)});
  };
  SplatScene s;
  s.camera = render::RenderCamera::from(cam);
  s.means = (torch::rand({g, 3}, f) - 0.5) * 3.0;
  s.log_scales = torch::rand({g, 3}, f) * 1.5 - 3.2;
  s.quats = torch::randn({g, 4}, f);
  s.logit_opacities = torch::randn({g, 1}, f) * 2.0;
  s.colors = torch::rand({g, n}, f);
  s.background = torch::rand({n}, f) * 0.5;
  // Awkward cases on fixed rows.
  s.means[0] = world(0.0, 0.0, -1.0);     // behind the camera
  s.means[1] = world(0.002, 0.0, 0.005);  // just behind the near plane (0.01)
  s.means[2] = world(9.0, 0.0, 3.0);      // far off-screen right
  s.means[3] = world(0.0, -3.5, 4.0);     // off-screen but large: clamped Jacobian
  s.log_scales[3] = torch::tensor({0.0f, -0.2f, 0.1f});
  s.means[16] = world(0.01, 0.02, 0.08);  // just in front of the near plane: huge
  s.log_scales[16] = torch::full({3}, -4.0f, f);
  s.log_scales[4] = torch::tensor({-1.0f, -7.0f, -1.0f});  // needle-thin
  s.log_scales[5] = torch::tensor({0.3f, 0.2f, 0.4f});     // very large
  s.logit_opacities[6] = torch::tensor({-5.4f});           // nearly transparent
  s.logit_opacities[7] = torch::tensor({-9.0f});           // below 1/255 everywhere
  for (int i = 8; i < 16; ++i) {  // an opaque stack: pixels stop at T < 1e-4
    s.means[i] = torch::tensor({0.1f * (i - 12), 0.05f * (i - 12), 0.2f * (i - 8)});
    s.log_scales[i] = torch::full({3}, -1.2f, f);
    s.logit_opacities[i] = torch::tensor({i % 2 == 0 ? 3.0f : 6.0f});  // some clamp at 0.99
  }
  return s;
}

// max |a - b| / max |b|: the error relative to the tensor's scale.
inline double scaled_error(const torch::Tensor& a, const torch::Tensor& b) {
  const torch::Tensor bd = b.to(torch::kFloat64);
  const double scale = std::max(bd.abs().max().item<double>(), 1e-30);
  return (a.to(torch::kFloat64) - bd).abs().max().item<double>() / scale;
}

}  // namespace ddhgs::test
