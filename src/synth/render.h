// Spectral ray casting of the plant scene, the turntable camera rig, sensor
// noise and the sparse point cloud.
#pragma once
#include "core/tensor.h"

#include <random>
#include <vector>

#include "core/camera.h"
#include "synth/generate.h"
#include "synth/plant.h"
#include "synth/spectra.h"

namespace ddhgs::synth {

// Lighting: one directional sun plus ambient; the backdrop is lit evenly.
struct Lighting {
  core::Vec3 to_light{0.4, -0.5, 0.9};  // direction towards the light (normalised on use)
  double sun = 0.9;
  double ambient = 0.25;
  double backdrop = 0.7;             // radiance factor of the background (0: none, black)
  double lamp_temperature_k = 3200;  // the lamp's colour (lamp_power): the light's spectral tilt
  // The brightest diffuse material sits at 0.85 x exposure of full scale.
  double exposure = 1;
};

// Everything that turns a hit into N band values, tabulated on the band grid.
struct SpectralSetup {
  std::vector<double> wavelengths_nm;  // N
  std::vector<float> reflectance;      // [M, N] material reflectances, row-major
  std::vector<float> band_gain;        // [N] lamp x response x normalisation
  std::vector<double> response;        // [N] sensor quantum efficiency
  Lighting lighting;
  NoiseModel noise;
  int bands() const { return int(wavelengths_nm.size()); }
};

// Tabulates the scene's materials on the grid and picks the gain that puts the
// brightest diffuse material at about 0.85 x lighting.exposure of full scale.
SpectralSetup make_spectral_setup(const PlantScene& scene,
                                  const std::vector<double>& wavelengths_nm,
                                  const NoiseModel& noise, const Lighting& lighting = {});

struct RigOptions {
  int views = 40;
  int rings = 3;
  double min_elevation_deg = 12, max_elevation_deg = 55;
  double fov_deg = 40;  // horizontal
  int width = 128, height = 96;
  double fill = 0.95;  // fraction of the frame (each axis) the plant's box fills
  double k1 = 0;       // radial lens distortion (OPENCV k1)
};

// The cameras a synthetic scene's flags ask for (views, rings, elevations,
// field of view, size, fill, k1).
RigOptions rig_options(const SynthConfig& config);

// The camera every view of a rig shares: square pixels, options.fov_deg
// across the width, the principal point at the centre, options.k1.
core::Intrinsics rig_intrinsics(const RigOptions& options);

// Rings of cameras at several elevations looking at the plant's centre; more
// views on the lower (longer) rings. Cameras use OpenCV axes, world z is up.
std::vector<core::Camera> turntable_rig(const PlantScene& scene, const RigOptions& options);

// World ray through pixel position (x, y) (pixel centres at +0.5), through
// the camera's lens model: a distorted camera renders a distorted view.
Ray camera_ray(const core::Camera& camera, double x, double y);

// Clean signal float32 [H, W, N] in [0, 1], supersample x supersample rays per pixel.
torch::Tensor render_clean(const PlantScene& scene, const SpectralSetup& setup,
                           const core::Camera& camera, int supersample);

// A north-up grid over the ground (world x east, y north, z up): pixel
// (col, row)'s corner at (left + col pixel, top - row pixel), scene units.
struct OrthoGrid {
  double left = 0, top = 0, pixel = 0;
  int width = 0, height = 0;
};

// The clean signal [H, W, N] seen straight down (rays along -z, one view
// direction for every pixel) over the grid: the orthographic truth of a
// survey, shaded as render_clean shades a nadir view.
torch::Tensor render_orthographic(const PlantScene& scene, const SpectralSetup& setup,
                                  const OrthoGrid& grid, int supersample);

// Noisy copy of clean [H, W, N]: per-band shot + read noise (NoiseModel), clamped to [0, 1].
torch::Tensor add_noise(const torch::Tensor& clean, const SpectralSetup& setup,
                        std::mt19937_64& rng);

// Radiance factor [H, W, N] (clean / band_gain): reflectance x shading, for previews.
torch::Tensor radiance_factor(const torch::Tensor& clean, const SpectralSetup& setup);

// Points on visible surfaces of one view: count pixels drawn at random whose
// centre ray hits something other than the background; each point gets the
// clean spectrum of its pixel and a small position jitter (std in scene units).
struct ViewPoints {
  std::vector<float> xyz;       // [P, 3]
  std::vector<float> spectra;   // [P, N]
  std::vector<int64_t> pixels;  // [P] y * W + x
};
ViewPoints sample_points(const PlantScene& scene, const core::Camera& camera,
                         const torch::Tensor& clean, int count, double jitter,
                         std::mt19937_64& rng);

}  // namespace ddhgs::synth
