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
// sensor (pi / irradiance; no sun-angle correction).
#pragma once
#include "core/tensor.h"

#include <string>
#include <vector>

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

// Where the panel lies in a panel image: a square window, its centre and
// side as fractions of the image (MicaSense's guidance is to fill the middle
// of the frame with the panel).
struct PanelWindow {
  double centre_x = 0.5, centre_y = 0.5;
  double size = 0.2;  // side, as a fraction of the shorter image side
};

// How one band camera's radiance becomes reflectance.
struct ReflectanceCalibration {
  int rig_index = 0;
  std::string band;
  double factor = 0;          // reflectance = radiance * factor
  std::string source;         // "panel" or "DLS"
  double panel_radiance = 0;  // panel: its mean radiance in the window
  double albedo = 0;          // panel: its albedo in this band
};

// One calibration per band camera of `panel` (a capture of the calibration
// panel), albedo given per camera in rig order. core::Error naming the file
// when the albedo count differs from the camera count, an albedo is not in
// (0, 1], or the window is saturated or dark.
std::vector<ReflectanceCalibration> panel_calibration(const RigCapture& panel,
                                                      const std::vector<double>& albedo,
                                                      const PanelWindow& window = {});

// The factor for one band image: the panel's for its camera where `panel`
// holds one, else pi over its own DLS irradiance. core::Error naming the file
// when neither exists.
ReflectanceCalibration reflectance_calibration(const RigBandImage& image,
                                               const std::vector<ReflectanceCalibration>& panel);

// read_band_counts -> counts_to_radiance -> * factor: [H, W] float32.
torch::Tensor read_band_reflectance(const RigBandImage& image,
                                    const ReflectanceCalibration& calibration);

}  // namespace ddhgs::io
