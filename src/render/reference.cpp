#include "render/reference.h"

#include "render/project.h"
#include "render/tiles.h"

namespace ddhgs::render {
namespace {

using torch::Tensor;
using torch::indexing::Slice;

// [G, 3, 3] rotation matrices of normalised quaternions (w, x, y, z).
Tensor quat_to_rotation(const Tensor& quats) {
  const Tensor q = quats / quats.norm(2, 1, true);
  const Tensor w = q.select(1, 0), x = q.select(1, 1), y = q.select(1, 2), z = q.select(1, 3);
  return torch::stack({1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                       2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)},
                      1)
      .view({-1, 3, 3});
}

}  // namespace

RenderOutput rasterize_reference(const Tensor& means, const Tensor& log_scales, const Tensor& quats,
                                 const Tensor& logit_opacities, const Tensor& colors,
                                 const RenderCamera& cam, const Tensor& background) {
  const auto f64 = torch::kFloat64;
  const int64_t g = means.size(0);
  const Tensor w2c =
      torch::from_blob(const_cast<float*>(cam.world_to_camera), {4, 4}, torch::kFloat32).to(f64);
  const Tensor view = w2c.index({Slice(0, 3), Slice(0, 3)});
  const Tensor mc = means.to(f64).matmul(view.t()) + w2c.index({Slice(0, 3), 3});
  const Tensor z = mc.select(1, 2);
  const Tensor front = z > cam.near_plane;
  const Tensor zs = torch::where(front, z, torch::ones_like(z));
  const Tensor tx = mc.select(1, 0) / zs, ty = mc.select(1, 1) / zs;
  const Tensor means2d = torch::where(front.unsqueeze(1),
                                      torch::stack({cam.fx * tx + cam.cx, cam.fy * ty + cam.cy}, 1),
                                      torch::zeros({g, 2}, f64));

  // EWA: cov2 = J view Sigma view^T J^T + 0.3 I, with x/z, y/z clamped in J.
  const auto lim = jacobian_clamp_limits(cam);
  const Tensor rx = tx.clamp(-lim[0], lim[1]), ry = ty.clamp(-lim[2], lim[3]);
  const Tensor zero = torch::zeros_like(z);
  const Tensor jac =
      torch::stack({cam.fx / zs, zero, -cam.fx * rx / zs, zero, cam.fy / zs, -cam.fy * ry / zs}, 1)
          .view({g, 2, 3});
  const Tensor rot = quat_to_rotation(quats.to(f64));
  const Tensor m = rot * log_scales.to(f64).exp().unsqueeze(1);
  const Tensor sigma = m.matmul(m.transpose(1, 2));
  const Tensor t = jac.matmul(view);
  const Tensor cov2 = t.matmul(sigma).matmul(t.transpose(1, 2)) + 0.3 * torch::eye(2, f64);
  const Tensor a = cov2.select(1, 0).select(1, 0), b = cov2.select(1, 0).select(1, 1),
               c = cov2.select(1, 1).select(1, 1);
  const Tensor det = a * c - b * b;
  const Tensor det_safe = torch::where(det > 0, det, torch::ones_like(det));
  const Tensor con_a = c / det_safe, con_b = -b / det_safe, con_c = a / det_safe;

  // Culling and radii (piecewise constant, no gradient).
  Tensor radii = torch::zeros({g}, torch::kInt32);
  std::vector<TileRect> rects(g);
  {
    torch::NoGradGuard no_grad;
    const Tensor mid = 0.5 * (a + c);
    const Tensor lambda = mid + (mid * mid - det).clamp_min(0.1).sqrt();
    const Tensor radius = (3.0 * lambda.sqrt()).ceil();
    const Tensor uv = means2d.to(torch::kFloat32).to(f64);  // the fast path bins float means
    const int tiles_x = tiles_along(cam.width), tiles_y = tiles_along(cam.height);
    for (int64_t i = 0; i < g; ++i) {
      rects[i] = {0, 0, 0, 0};
      if (!front[i].item<bool>() || !(det[i].item<double>() > 0)) continue;
      const TileRect r = tile_rect(uv[i][0].item<double>(), uv[i][1].item<double>(),
                                   radius[i].item<double>(), tiles_x, tiles_y);
      if (r.empty()) continue;
      rects[i] = r;
      radii[i] = int32_t(radius[i].item<double>());
    }
  }

  // Every pixel against every Gaussian, Gaussians in (float) depth order.
  const int64_t w = cam.width, h = cam.height;
  const Tensor ys = torch::arange(h, f64).view({h, 1}).expand({h, w}).reshape({-1});
  const Tensor xs = torch::arange(w, f64).view({1, w}).expand({h, w}).reshape({-1});
  Tensor in_rect = torch::zeros({h * w, g}, torch::kBool);
  for (int64_t i = 0; i < g; ++i) {
    const TileRect& r = rects[i];
    const Tensor tx_pix = (xs / kTileSize).floor(), ty_pix = (ys / kTileSize).floor();
    in_rect.select(1, i).copy_((tx_pix >= r.x0) & (tx_pix < r.x1) & (ty_pix >= r.y0) &
                               (ty_pix < r.y1));
  }
  const Tensor dx = means2d.select(1, 0).unsqueeze(0) - (xs + 0.5).unsqueeze(1);
  const Tensor dy = means2d.select(1, 1).unsqueeze(0) - (ys + 0.5).unsqueeze(1);
  const Tensor power = 0.5 * (con_a * dx * dx + con_c * dy * dy) + con_b * dx * dy;
  const Tensor opacity = torch::sigmoid(logit_opacities.to(f64).view({g}));
  Tensor alpha = (opacity * (-power).exp()).clamp_max(0.99);
  alpha = torch::where(in_rect & (alpha >= 1.0 / 255.0), alpha, torch::zeros_like(alpha));

  const Tensor order = std::get<1>(z.to(torch::kFloat32).sort(true, 0, false));
  alpha = alpha.index_select(1, order);
  // A pixel stops before the Gaussian that would take T below 1e-4.
  const Tensor keep = (1 - alpha.detach()).cumprod(1) >= 1e-4;
  alpha = alpha * keep;
  const Tensor one_minus = 1 - alpha;
  const Tensor trans_incl = one_minus.cumprod(1);
  const Tensor trans =
      torch::cat({torch::ones({h * w, 1}, f64), trans_incl.index({Slice(), Slice(0, g - 1)})}, 1)
          .index({Slice(), Slice(0, g)});
  const Tensor weight = alpha * trans;
  const Tensor final_t = g > 0 ? trans_incl.select(1, g - 1) : torch::ones({h * w}, f64);
  const Tensor cols = colors.to(f64).index_select(0, order);
  const Tensor image = weight.matmul(cols) + final_t.unsqueeze(1) * background.to(f64);
  const Tensor depth = weight.matmul(z.index_select(0, order));
  return {image.view({h, w, -1}), (1 - final_t).view({h, w}), depth.view({h, w}), radii, means2d};
}

}  // namespace ddhgs::render
