#include "synth/render.h"

#include <algorithm>
#include <cmath>

#include "core/distortion.h"
#include "core/error.h"
#include "core/parallel.h"

namespace ddhgs::synth {

using core::Vec3;

SpectralSetup make_spectral_setup(const PlantScene& scene,
                                  const std::vector<double>& wavelengths_nm,
                                  const NoiseModel& noise, const Lighting& lighting) {
  SpectralSetup setup;
  setup.wavelengths_nm = wavelengths_nm;
  setup.noise = noise;
  setup.lighting = lighting;
  const int n = int(wavelengths_nm.size());
  auto spectra = scene.material_spectra();
  setup.reflectance.resize(spectra.size() * n);
  for (size_t m = 0; m < spectra.size(); ++m)
    for (int b = 0; b < n; ++b) setup.reflectance[m * n + b] = float(spectra[m](wavelengths_nm[b]));

  std::vector<double> lamp_response(n);
  double brightest = 1e-12;
  for (int b = 0; b < n; ++b) {
    setup.response.push_back(sensor_response(wavelengths_nm[b]));
    lamp_response[b] =
        lamp_power(wavelengths_nm[b], lighting.lamp_temperature_k) * setup.response[b];
    // The scene's own materials set the gain; the targets' paint does
    // not, so printing targets changes no other pixel.
    for (size_t m = 0; m < size_t(scene.scene_materials()); ++m) {
      double light = m == kBackground ? lighting.backdrop : lighting.ambient + lighting.sun;
      brightest = std::max(brightest, setup.reflectance[m * n + b] * light * lamp_response[b]);
    }
  }
  for (int b = 0; b < n; ++b)
    setup.band_gain.push_back(float(0.85 * lighting.exposure * lamp_response[b] / brightest));
  return setup;
}

RigOptions rig_options(const SynthConfig& config) {
  RigOptions rig;
  rig.views = config.views;
  rig.rings = config.rings;
  rig.min_elevation_deg = config.min_elevation_deg;
  rig.max_elevation_deg = config.max_elevation_deg;
  rig.fov_deg = config.fov_deg;
  rig.width = config.width;
  rig.height = config.height;
  rig.fill = config.fill;
  rig.k1 = config.k1;
  return rig;
}

core::Intrinsics rig_intrinsics(const RigOptions& options) {
  core::Intrinsics intr;
  intr.width = options.width;
  intr.height = options.height;
  intr.fx = intr.fy =
      core::focal_from_fov(options.fov_deg * 3.14159265358979323846 / 180, options.width);
  intr.cx = 0.5 * options.width;
  intr.cy = 0.5 * options.height;
  intr.k1 = options.k1;
  return intr;
}

std::vector<core::Camera> turntable_rig(const PlantScene& scene, const RigOptions& options) {
  core::require(options.views >= 1 && options.rings >= 1 && options.width > 0 &&
                    options.height > 0 && options.fov_deg > 0 && options.fov_deg < 170,
                "synth: expected views >= 1, rings >= 1, a positive size and 0 < fov < 170 deg");
  const double deg = 3.14159265358979323846 / 180;
  const int rings = std::min(options.rings, options.views);
  std::vector<double> elevation(rings), weight(rings);
  double total_weight = 0;
  for (int r = 0; r < rings; ++r) {
    double f = rings == 1 ? 0.5 : double(r) / (rings - 1);
    elevation[r] =
        (options.min_elevation_deg + f * (options.max_elevation_deg - options.min_elevation_deg)) *
        deg;
    weight[r] = std::cos(elevation[r]);  // ring circumference
    total_weight += weight[r];
  }
  std::vector<int> per_ring(rings);
  int assigned = 0;
  for (int r = 0; r < rings; ++r) {
    per_ring[r] = std::max(1, int(std::floor(options.views * weight[r] / total_weight)));
    assigned += per_ring[r];
  }
  for (int r = 0; assigned != options.views; r = (r + 1) % rings) {
    int step = assigned < options.views ? 1 : (per_ring[r] > 1 ? -1 : 0);
    per_ring[r] += step;
    assigned += step;
  }

  const core::Intrinsics intr = rig_intrinsics(options);
  // Same distance for every ring: the farthest at which the plant's box, seen
  // from any ring, fills the requested fraction of the frame.
  const Vec3 half = (scene.box_max - scene.box_min) * 0.5;
  const double r_xy = std::max(half.x, half.y);
  const double tan_x = std::tan(options.fill * std::atan(0.5 * options.width / intr.fx));
  const double tan_y = std::tan(options.fill * std::atan(0.5 * options.height / intr.fy));
  double distance = 0;
  for (double e : elevation) {
    double half_height = half.z * std::cos(e) + r_xy * std::sin(e);
    distance = std::max({distance, r_xy / tan_x + 0.25 * r_xy, half_height / tan_y + 0.25 * r_xy});
  }

  std::vector<core::Camera> cameras;
  Vec3 target = scene.centre();
  for (int r = 0; r < rings; ++r)
    for (int i = 0; i < per_ring[r]; ++i) {
      // Rings are offset by a fraction of their spacing so azimuths interleave.
      double azimuth = 2 * 3.14159265358979323846 * (i + double(r) / rings) / per_ring[r];
      Vec3 dir{std::cos(elevation[r]) * std::cos(azimuth),
               std::cos(elevation[r]) * std::sin(azimuth), std::sin(elevation[r])};
      core::Camera camera;
      camera.intrinsics = intr;
      camera.world_to_camera = core::look_at(target + dir * distance, target, Vec3{0, 0, 1});
      cameras.push_back(camera);
    }
  return cameras;
}

Ray camera_ray(const core::Camera& camera, double x, double y) {
  const auto& k = camera.intrinsics;
  core::Mat4 c2w = camera.camera_to_world();
  const core::Point2 n = core::undistort(k, {(x - k.cx) / k.fx, (y - k.cy) / k.fy});
  Vec3 d{n.x, n.y, 1.0};
  return {c2w.translation(), (c2w.rotation() * d).normalized()};
}

namespace {

// The clean signal [H, W, N] of the rays ray_at(x, y) hands back for pixel
// positions (x, y), supersample x supersample of them per pixel.
template <typename RayAt>
torch::Tensor render_rays(const PlantScene& scene, const SpectralSetup& setup, int w, int h,
                          int supersample, const RayAt& ray_at) {
  const int n = setup.bands();
  const int ss = std::max(1, supersample);
  auto out = torch::empty({h, w, n}, torch::kFloat32);
  float* data = out.data_ptr<float>();
  const Lighting& light = setup.lighting;
  const Vec3 l = light.to_light.normalized();
  const float* table = setup.reflectance.data();
  core::parallel_for(0, h, 1, [&](int64_t y0, int64_t y1) {
    std::vector<float> acc(n);
    for (int64_t y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        std::fill(acc.begin(), acc.end(), 0.0f);
        for (int sy = 0; sy < ss; ++sy)
          for (int sx = 0; sx < ss; ++sx) {
            const Ray ray = ray_at(x + (sx + 0.5) / ss, y + (sy + 0.5) / ss);
            SurfaceHit hit;
            if (!scene.intersect(ray, &hit)) {
              const float* bg = table + kBackground * n;
              for (int b = 0; b < n; ++b) acc[b] += float(light.backdrop) * bg[b];
              continue;
            }
            double cos_l = hit.normal.dot(l);
            double visible = cos_l > 0 && !scene.occluded({hit.point + hit.normal * 1e-4, l}, 1e30);
            double diffuse = light.ambient + light.sun * std::max(cos_l, 0.0) * visible;
            double specular = 0;
            if (visible && hit.specular > 0) {
              Vec3 half = (l - ray.dir).normalized();
              specular = hit.specular * light.sun *
                         std::pow(std::max(hit.normal.dot(half), 0.0), hit.shininess);
            }
            const float* ra = table + hit.material_a * n;
            const float* rb = table + hit.material_b * n;
            const float wa = float(diffuse * (1 - hit.mix)), wb = float(diffuse * hit.mix);
            const float spec = float(specular);
            for (int b = 0; b < n; ++b) acc[b] += wa * ra[b] + wb * rb[b] + spec;
          }
        float* px = data + (y * w + x) * n;
        const float norm = 1.0f / float(ss * ss);
        for (int b = 0; b < n; ++b)
          px[b] = std::clamp(acc[b] * norm * setup.band_gain[b], 0.0f, 1.0f);
      }
  });
  return out;
}

}  // namespace

torch::Tensor render_clean(const PlantScene& scene, const SpectralSetup& setup,
                           const core::Camera& camera, int supersample) {
  return render_rays(scene, setup, camera.intrinsics.width, camera.intrinsics.height, supersample,
                     [&camera](double x, double y) { return camera_ray(camera, x, y); });
}

torch::Tensor render_orthographic(const PlantScene& scene, const SpectralSetup& setup,
                                  const OrthoGrid& grid, int supersample) {
  core::require(grid.width > 0 && grid.height > 0 && grid.pixel > 0,
                "synth: an orthographic grid needs a positive size and pixel");
  // Straight down from above everything the scene holds.
  const double top = scene.box_max.z + 1;
  return render_rays(
      scene, setup, grid.width, grid.height, supersample, [&grid, top](double x, double y) {
        return Ray{{grid.left + x * grid.pixel, grid.top - y * grid.pixel, top}, {0, 0, -1}};
      });
}

torch::Tensor add_noise(const torch::Tensor& clean, const SpectralSetup& setup,
                        std::mt19937_64& rng) {
  const int n = setup.bands();
  core::require(clean.dim() == 3 && clean.size(2) == n, "synth: clean cube has the wrong bands");
  auto src = clean.contiguous().to(torch::kFloat32);
  auto out = torch::empty_like(src);
  // Per band: variance = shot_b s + read_b^2 (see noise_std).
  std::vector<double> shot(n), read2(n);
  for (int b = 0; b < n; ++b) {
    double q = std::pow(std::max(setup.response[b], 1e-3), setup.noise.edge_power);
    double scale2 = setup.noise.scale * setup.noise.scale;
    shot[b] = scale2 * setup.noise.shot / q;
    read2[b] = scale2 * (setup.noise.read / q) * (setup.noise.read / q);
  }
  std::normal_distribution<double> normal(0.0, 1.0);
  const float* in = src.data_ptr<float>();
  float* o = out.data_ptr<float>();
  const int64_t pixels = src.numel() / n;
  for (int64_t p = 0; p < pixels; ++p)
    for (int b = 0; b < n; ++b) {
      double s = in[p * n + b];
      double std = std::sqrt(shot[b] * std::max(s, 0.0) + read2[b]);
      o[p * n + b] = float(std::clamp(s + std * normal(rng), 0.0, 1.0));
    }
  return out;
}

torch::Tensor radiance_factor(const torch::Tensor& clean, const SpectralSetup& setup) {
  auto gain = torch::tensor(setup.band_gain, torch::kFloat32);
  return clean / gain.clamp_min(1e-12);
}

ViewPoints sample_points(const PlantScene& scene, const core::Camera& camera,
                         const torch::Tensor& clean, int count, double jitter,
                         std::mt19937_64& rng) {
  ViewPoints out;
  const int w = camera.intrinsics.width, h = camera.intrinsics.height;
  const int64_t n = clean.size(2);
  auto c = clean.accessor<float, 3>();
  std::uniform_int_distribution<int64_t> pick(0, int64_t(w) * h - 1);
  std::normal_distribution<double> normal(0.0, jitter);
  for (int attempt = 0; attempt < 20 * count && int(out.pixels.size()) < count; ++attempt) {
    int64_t pixel = pick(rng);
    int x = int(pixel % w), y = int(pixel / w);
    SurfaceHit hit;
    if (!scene.intersect(camera_ray(camera, x + 0.5, y + 0.5), &hit)) continue;
    Vec3 p = hit.point + Vec3{normal(rng), normal(rng), normal(rng)};
    out.xyz.insert(out.xyz.end(), {float(p.x), float(p.y), float(p.z)});
    for (int64_t b = 0; b < n; ++b) out.spectra.push_back(c[y][x][b]);
    out.pixels.push_back(pixel);
  }
  return out;
}

}  // namespace ddhgs::synth
