// `ddhgs synth --preset rig`: the synthetic plant as a five-camera
// multispectral rig sees it (MicaSense RedEdge-MX bands: blue 475, green 560,
// red 668, NIR 842, red edge 717 nm). Each trigger writes one raw 16-bit TIFF
// per band camera with the rig's XMP and EXIF metadata; each band camera
// looks along its own rig-relative rotation; counts come from the clean
// reflectance through the inverse of MicaSense's radiometric model (black
// level, exposure, gain, calibration, vignetting, a constant sun as the DLS
// reads it) with sensor noise. Output:
//   captures/IMG_NNNN_k.tif  raw band images, k = rig camera index 1..5
//   panel/PANL_0000_k.tif    a capture of a calibration panel (albedo in synth.json)
//   truth/                   a band-per-view scene of every band camera's true
//                            pose and clean reflectance (bands/ and clean/, float32),
//                            with points.ply
//   cubes/                   the same captures as registered five-band cubes
//                            from the reference pose (noisy and clean/), as a
//                            hyperspectral camera would take them
//   synth.json               the parameters, rig rotations (factory and true
//                            errors), panel albedo and each capture's light
//                            factor (light_factors)
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "synth/generate.h"

namespace ddhgs::synth {

struct RigBandCamera {
  int index = 1;  // RigCameraIndex
  std::string name;
  double centre_nm = 0, fwhm_nm = 0;
  std::vector<double> relatives_deg;  // RigRelatives (x, y, z)
  double irradiance = 1;              // sun, W/m^2/nm, as the DLS reads it
  double panel_albedo = 0.5;
};

// The five band cameras, in rig order.
std::vector<RigBandCamera> rededge_rig();

// Each capture's true illumination over what its DLS reports, one factor per
// capture (config.views): config.light_factors when given, else drawn from
// the seed uniformly within 1 +- config.light_change.
std::vector<double> capture_light_factors(const SynthConfig& config);

SynthResult write_synthetic_rig(const SynthConfig& config, const std::filesystem::path& out,
                                bool force);

}  // namespace ddhgs::synth
