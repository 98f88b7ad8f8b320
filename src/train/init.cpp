#include "train/init.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/log.h"
#include "core/spectral_pca.h"
#include "io/scene/scene_report.h"
#include "model/knn.h"

namespace ddhgs::train {

namespace {

std::vector<int> spread(const std::vector<int>& views, int count) {
  if (count <= 0 || int(views.size()) <= count) return views;
  std::vector<int> out;
  for (int i = 0; i < count; ++i) out.push_back(views[size_t(i) * views.size() / size_t(count)]);
  return out;
}

core::Vec3 look_at_point(const io::Scene& scene, const std::vector<int>& views) {
  // Solve sum (I - d d^T) x = sum (I - d d^T) c over the optical axes.
  double a[3][3] = {{0}}, b[3] = {0};
  core::Vec3 mean;
  for (int v : views) {
    const core::Camera& cam = scene.views[v].camera;
    core::Vec3 c = cam.center(), d = cam.forward();
    mean = mean + c * (1.0 / double(views.size()));
    double dd[3] = {d.x, d.y, d.z}, cc[3] = {c.x, c.y, c.z};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        double m = (i == j ? 1.0 : 0.0) - dd[i] * dd[j];
        a[i][j] += m;
        b[i] += m * cc[j];
      }
  }
  core::Mat3 m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = a[i][j];
  const double det = m.determinant();
  if (std::abs(det) < 1e-6 * double(views.size() * views.size() * views.size())) {
    // Parallel axes (a forward-facing capture): look one extent ahead.
    core::Vec3 forward;
    for (int v : views) forward = forward + scene.views[v].camera.forward();
    return mean + forward.normalized() * std::max(scene_extent(scene, views), 1.0);
  }
  // Cramer's rule on the 3x3 system.
  core::Vec3 x;
  double* out[3] = {&x.x, &x.y, &x.z};
  for (int k = 0; k < 3; ++k) {
    core::Mat3 mk = m;
    for (int i = 0; i < 3; ++i) mk(i, k) = b[i];
    *out[k] = mk.determinant() / det;
  }
  return x;
}

// Tangent of the half-angle from the optical axis to an image corner.
double corner_tan(const core::Intrinsics& k) {
  return std::hypot(0.5 * k.width / k.fx, 0.5 * k.height / k.fy);
}

// The radius of what the views see at the distance of the point they look
// at (scene units), averaged over the views.
double field_radius(const io::Scene& scene, const std::vector<int>& views,
                    const core::Vec3& target) {
  double sum = 0;
  for (int v : views) {
    const core::Camera& cam = scene.views[v].camera;
    sum += (target - cam.center()).norm() * corner_tan(cam.intrinsics);
  }
  return sum / double(views.size());
}

}  // namespace

torch::Tensor sample_view_volume(const io::Scene& scene, const std::vector<int>& views,
                                 int64_t count, at::Generator& generator) {
  core::require(!views.empty(), scene.root, "no training views");
  const core::Vec3 target = look_at_point(scene, views);
  const double radius = field_radius(scene, views, target);
  auto u = torch::rand({count, 4}, generator, torch::kFloat64);
  auto ua = u.accessor<double, 2>();
  auto out = torch::empty({count, 3}, torch::kFloat32);
  auto oa = out.accessor<float, 2>();
  for (int64_t i = 0; i < count; ++i) {
    const int v = views[std::min(size_t(ua[i][0] * double(views.size())), views.size() - 1)];
    const core::Camera& cam = scene.views[v].camera;
    const auto& k = cam.intrinsics;
    const double px = ua[i][1] * k.width, py = ua[i][2] * k.height;
    const core::Vec3 dir_cam{(px - k.cx) / k.fx, (py - k.cy) / k.fy, 1.0};
    const core::Vec3 c = cam.center();
    const double distance = std::max((target - c).norm(), 1e-3);
    // z-depth along the camera axis, so points fill the frustum slab: as deep
    // as the field is wide, at most half the distance either side.
    const double half_depth = std::min(0.5 * distance, radius);
    const double depth = distance + half_depth * (2 * ua[i][3] - 1);
    const core::Vec3 p = cam.camera_to_world().transform_point(dir_cam * depth);
    oa[i][0] = float(p.x);
    oa[i][1] = float(p.y);
    oa[i][2] = float(p.z);
  }
  return out;
}

double view_direction_spread_deg(const io::Scene& scene, const std::vector<int>& views) {
  std::vector<core::Vec3> forward;
  core::Vec3 mean{0, 0, 0};
  for (int v : views) {
    // The camera's +z axis in world coordinates: the third row of R (w2c).
    const core::Mat3 r = scene.views[size_t(v)].camera.world_to_camera.rotation();
    forward.push_back(core::Vec3{r(2, 0), r(2, 1), r(2, 2)}.normalized());
    mean = mean + forward.back();
  }
  if (mean.norm() < 1e-9) return 180;
  mean = mean.normalized();
  double widest = 0;
  for (const core::Vec3& f : forward)
    widest = std::max(widest, std::acos(std::clamp(f.dot(mean), -1.0, 1.0)) * 180 / M_PI);
  return widest;
}

std::pair<torch::Tensor, torch::Tensor> colours_from_views(const io::Scene& scene,
                                                           const std::vector<int>& views,
                                                           const torch::Tensor& xyz) {
  const int64_t p = xyz.size(0), n = scene.bands();
  auto colours = torch::zeros({p, n}, torch::kFloat32);
  auto seen = torch::zeros({p, n}, torch::kBool);
  auto points = xyz.to(torch::kFloat32).contiguous();
  auto xa = points.accessor<float, 2>();
  auto sa = seen.accessor<bool, 2>();
  for (int v : views) {
    const core::Camera& cam = scene.views[v].camera;
    const auto& k = cam.intrinsics;
    torch::Tensor image = scene.image(v);  // [H, W, the view's bands]
    const std::vector<int>& held = scene.views[v].bands;
    std::vector<int64_t> bands(held.begin(), held.end());
    if (bands.empty())
      for (int64_t b = 0; b < n; ++b) bands.push_back(b);
    std::vector<int64_t> rows, pixels;
    for (int64_t i = 0; i < p; ++i) {
      // Each band of a point takes its colour from the first view that sees it.
      if (std::all_of(bands.begin(), bands.end(), [&](int64_t b) { return sa[i][b]; })) continue;
      const core::Vec3 q = cam.world_to_camera.transform_point(
          core::Vec3{double(xa[i][0]), double(xa[i][1]), double(xa[i][2])});
      if (q.z <= 1e-6) continue;
      const double u = k.fx * q.x / q.z + k.cx, w = k.fy * q.y / q.z + k.cy;
      if (u < 0 || w < 0 || u >= k.width || w >= k.height) continue;
      rows.push_back(i);
      pixels.push_back(int64_t(w) * image.size(1) + int64_t(u));
    }
    if (rows.empty()) continue;
    const auto row_t = torch::tensor(rows, torch::kInt64);
    const auto band_t = torch::tensor(bands, torch::kInt64);
    const auto values = image.reshape({-1, image.size(2)})
                            .index_select(0, torch::tensor(pixels, torch::kInt64));  // [R, b]
    // Only the bands not yet seen change.
    const auto old = colours.index_select(0, row_t).index_select(1, band_t);
    const auto fresh = ~seen.index_select(0, row_t).index_select(1, band_t);
    const auto merged = torch::where(fresh, values, old);
    for (size_t j = 0; j < bands.size(); ++j)
      colours.select(1, bands[j]).index_copy_(0, row_t, merged.select(1, int64_t(j)).contiguous());
    for (int64_t i : rows)
      for (int64_t b : bands) sa[i][b] = true;
  }
  return {colours, seen};
}

model::Gaussians initialise_gaussians(const io::Scene& scene, const InitOptions& options,
                                      const model::ColourModel& colour) {
  const int64_t n = scene.bands();
  core::require(n > 0, scene.root, "the scene has no bands");
  auto generator = at::make_generator<at::CPUGeneratorImpl>(options.seed);
  torch::Tensor xyz, values;
  const bool has_points = scene.points.xyz.defined() && scene.points.xyz.size(0) > 0;
  if (options.random || !has_points) {
    xyz = sample_view_volume(scene, scene.train, options.random_points, generator);
    values = torch::full({xyz.size(0), n}, 0.5f);
    core::log_warn("initialising " + std::to_string(xyz.size(0)) +
                   " Gaussians at random inside the cameras' view volume" +
                   (options.random ? "" : " (the dataset has no points)"));
  } else {
    xyz = scene.points.xyz.to(torch::kFloat32).contiguous();
    const auto& spectra = scene.points.spectra;
    const auto& rgb = scene.points.rgb;
    if (spectra.defined() && spectra.size(1) == n) {
      values = spectra.to(torch::kFloat32);
    } else if (n == 3 && rgb.defined()) {
      values = rgb.to(torch::kFloat32) / 255.0f;
    } else {
      auto [colours, seen] = colours_from_views(
          scene,
          // A band-per-view scene's sample would miss bands: every view.
          scene.band_per_view() ? scene.train : spread(scene.train, options.colour_views), xyz);
      values = torch::where(seen, colours, torch::full_like(colours, 0.5f));
      const int64_t unseen = xyz.size(0) - seen.any(1).sum().item<int64_t>();
      if (unseen > 0)
        core::log_info(std::to_string(unseen) + " of " + std::to_string(xyz.size(0)) +
                       " points are outside the sampled views; they start grey");
    }
    int64_t count = 0;
    if (!scene.train.empty()) {
      const auto& first = scene.views[scene.train.front()].camera.intrinsics;
      count =
          std::llround(options.extra_random_per_pixel * double(first.width) * double(first.height));
    }
    if (count > 0 && scene.train.size() >= 2) {
      const double spread = view_direction_spread_deg(scene, scene.train);
      if (spread < kOneSidedSpreadDeg) {
        char text[160];
        std::snprintf(text, sizeof text,
                      "the training views all look within %.1f degrees of one direction (a "
                      "one-sided capture): no extra random points",
                      spread);
        core::log_info(text);
        count = 0;
      }
    }
    if (count > 0) {
      auto extra = sample_view_volume(scene, scene.train, count, generator);
      xyz = torch::cat({xyz, extra});
      values = torch::cat({values, torch::full({extra.size(0), n}, 0.5f)});
      core::log_info("added " + std::to_string(extra.size(0)) +
                     " random Gaussians inside the cameras' view volume to the dataset's " +
                     std::to_string(xyz.size(0) - extra.size(0)) + " points");
    }
  }
  const int64_t g = xyz.size(0);
  model::Gaussians gaussians;
  gaussians.means = xyz.clone();
  auto dist2 = model::mean_sq_distance_to_neighbours(xyz, options.neighbours).clamp_min(1e-7f);
  gaussians.log_scales = (0.5f * dist2.log()).unsqueeze(1).repeat({1, 3}).contiguous();
  gaussians.quats = torch::zeros({g, 4});
  gaussians.quats.select(1, 0).fill_(1.0f);
  const double logit = std::log(options.opacity / (1 - options.opacity));
  gaussians.logit_opacities = torch::full({g, 1}, float(logit));
  gaussians.colour = colour;
  gaussians.sh_dc = colour.sh_dc_for(values.clamp(0, 1)).to(torch::kFloat32).contiguous();
  const int k = (options.sh_degree + 1) * (options.sh_degree + 1) - 1;
  gaussians.sh_rest = torch::zeros({g, colour.channels(n), k});
  gaussians.active_sh_degree = 0;
  for (torch::Tensor* t : gaussians.tensors()) t->requires_grad_(true);
  return gaussians;
}

}  // namespace ddhgs::train

namespace ddhgs::train {

namespace {
std::string percent(double share) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f", 100 * share);
  return text;
}
}  // namespace

model::ColourModel initial_colour_model(const io::Scene& scene, int spectral_rank,
                                        int subspace_from_bands) {
  const int64_t n = scene.bands();
  if (spectral_rank < 0 && n < subspace_from_bands) {
    core::log_info("colour model: one SH set per band (" + std::to_string(n) +
                   " bands, below model.subspace_from_bands " +
                   std::to_string(subspace_from_bands) + ")");
    return {};
  }
  if (spectral_rank == 0) return {};
  // The basis comes from whole pixel spectra, which no view of a
  // band-per-view scene holds.
  if (scene.band_per_view()) {
    if (spectral_rank > 0)
      throw core::Error(scene.root,
                        "is a band-per-view scene (each view holds some of the bands): its pixels "
                        "give no whole spectra for a subspace basis; use model.spectral_rank=0");
    core::log_info(
        "colour model: one SH set per band (a band-per-view scene has no whole "
        "spectra for a subspace basis)");
    return {};
  }
  if (spectral_rank > n)
    throw core::Error(scene.root, "model.spectral_rank " + std::to_string(spectral_rank) +
                                      " is above the scene's " + std::to_string(n) +
                                      " bands (0 for one SH set per band)");
  const io::SpectraSample sample = io::sample_spectra(scene);
  const core::SpectralPca pca = core::spectral_pca(sample.spectra);
  int64_t k = spectral_rank;
  if (k < 0) {
    k = std::clamp<int64_t>(core::whitened_signal_rank(sample.spectra, sample.noise_sigma), 1, n);
  }
  core::log_info("colour model: " + std::to_string(k) + " latent channels for " +
                 std::to_string(n) + " bands (a basis from the principal components of " +
                 std::to_string(sample.spectra.size(0)) + " pixels of " +
                 std::to_string(sample.views) + " training views, holding " + percent(pca.kept(k)) +
                 " % of their variance)");
  return model::latent_from_pca(pca, k);
}

model::ColourModel resumed_colour_model(const io::Scene& scene, int64_t rank) {
  const int64_t n = scene.bands();
  if (rank == 0) {
    core::log_info("colour model: one SH set per band (" + std::to_string(n) +
                   " bands, from the checkpoint)");
    return {};
  }
  core::log_info("colour model: " + std::to_string(rank) + " latent channels for " +
                 std::to_string(n) + " bands (basis and mean from the checkpoint)");
  model::ColourModel colour;
  colour.basis = torch::zeros({n, rank});
  colour.mean = torch::zeros({n});
  return colour;
}

}  // namespace ddhgs::train
