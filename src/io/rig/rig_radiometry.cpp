#include "io/rig/rig_radiometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/text.h"
#include "io/cube/cube.h"
#include "io/rig/panel_label.h"

namespace ddhgs::io {

namespace {

// A region a panel label places is taken when the signal in it spreads less
// than this over its mean (the maker's panels: 2-3 % with the lens's
// vignetting; half on the panel, half on the ground: 30 % or more).
constexpr double kLabelledPanelSpread = 0.05;
// ... and with no panel found, when its mean is at least this share of the
// image's bright end (its 99.5th percentile), as the finder asks of a panel.
constexpr double kPanelBrightShare = 0.25;

// The band camera as far as a panel capture says: its lens where the
// metadata gives one; otherwise (geometry is not needed for radiometry) the
// image taken as a pinhole one, in which a label's layout applies as well.
core::Intrinsics panel_lens(const RigBandImage& image) {
  try {
    return rig_intrinsics(image);
  } catch (const core::Error&) {
    core::Intrinsics pinhole;
    pinhole.fx = pinhole.fy = 1;
    pinhole.width = int(image.width), pinhole.height = int(image.height);
    return pinhole;
  }
}

double bright_end(const torch::Tensor& signal) {
  const torch::Tensor flat = signal.flatten();
  const int64_t rank = std::max<int64_t>(1, int64_t(0.995 * double(flat.numel())));
  return std::get<0>(flat.kthvalue(rank)).item<double>();
}

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

torch::Tensor band_signal(const RigBandImage& image, const torch::Tensor& counts) {
  return (counts.to(torch::kFloat) - float(image.radiometry.black_level)).clamp_min(0.0f);
}

std::optional<PanelRegion> locate_panel(const RigBandImage& image, const torch::Tensor& signal) {
  std::optional<PanelRegion> region = find_panel(signal);
  // A MicaSense label places the region the maker's library measures. It
  // is taken when that region is as even as a panel and as bright as the
  // panel found (or, with none found, as bright as the finder asks a
  // panel to be); otherwise (a label misread, a layout not known) the
  // panel as found.
  std::optional<PanelRegion> placed;
  try {
    placed = find_labelled_panel(signal, panel_lens(image));
  } catch (const core::Error&) {
    // A lens model the undistortion cannot invert near the frame's edge:
    // no label frame, so the panel as found.
  }
  if (placed) {
    const double placed_level = signal.masked_select(placed->mask).mean().item<double>();
    const double level = region ? signal.masked_select(region->mask).mean().item<double>()
                                : kPanelBrightShare * bright_end(signal);
    const bool as_bright =
        region ? std::abs(placed_level / level - 1) < 0.1 : placed_level >= level;
    if (placed->spread < kLabelledPanelSpread && as_bright) region = std::move(placed);
  }
  return region;
}

std::vector<ReflectanceCalibration> panel_calibration(const RigCapture& panel,
                                                      const std::vector<RigBandImage>& cameras,
                                                      const std::vector<double>& albedo,
                                                      const PanelRegions& regions) {
  core::require(!panel.bands.empty(), "the panel capture holds no band images");
  if (albedo.size() != cameras.size())
    throw core::Error(panel.bands.front().file,
                      "the rig has " + std::to_string(cameras.size()) + " band cameras but " +
                          std::to_string(albedo.size()) +
                          " panel albedo values were given (one per camera, in rig order)");
  std::vector<ReflectanceCalibration> out;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const RigBandImage& camera = cameras[i];
    const RigBandImage* found = nullptr;
    for (const RigBandImage& b : panel.bands)
      if (b.band_name == camera.band_name && std::abs(b.centre_nm - camera.centre_nm) < 0.5)
        found = &b;
    if (!found) {
      std::string held;
      for (const RigBandImage& b : panel.bands)
        held +=
            (held.empty() ? "" : ", ") + b.band_name + " " + core::number_text(b.centre_nm) + " nm";
      throw core::Error(camera.file,
                        "band " + camera.band_name + " (" + core::number_text(camera.centre_nm) +
                            " nm) has no image in the panel capture, which holds " + held);
    }
    const RigBandImage& image = *found;
    if (!(albedo[i] > 0 && albedo[i] <= 1))
      throw core::Error(image.file, "panel albedo " + core::number_text(albedo[i]) + " for band " +
                                        image.band_name + " is not in (0, 1]");
    const torch::Tensor counts = read_band_counts(image);
    ReflectanceCalibration c;
    auto given = regions.find(camera.rig_index);
    if (given == regions.end()) given = regions.find(-1);
    if (given != regions.end()) {
      c.region = panel_region_from_box(image.height, image.width, given->second,
                                       "--panel-region for " + image.file.string());
    } else {
      const torch::Tensor signal = band_signal(image, counts);
      if (!(signal.max().item<double>() > 0))
        throw core::Error(image.file, "the panel capture reads no signal above the black level");
      std::optional<PanelRegion> region = locate_panel(image, signal);
      if (!region)
        throw PanelNotFound(image,
                            "no calibration panel found (an even, bright square; the QR label "
                            "beside it is not the panel): name where it lies with --panel-region "
                            "x,y,w,h");
      c.region = std::move(*region);
    }
    const torch::Tensor in_region = counts.masked_select(c.region.mask).to(torch::kDouble);
    const double full_scale = std::ldexp(1.0, image.bits) - 1;
    c.raw_mean = in_region.mean().item<double>();
    c.raw_spread = in_region.std().item<double>();
    c.saturated = (in_region >= full_scale - std::ldexp(1.0, image.bits - 8)).sum().item<int64_t>();
    if (double(c.saturated) > 0.005 * double(c.region.pixels))
      throw core::Error(image.file, "the panel is saturated: " + std::to_string(c.saturated) +
                                        " of its " + std::to_string(c.region.pixels) +
                                        " pixels are at the top of the " +
                                        std::to_string(image.bits) +
                                        "-bit range: take the panel capture with a shorter "
                                        "exposure");
    const double radiance = counts_to_radiance(image, counts)
                                .masked_select(c.region.mask)
                                .to(torch::kDouble)
                                .mean()
                                .item<double>();
    if (!(radiance > 0))
      throw core::Error(image.file, "the panel region reads no signal above the black level");
    c.rig_index = camera.rig_index;
    c.band = camera.band_name;
    c.centre_nm = camera.centre_nm;
    c.factor = albedo[i] / radiance;
    c.source = "panel";
    c.panel_radiance = radiance;
    c.albedo = albedo[i];
    c.panel_file = image.file;
    c.irradiance = radiance * M_PI / albedo[i];
    out.push_back(std::move(c));
  }
  return out;
}

ReflectanceCalibration reflectance_calibration(const RigBandImage& image,
                                               const std::vector<ReflectanceCalibration>& panel) {
  for (const ReflectanceCalibration& c : panel)
    if (c.band == image.band_name && std::abs(c.centre_nm - image.centre_nm) < 0.5) return c;
  if (!panel.empty())
    throw core::Error(image.file, "band " + image.band_name + " (" +
                                      core::number_text(image.centre_nm) +
                                      " nm) is not in the panel capture");
  if (image.radiometry.irradiance <= 0)
    throw core::Error(image.file,
                      "has no downwelling light sensor irradiance (XMP SpectralIrradiance) and "
                      "no panel capture was given: reflectance cannot be computed");
  ReflectanceCalibration c;
  c.rig_index = image.rig_index;
  c.band = image.band_name;
  c.centre_nm = image.centre_nm;
  c.factor = M_PI / image.radiometry.irradiance;
  c.source = "DLS";
  c.irradiance = image.radiometry.irradiance;
  return c;
}

torch::Tensor read_band_reflectance(const RigBandImage& image,
                                    const ReflectanceCalibration& calibration) {
  return counts_to_radiance(image, read_band_counts(image)) * float(calibration.factor);
}

}  // namespace ddhgs::io
