// Validation and the autograd wrapper around project -> bin -> blend.
#include "render/rasterize.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "core/error.h"
#include "core/stage_timer.h"
#include "core/threads.h"
#include "render/blend.h"
#include "render/project.h"
#include "render/tiles.h"

namespace ddhgs::render {
namespace {

using torch::Tensor;
using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

std::string shape_of(const Tensor& t) {
  std::ostringstream s;
  s << t.sizes();
  return s.str();
}

// Every value finite. Float32 contiguous tensors (what training passes) are
// checked in place: torch::isfinite would first build a [numel] bool tensor,
// which took ~15 % of a forward at 100k x 128 colours.
bool all_finite(const Tensor& t) {
  if (t.scalar_type() != torch::kFloat32 || !t.is_contiguous())
    return torch::isfinite(t).all().item<bool>();
  const uint32_t* bits = static_cast<const uint32_t*>(t.data_ptr());
  constexpr uint32_t kExponent = 0x7f800000u;  // all ones: infinity or NaN
  uint32_t worst = 0;
  for (int64_t i = 0, n = t.numel(); i < n; ++i) worst = std::max(worst, bits[i] & kExponent);
  return worst != kExponent;
}

void require_shape(const Tensor& t, const char* name, std::initializer_list<int64_t> dims,
                   const std::string& expected) {
  core::require(t.defined(), std::string("rasterize: ") + name + " is missing");
  bool ok = t.dim() == int64_t(dims.size());
  int i = 0;
  for (int64_t d : dims) {
    ok = ok && (d < 0 || t.size(i) == d);
    ++i;
  }
  core::require(ok, std::string("rasterize: ") + name + " must have shape " + expected + ", got " +
                        shape_of(t));
  core::require(t.device().is_cpu() && t.is_floating_point(),
                std::string("rasterize: ") + name + " must be a floating-point CPU tensor");
  core::require(t.numel() == 0 || all_finite(t),
                std::string("rasterize: ") + name + " contains NaN or infinite values");
}

void validate(const Tensor& means, const Tensor& log_scales, const Tensor& quats,
              const Tensor& logit_opacities, const Tensor& colors, const RenderCamera& cam,
              const Tensor& background, const Tensor& sink) {
  require_shape(means, "means", {-1, 3}, "[G, 3]");
  const int64_t g = means.size(0);
  require_shape(log_scales, "log_scales", {g, 3}, "[G, 3] with G = " + std::to_string(g));
  require_shape(quats, "quats", {g, 4}, "[G, 4] (w, x, y, z)");
  require_shape(logit_opacities, "logit_opacities", {g, 1}, "[G, 1]");
  require_shape(colors, "colors", {g, -1}, "[G, N]");
  const int64_t n = colors.size(1);
  core::require(
      n >= 1, "rasterize: colors must have at least one channel (N >= 1), got " + shape_of(colors));
  require_shape(background, "background", {n}, "[N] with N = colors.size(1)");
  if (sink.defined()) require_shape(sink, "means2d_grad_sink", {g, 2}, "[G, 2]");
  if (g > 0) {
    core::require((quats.abs().sum(1) > 0).all().item<bool>(),
                  "rasterize: quats has a row with zero norm");
  }
  core::require(cam.width > 0 && cam.height > 0,
                "rasterize: camera image size must be positive, got " + std::to_string(cam.width) +
                    " x " + std::to_string(cam.height));
  bool finite = std::isfinite(cam.fx) && std::isfinite(cam.fy) && std::isfinite(cam.cx) &&
                std::isfinite(cam.cy) && std::isfinite(cam.near_plane);
  for (float v : cam.world_to_camera) finite = finite && std::isfinite(v);
  core::require(finite, "rasterize: camera has non-finite intrinsics or pose");
  core::require(cam.fx > 0 && cam.fy > 0, "rasterize: camera focal lengths must be positive");
  core::require(cam.near_plane > 0, "rasterize: camera near_plane must be positive");
}

// The camera travels to the backward as a list of doubles in saved_data.
std::vector<double> pack(const RenderCamera& c) {
  std::vector<double> v = {c.fx, c.fy, c.cx, c.cy, double(c.width), double(c.height), c.near_plane};
  v.insert(v.end(), c.world_to_camera, c.world_to_camera + 16);
  return v;
}

RenderCamera unpack(const std::vector<double>& v) {
  RenderCamera c;
  c.fx = float(v[0]), c.fy = float(v[1]), c.cx = float(v[2]), c.cy = float(v[3]);
  c.width = int(v[4]), c.height = int(v[5]), c.near_plane = float(v[6]);
  for (int i = 0; i < 16; ++i) c.world_to_camera[i] = float(v[7 + i]);
  return c;
}

TileBins& bins_for(const Projected& p, const RenderCamera& cam) {
  thread_local TileBins bins;  // capacity reused between calls
  bin_gaussians(p.means2d.data_ptr<float>(), p.conics.data_ptr<float>(),
                p.opacities.data_ptr<float>(), p.depths.data_ptr<float>(),
                p.radii.data_ptr<int32_t>(), p.means2d.size(0), cam.width, cam.height,
                core::thread_count(), bins);
  return bins;
}

class RasterizeFunction : public torch::autograd::Function<RasterizeFunction> {
 public:
  static variable_list forward(AutogradContext* ctx, const Tensor& means, const Tensor& log_scales,
                               const Tensor& quats, const Tensor& logit_opacities,
                               const Tensor& colors, const Tensor& background, const Tensor& sink,
                               const RenderCamera& cam) {
    core::StageScope stage("rasterize forward");
    Projected p = project_forward(means, log_scales, quats, logit_opacities, cam);
    BlendForward b =
        blend_forward(p, colors, background, bins_for(p, cam), cam.width, cam.height, true);
    ctx->saved_data["camera"] = pack(cam);
    ctx->saved_data["has_sink"] = sink.numel() > 0;
    ctx->save_for_backward({means, log_scales, quats, logit_opacities, colors, background,
                            p.means2d, p.conics, p.depths, p.opacities, p.radii, b.image, b.depth,
                            b.final_T});
    ctx->mark_non_differentiable({p.radii});
    return {b.image, b.alpha, b.depth, p.radii, p.means2d};
  }

  static variable_list backward(AutogradContext* ctx, variable_list grads) {
    core::StageScope stage("rasterize backward");
    const variable_list s = ctx->get_saved_variables();
    const RenderCamera cam = unpack(ctx->saved_data["camera"].toDoubleVector());
    const Projected p{s[6], s[7], s[8], s[9], s[10]};
    BlendForward fwd;
    fwd.image = s[11], fwd.depth = s[12], fwd.final_T = s[13];
    auto as_float = [](const Tensor& t) { return t.to(torch::kFloat32).contiguous(); };
    const BlendGrads bg =
        blend_backward(p, s[4], s[5], bins_for(p, cam), cam.width, cam.height, fwd,
                       as_float(grads[0]), as_float(grads[1]), as_float(grads[2]));
    const Tensor d_means2d = bg.means2d + as_float(grads[4]);
    const ProjectGrads pg = project_backward(s[0], s[1], s[2], s[3], cam, p, d_means2d, bg.conics,
                                             bg.depths, bg.opacities);
    const bool has_sink = ctx->saved_data["has_sink"].toBool();
    return {pg.means,
            pg.log_scales,
            pg.quats,
            pg.logit_opacities,
            bg.colors,
            bg.background,
            has_sink ? d_means2d : Tensor(),
            Tensor()};
  }
};

}  // namespace

RenderCamera RenderCamera::from(const core::Camera& camera) {
  const core::Intrinsics& in = camera.intrinsics;
  core::require(!in.has_distortion(),
                "rasterize: camera has lens distortion; the rasterizer is pinhole only "
                "(undistort the images first)");
  RenderCamera c;
  c.fx = float(in.fx), c.fy = float(in.fy), c.cx = float(in.cx), c.cy = float(in.cy);
  c.width = in.width, c.height = in.height;
  c.frame_x = in.frame_x, c.frame_y = in.frame_y;
  c.frame_width = in.frame_width, c.frame_height = in.frame_height;
  for (int i = 0; i < 16; ++i) c.world_to_camera[i] = float(camera.world_to_camera.m[i]);
  return c;
}

RenderOutput rasterize(const Tensor& means, const Tensor& log_scales, const Tensor& quats,
                       const Tensor& logit_opacities, const Tensor& colors,
                       const RenderCamera& camera, const Tensor& background,
                       const Tensor& means2d_grad_sink) {
  validate(means, log_scales, quats, logit_opacities, colors, camera, background,
           means2d_grad_sink);
  // Casts are recorded by autograd, so double inputs get double gradients.
  auto f32 = [](const Tensor& t) { return t.to(torch::kFloat32).contiguous(); };
  const Tensor m = f32(means), ls = f32(log_scales), q = f32(quats), lo = f32(logit_opacities),
               c = f32(colors), bgd = f32(background);
  const bool needs_grad = torch::GradMode::is_enabled() &&
                          (m.requires_grad() || ls.requires_grad() || q.requires_grad() ||
                           lo.requires_grad() || c.requires_grad() || bgd.requires_grad() ||
                           (means2d_grad_sink.defined() && means2d_grad_sink.requires_grad()));
  if (needs_grad) {
    // autograd::Function rejects undefined tensor inputs: an empty stand-in.
    const Tensor sink =
        means2d_grad_sink.defined() ? f32(means2d_grad_sink) : torch::empty({0}, torch::kFloat32);
    const variable_list out = RasterizeFunction::apply(m, ls, q, lo, c, bgd, sink, camera);
    return {out[0], out[1], out[2], out[3], out[4]};
  }
  // Validation renders: no autograd graph, nothing kept for a backward.
  Projected p = project_forward(m, ls, q, lo, camera);
  BlendForward b =
      blend_forward(p, c, bgd, bins_for(p, camera), camera.width, camera.height, false);
  return {b.image, b.alpha, b.depth, p.radii, p.means2d};
}

}  // namespace ddhgs::render
