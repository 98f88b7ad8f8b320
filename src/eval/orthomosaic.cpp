#include "eval/orthomosaic.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"
#include "core/log.h"

namespace ddhgs::eval {

namespace {

constexpr int64_t kOrthoMaxSide = 40000;  // pixels: 1.6 G pixels a band

// The CRS height of every Gaussian centre, float64 [G].
torch::Tensor crs_heights(const model::Gaussians& gaussians, const io::Georeference& georef) {
  const core::Similarity& s = georef.scene_to_crs;
  const core::Vec3 up = georef.scene_up();
  const torch::Tensor means = gaussians.means.detach().to(torch::kFloat64);
  const torch::Tensor dir = torch::tensor({up.x, up.y, up.z}, torch::kFloat64);
  return means.matmul(dir) * s.scale + s.translation.z;
}

}  // namespace

Ground model_ground(const model::Gaussians& gaussians, const io::Georeference& georef) {
  core::require(gaussians.size() > 0, "orthomosaic: the model has no Gaussians");
  const torch::Tensor h = crs_heights(gaussians, georef);
  Ground g;
  g.height_m = h.median().item<double>();
  const torch::Tensor distance = (h - g.height_m).abs();
  // kthvalue, not quantile: quantile refuses tensors of over 16 M values.
  const int64_t k = std::max<int64_t>(1, int64_t(std::ceil(0.999 * double(distance.numel()))));
  g.relief_m = std::get<0>(distance.kthvalue(k)).item<double>();
  return g;
}

OrthoGrid flight_grid(const io::Scene& scene, const io::Georeference& georef, const Ground& ground,
                      double gsd_m) {
  const core::Similarity& s = georef.scene_to_crs;
  double left = std::numeric_limits<double>::max(), right = -left, bottom = left, top = -left;
  std::vector<double> own;
  for (const io::View& view : scene.views) {
    const core::Intrinsics& k = view.camera.intrinsics;
    const core::Mat4 c2w = view.camera.camera_to_world();
    const core::Vec3 eye = s.apply(c2w.translation());
    core::require(eye.z > ground.height_m, scene.root,
                  "view " + view.name + " is not above the ground (camera at " +
                      core::format_g(eye.z) + " m, ground at " + core::format_g(ground.height_m) +
                      " m): no orthomosaic");
    for (double u : {0.0, double(k.width)})
      for (double v : {0.0, double(k.height)}) {
        const core::Vec3 d =
            s.rotation * (c2w.rotation() * core::Vec3{(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1});
        core::require(d.z < -1e-3 * d.norm(), scene.root,
                      "view " + view.name +
                          " sees above the horizon: its footprint on the ground is unbounded");
        const core::Vec3 hit = eye + d * ((ground.height_m - eye.z) / d.z);
        left = std::min(left, hit.x);
        right = std::max(right, hit.x);
        bottom = std::min(bottom, hit.y);
        top = std::max(top, hit.y);
      }
    own.push_back((eye.z - ground.height_m) / k.fx);
  }
  core::require(!own.empty(), scene.root, "the scene has no views: no footprint");
  std::nth_element(own.begin(), own.begin() + own.size() / 2, own.end());
  OrthoGrid grid;
  grid.gsd_m = gsd_m > 0 ? gsd_m : own[own.size() / 2];
  grid.left_m = std::floor(left / grid.gsd_m) * grid.gsd_m;
  grid.top_m = std::ceil(top / grid.gsd_m) * grid.gsd_m;
  const double width = std::ceil((right - grid.left_m) / grid.gsd_m);
  const double height = std::ceil((grid.top_m - bottom) / grid.gsd_m);
  core::require(width <= double(kOrthoMaxSide) && height <= double(kOrthoMaxSide),
                "--gsd " + core::format_g(grid.gsd_m) + " m makes a " + core::format_g(width) +
                    " x " + core::format_g(height) + " pixel orthomosaic; at most " +
                    std::to_string(kOrthoMaxSide) + " a side: give a larger --gsd");
  grid.width = std::max<int64_t>(1, int64_t(width));
  grid.height = std::max<int64_t>(1, int64_t(height));
  return grid;
}

core::Camera ortho_tile_camera(const OrthoGrid& grid, const io::Georeference& georef,
                               const Ground& ground, int64_t tile_col, int64_t tile_row) {
  const core::Similarity& s = georef.scene_to_crs;
  const int64_t x0 = tile_col * kOrthoTile, y0 = tile_row * kOrthoTile;
  const int w = int(std::min<int64_t>(kOrthoTile, grid.width - x0));
  const int h = int(std::min<int64_t>(kOrthoTile, grid.height - y0));
  // The largest displacement r h / (D - h) at the tile's corner stays under
  // kOrthoParallaxPx: D = h (1 + r / limit), h the relief (at least a GSD).
  const double corner_px = 0.5 * std::hypot(double(w), double(h));
  const double relief = std::max(ground.relief_m, grid.gsd_m);
  const double distance_m = relief * (1 + corner_px / kOrthoParallaxPx);
  const core::Vec3 centre{grid.left_m + (double(x0) + 0.5 * w) * grid.gsd_m,
                          grid.top_m - (double(y0) + 0.5 * h) * grid.gsd_m,
                          ground.height_m + distance_m};
  // Camera axes in the CRS: x east, y south, z down (A = diag(1, -1, -1));
  // a scene point p is at A (s R p + t - centre) / s in camera units.
  core::Mat3 a;
  a(1, 1) = -1;
  a(2, 2) = -1;
  const core::Mat3 rotation = a * s.rotation;
  const core::Vec3 translation = (a * (s.translation - centre)) * (1 / s.scale);
  core::Camera camera;
  camera.world_to_camera = core::Mat4::from(rotation, translation);
  core::Intrinsics& k = camera.intrinsics;
  k.width = w;
  k.height = h;
  k.fx = k.fy = distance_m / grid.gsd_m;
  k.cx = 0.5 * w;
  k.cy = 0.5 * h;
  return camera;
}

Orthomosaic render_orthomosaic(const model::Gaussians& gaussians, const io::Georeference& georef,
                               const OrthoGrid& grid, const Ground& ground,
                               const torch::Tensor& background) {
  torch::NoGradGuard no_grad;
  core::require(background.dim() == 1 && background.size(0) == gaussians.bands(),
                "orthomosaic: the background needs one value per band of the model");
  Orthomosaic out;
  out.alpha = torch::zeros({grid.height, grid.width}, torch::kFloat32);
  const torch::Tensor bg = background.detach().to(torch::kFloat32).contiguous();
  const int64_t cols = (grid.width + kOrthoTile - 1) / kOrthoTile;
  const int64_t rows = (grid.height + kOrthoTile - 1) / kOrthoTile;
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t c = 0; c < cols; ++c) {
      const core::Camera camera = ortho_tile_camera(grid, georef, ground, c, r);
      const render::RenderOutput tile = model::render_gaussians(gaussians, camera, bg);
      const int64_t y0 = r * kOrthoTile, x0 = c * kOrthoTile;
      const int64_t h = camera.intrinsics.height, w = camera.intrinsics.width;
      if (!out.image.defined())  // M bands: N, or an output map's
        out.image = torch::zeros({grid.height, grid.width, tile.image.size(2)}, torch::kFloat32);
      out.image.slice(0, y0, y0 + h).slice(1, x0, x0 + w).copy_(tile.image);
      out.alpha.slice(0, y0, y0 + h).slice(1, x0, x0 + w).copy_(tile.alpha);
    }
  return out;
}

}  // namespace ddhgs::eval
