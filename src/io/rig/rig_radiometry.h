// Counts to radiance, and radiance to reflectance, for the band images of a
// multispectral rig, by the sensor model MicaSense publishes for RedEdge and
// Altum cameras:
//
//   L = V(x, y) * R(y) * (p - black) / (gain * exposure) * a1 / 2^bits
//   V = 1 / (1 + k0 r + k1 r^2 + ...)     r: pixels from the vignetting centre
//   R = 1 / (1 + a2 y / exposure - a3 y)  y: the pixel's row
//
// L in W/m^2/sr/nm; p the raw count, black the black level, gain = ISO/100,
// a1..a3 the XMP RadiometricCalibration, k the XMP VignettingPolynomial.
// Counts below the black level read as radiance 0.
//
// Reflectance = L * factor, the factor from a calibration-panel capture
// (the panel's albedo over its measured radiance, one factor per band camera
// for the whole flight) or else from the capture's own downwelling light
// sensor (pi / irradiance, the irradiance on level ground: io/rig/sun.h).
#pragma once
#include "core/tensor.h"

#include <array>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/rig/panel_finder.h"
#include "io/rig/rig_capture.h"

namespace ddhgs::io {

// core::Error naming the file when its metadata lacks what the model needs
// (exposure, ISO gain, the three calibration coefficients).
void require_radiometry(const RigBandImage& image);

// V(x, y) as [H, W] float32 (ones where the file gives no vignetting model).
torch::Tensor vignetting_correction(const RigBandImage& image);

// counts: [H, W] raw counts as float. Returns radiance [H, W] float32.
torch::Tensor counts_to_radiance(const RigBandImage& image, const torch::Tensor& counts);
// The inverse, for writing synthetic captures: the (unrounded, unclamped)
// counts that read back as `radiance`.
torch::Tensor radiance_to_counts(const RigBandImage& image, const torch::Tensor& radiance);

// The file's pixels as [H, W] float32 counts.
torch::Tensor read_band_counts(const RigBandImage& image);

// How one band camera's radiance becomes reflectance.
struct ReflectanceCalibration {
  int rig_index = 0;
  std::string band;
  double centre_nm = 0;
  double factor = 0;          // reflectance = radiance * factor
  std::string source;         // "panel" or "DLS"
  double panel_radiance = 0;  // panel: its mean radiance in the region
  double albedo = 0;          // panel: its albedo in this band
  // panel: the file, the region measured (io/rig/panel_finder.h) and what it
  // holds: raw counts' mean and spread, saturated pixels, and the irradiance
  // the panel implies (pi L / albedo, W/m^2/nm).
  std::filesystem::path panel_file;
  PanelRegion region;
  double raw_mean = 0, raw_spread = 0;
  int64_t saturated = 0;
  double irradiance = 0;
};

// The panel region in a band image of a panel capture (signal: its counts
// above the black level, band_signal): placed from a MicaSense QR label
// where one is read and the region it places is even and bright
// (io/rig/panel_label.h), else the panel as the finder finds it
// (io/rig/panel_finder.h). nullopt when neither finds one.
std::optional<PanelRegion> locate_panel(const RigBandImage& image, const torch::Tensor& signal);

// No panel could be told apart in `image`: the caller may show the image.
struct PanelNotFound : core::Error {
  PanelNotFound(const RigBandImage& band, const std::string& problem)
      : core::Error(band.file, problem), image(band) {}
  RigBandImage image;
};

// Given panel regions (x, y, width, height): by rig camera index, or for
// every camera under the key -1.
using PanelRegions = std::map<int, std::array<int64_t, 4>>;

// One calibration per band camera of `cameras` (the flight's, in rig order;
// albedo in the same order) from `panel`, a capture of the calibration panel:
// each camera takes the panel image of its own band (by band name and centre
// wavelength, never by rig index), the panel found in it (or the region
// given), and the region's mean radiance. core::Error naming the file when
// the albedo count differs from the camera count, an albedo is not in
// (0, 1], a camera's band has no panel image, no panel is found, or the
// region is saturated or dark.
std::vector<ReflectanceCalibration> panel_calibration(const RigCapture& panel,
                                                      const std::vector<RigBandImage>& cameras,
                                                      const std::vector<double>& albedo,
                                                      const PanelRegions& regions = {});

// The counts above the black level ([H, W] float) and the full-scale count
// of a band image: what the panel finder looks at.
torch::Tensor band_signal(const RigBandImage& image, const torch::Tensor& counts);

// The factor for one band image: the panel's for its band (by band name and
// centre wavelength) where `panel` is not empty, else pi over its own DLS
// irradiance (io/rig/rig_capture.h: on level ground as the camera maker
// defines it). core::Error naming the file when neither exists.
ReflectanceCalibration reflectance_calibration(const RigBandImage& image,
                                               const std::vector<ReflectanceCalibration>& panel);

// read_band_counts -> counts_to_radiance -> * factor: [H, W] float32.
torch::Tensor read_band_reflectance(const RigBandImage& image,
                                    const ReflectanceCalibration& calibration);

}  // namespace ddhgs::io
