#include "io/rig/rig_radiometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "io/cube/cube.h"

namespace ddhgs::io {

namespace {

constexpr double kPi = 3.14159265358979323846;

// R(y) as [H, 1]: the row-dependent readout correction.
torch::Tensor row_correction(const RigBandImage& image) {
  const RigRadiometry& r = image.radiometry;
  const torch::Tensor y = torch::arange(image.height, torch::kDouble).unsqueeze(1);
  const double a2 = r.calibration[1], a3 = r.calibration[2];
  return (1.0 / (1.0 + a2 * y / r.exposure_s - a3 * y)).to(torch::kFloat);
}

// The scale from (p - black) * V * R to radiance.
double count_scale(const RigBandImage& image) {
  const RigRadiometry& r = image.radiometry;
  return r.calibration[0] / (r.gain() * r.exposure_s * std::ldexp(1.0, image.bits));
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", v);
  return text;
}

}  // namespace

void require_radiometry(const RigBandImage& image) {
  const RigRadiometry& r = image.radiometry;
  const std::string cannot = ": its counts cannot be converted to radiance";
  if (r.exposure_s <= 0) throw core::Error(image.file, "its EXIF has no ExposureTime" + cannot);
  if (r.iso_speed <= 0)
    throw core::Error(image.file, "its EXIF has no ISOSpeed (the gain)" + cannot);
  if (r.calibration.size() != 3)
    throw core::Error(image.file, "its XMP has no RadiometricCalibration" + cannot);
  if (image.bits <= 0 || image.bits > 32)
    throw core::Error(image.file,
                      "has " + std::to_string(image.bits) + " bits per sample" + cannot);
}

torch::Tensor vignetting_correction(const RigBandImage& image) {
  const RigRadiometry& r = image.radiometry;
  if (r.vignetting_centre_px.size() != 2 || r.vignetting_polynomial.empty())
    return torch::ones({image.height, image.width});
  const torch::Tensor y = torch::arange(image.height, torch::kDouble).unsqueeze(1);
  const torch::Tensor x = torch::arange(image.width, torch::kDouble).unsqueeze(0);
  const torch::Tensor radius = torch::sqrt((x - r.vignetting_centre_px[0]).square() +
                                           (y - r.vignetting_centre_px[1]).square());
  // 1 + k0 r + k1 r^2 + ..., by Horner from the highest power.
  torch::Tensor poly = torch::zeros_like(radius);
  for (auto k = r.vignetting_polynomial.rbegin(); k != r.vignetting_polynomial.rend(); ++k)
    poly = (poly + *k) * radius;
  return (1.0 / (poly + 1.0)).to(torch::kFloat);
}

torch::Tensor counts_to_radiance(const RigBandImage& image, const torch::Tensor& counts) {
  require_radiometry(image);
  const torch::Tensor signal =
      (counts.to(torch::kFloat) - float(image.radiometry.black_level)).clamp_min(0.0f);
  return signal * vignetting_correction(image) * row_correction(image) * float(count_scale(image));
}

torch::Tensor radiance_to_counts(const RigBandImage& image, const torch::Tensor& radiance) {
  require_radiometry(image);
  return radiance.to(torch::kFloat) /
             (vignetting_correction(image) * row_correction(image) * float(count_scale(image))) +
         float(image.radiometry.black_level);
}

torch::Tensor read_band_counts(const RigBandImage& image) {
  const Cube cube = read_cube(image.file);
  core::require(cube.bands() == 1 && cube.height() == image.height && cube.width() == image.width,
                image.file, "its pixels do not match its header (one band expected)");
  return cube_to_float(cube, 1.0).squeeze(2);
}

std::vector<ReflectanceCalibration> panel_calibration(const RigCapture& panel,
                                                      const std::vector<double>& albedo,
                                                      const PanelWindow& window) {
  core::require(!panel.bands.empty(), "the panel capture holds no band images");
  if (albedo.size() != panel.bands.size())
    throw core::Error(panel.bands.front().file,
                      "the panel capture has " + std::to_string(panel.bands.size()) +
                          " band cameras but " + std::to_string(albedo.size()) +
                          " panel albedo values were given (one per camera, in rig order)");
  std::vector<ReflectanceCalibration> out;
  for (size_t i = 0; i < panel.bands.size(); ++i) {
    const RigBandImage& image = panel.bands[i];
    if (!(albedo[i] > 0 && albedo[i] <= 1))
      throw core::Error(image.file, "panel albedo " + number(albedo[i]) + " for band " +
                                        image.band_name + " is not in (0, 1]");
    const int64_t side = std::max<int64_t>(
        1, int64_t(std::lround(window.size * double(std::min(image.width, image.height)))));
    const int64_t x0 =
        std::clamp<int64_t>(int64_t(std::lround(window.centre_x * double(image.width))) - side / 2,
                            0, image.width - side);
    const int64_t y0 =
        std::clamp<int64_t>(int64_t(std::lround(window.centre_y * double(image.height))) - side / 2,
                            0, image.height - side);
    const torch::Tensor counts = read_band_counts(image);
    const torch::Tensor in_window = counts.slice(0, y0, y0 + side).slice(1, x0, x0 + side);
    const double full_scale = std::ldexp(1.0, image.bits) - 1;
    if (in_window.max().item<double>() >= 0.98 * full_scale)
      throw core::Error(image.file,
                        "the panel is saturated in its window (counts at the top of the " +
                            std::to_string(image.bits) +
                            "-bit range): take the panel capture with a shorter exposure");
    const double radiance = counts_to_radiance(image, counts)
                                .slice(0, y0, y0 + side)
                                .slice(1, x0, x0 + side)
                                .mean()
                                .item<double>();
    if (!(radiance > 0))
      throw core::Error(image.file, "the panel reads no signal in its window (" +
                                        std::to_string(side) + " px square at " +
                                        std::to_string(x0) + "," + std::to_string(y0) + ")");
    ReflectanceCalibration c;
    c.rig_index = image.rig_index;
    c.band = image.band_name;
    c.factor = albedo[i] / radiance;
    c.source = "panel";
    c.panel_radiance = radiance;
    c.albedo = albedo[i];
    out.push_back(c);
  }
  return out;
}

ReflectanceCalibration reflectance_calibration(const RigBandImage& image,
                                               const std::vector<ReflectanceCalibration>& panel) {
  for (const ReflectanceCalibration& c : panel)
    if (c.rig_index == image.rig_index) return c;
  if (!panel.empty())
    throw core::Error(image.file, "band camera " + std::to_string(image.rig_index) + " (" +
                                      image.band_name + ") is not in the panel capture");
  if (image.radiometry.irradiance <= 0)
    throw core::Error(image.file,
                      "has no downwelling light sensor irradiance (XMP SpectralIrradiance) and "
                      "no panel capture was given: reflectance cannot be computed");
  ReflectanceCalibration c;
  c.rig_index = image.rig_index;
  c.band = image.band_name;
  c.factor = kPi / image.radiometry.irradiance;
  c.source = "DLS";
  return c;
}

torch::Tensor read_band_reflectance(const RigBandImage& image,
                                    const ReflectanceCalibration& calibration) {
  return counts_to_radiance(image, read_band_counts(image)) * float(calibration.factor);
}

}  // namespace ddhgs::io
