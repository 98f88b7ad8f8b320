// `ddhgs process`, first step: the cubes of a capture and their pseudo-RGB
// images with one scene-wide contrast stretch.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/log.h"
#include "io/image/image.h"
#include "io/scene/scene.h"
#include "process/pseudo_rgb_images.h"

namespace ddhgs::process {
using namespace io;
namespace fs = std::filesystem;

namespace {

// pseudo_rgb clamps at 1 before the sRGB curve; scaling its input down by
// this factor keeps values up to 16 x white (radiance cubes) for the stretch.
constexpr double kHeadroom = 16.0;

// Values sampled per view for the percentiles: plenty for 0.5 % tails.
constexpr int64_t kSamplesPerView = 1 << 16;

torch::Tensor srgb_decode(const torch::Tensor& encoded) {
  return torch::where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055).pow(2.4));
}

}  // namespace

core::PseudoRgbOptions parse_sfm_pseudo_rgb(const std::string& spec) {
  const std::string matrix = "matrix:";
  if (spec.rfind(matrix, 0) == 0)
    return core::parse_pseudo_rgb("map:" + spec.substr(matrix.size()));
  return core::parse_pseudo_rgb(spec);
}

bool pseudo_rgb_encodes(const core::PseudoRgbOptions& options) {
  return options.mode == core::PseudoRgbMode::Cie || options.map_output_linear;
}

torch::Tensor pseudo_rgb_linear(const torch::Tensor& cube,
                                const std::vector<double>& wavelengths_nm,
                                const core::PseudoRgbOptions& options) {
  core::PseudoRgbOptions scaled = options;
  scaled.exposure = options.exposure / kHeadroom;
  torch::Tensor display = core::pseudo_rgb(cube, wavelengths_nm, scaled);  // [H, W, 3]
  // Back to linear light: the stretch is a gain on light, applied before the curve.
  if (pseudo_rgb_encodes(options)) display = srgb_decode(display);
  return display * kHeadroom;
}

Stretch scene_stretch(const std::vector<torch::Tensor>& samples, double low_percent,
                      double high_percent) {
  std::vector<torch::Tensor> flat;
  for (const auto& s : samples) flat.push_back(s.reshape({-1}).to(torch::kFloat32));
  torch::Tensor all = std::get<0>(torch::cat(flat).sort());
  Stretch stretch;
  int64_t n = all.numel();
  if (n == 0) return stretch;
  auto at = [&](double percent) {
    double pos = percent / 100.0 * double(n - 1);
    auto lo = int64_t(std::floor(pos)), hi = std::min(lo + 1, n - 1);
    double f = pos - double(lo);
    return all[lo].item<double>() * (1 - f) + all[hi].item<double>() * f;
  };
  stretch.low = at(low_percent);
  stretch.high = at(high_percent);
  // A flat scene (all values equal) keeps its value instead of dividing by 0.
  if (!(stretch.high > stretch.low)) {
    stretch.low = 0;
    stretch.high = std::max(stretch.high, 1e-6);
  }
  return stretch;
}

torch::Tensor apply_stretch(const torch::Tensor& linear, const Stretch& stretch, bool encode) {
  torch::Tensor unit =
      ((linear.to(torch::kFloat32) - stretch.low) / (stretch.high - stretch.low)).clamp(0, 1);
  return core::to_u8(encode ? core::srgb_encode(unit) : unit);
}

Stretch write_pseudo_rgb_images(const CubeSet& cubes, const core::PseudoRgbOptions& options,
                                const fs::path& images_dir) {
  fs::create_directories(images_dir);
  const int64_t n = int64_t(cubes.files.size());
  core::ProgressBar bar("pseudo-RGB", 2 * n);
  // Half precision keeps a 640x512 view in 2 MB: plenty for 8-bit output.
  std::vector<torch::Tensor> linear, samples;
  for (int64_t v = 0; v < n; ++v) {
    const fs::path& file = cubes.files[size_t(v)];
    Cube cube = read_cube(file);
    require_bands(file, cube.bands(), cubes.bands);
    torch::Tensor rgb = pseudo_rgb_linear(cube_to_float(cube), cubes.wavelengths_nm, options);
    torch::Tensor flat = rgb.reshape({-1});
    int64_t step = std::max<int64_t>(1, flat.numel() / kSamplesPerView);
    samples.push_back(flat.slice(0, 0, flat.numel(), step).clone());
    linear.push_back(rgb.to(torch::kHalf));
    bar.update(v + 1);
  }
  Stretch stretch = scene_stretch(samples);
  bool encode = pseudo_rgb_encodes(options);
  for (int64_t v = 0; v < n; ++v) {
    write_png(images_dir / (cubes.names[size_t(v)] + ".png"),
              apply_stretch(linear[size_t(v)], stretch, encode));
    linear[size_t(v)] = torch::Tensor();
    bar.update(n + v + 1);
  }
  bar.finish();
  return stretch;
}

}  // namespace ddhgs::process
