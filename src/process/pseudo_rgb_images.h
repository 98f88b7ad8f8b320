// `ddhgs process`, first step: pseudo-RGB PNGs of the cubes for COLMAP,
// with one contrast stretch for the whole scene.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <string>
#include <vector>

#include "core/colour.h"
#include "process/cube_set.h"

namespace ddhgs::process {

// "cie" (CIE 1931 + D65), "bands:R,G,B" (nearest bands to these wavelengths,
// nm) or "matrix:FILE" (3 rows of N weights, see core::parse_pseudo_rgb's
// map:FILE); the core spellings are accepted too.
core::PseudoRgbOptions parse_sfm_pseudo_rgb(const std::string& spec);

// Display-linear pseudo-RGB of each view [H, W, 3] -> 8-bit sRGB images with
// ONE contrast stretch for the whole scene: the low / high percentiles of all
// views' values map to 0 / 1, so a surface looks the same in every image and
// SIFT descriptors match across views.
struct Stretch {
  double low = 0, high = 1;  // display-linear values mapped to 0 and 1
};
// samples: display-linear values (any shape); low/high percentiles in [0, 100].
Stretch scene_stretch(const std::vector<torch::Tensor>& samples, double low_percent = 0.5,
                      double high_percent = 99.5);
// linear: float [H, W, 3] display-linear; returns uint8 [H, W, 3], sRGB-encoded
// when encode (CIE and bands modes), else stretched values as they are.
torch::Tensor apply_stretch(const torch::Tensor& linear, const Stretch& stretch, bool encode);
// Display-linear pseudo-RGB float [H, W, 3] of a float cube [H, W, N] in
// [0, 1]; values up to 16 x white survive (headroom for radiance cubes).
torch::Tensor pseudo_rgb_linear(const torch::Tensor& cube,
                                const std::vector<double>& wavelengths_nm,
                                const core::PseudoRgbOptions& options);
// Whether a mode's display values get the sRGB curve.
bool pseudo_rgb_encodes(const core::PseudoRgbOptions& options);

// Writes images_dir/<name>.png for every cube; returns the stretch used.
Stretch write_pseudo_rgb_images(const CubeSet& cubes, const core::PseudoRgbOptions& options,
                                const std::filesystem::path& images_dir);

}  // namespace ddhgs::process
