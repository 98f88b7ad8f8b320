// Pictures and viewer data of the report's test views (internal to report.cpp).
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "eval/figures.h"

namespace ddhgs::eval {

// Band selections of the report's pictures: pseudo-RGB, then the paper's
// ranges (400-418, 750-768, 1082-1100 nm) moved inside the scene's range
// (kept at their width, clamped to the first and last band) so every scene
// shows its blue, red-edge and near-infrared ends; a window between two bands
// takes the nearest band. Duplicates are dropped. Wavelengths not in
// increasing order (an RGB run's R, G, B) give one selection per band.
std::vector<BandSelection> report_band_selections(const std::vector<double>& wavelengths_nm);

// What a selection shows, for menus: "pseudo-RGB", "750-768 nm (bands 3-4)".
std::string selection_title(const BandSelection& bands, const std::vector<double>& wavelengths_nm);

// truth | render | error heatmap, with the error's colour bar under it:
// float [H', W', 3].
torch::Tensor comparison_figure(const torch::Tensor& render,  // [H, W, N]
                                const torch::Tensor& truth,   // [H, W, N]
                                const std::vector<double>& wavelengths_nm,
                                const BandSelection& bands, double diff_max);

// All bands of a cube as one 8-bit grey atlas (reflectance 0..1 -> 0..255),
// after area-averaging down so the longer side is at most max_px: uint8
// [rows * h, cols * w] with band b at tile (b / cols, b % cols).
struct BandAtlas {
  torch::Tensor pixels;                           // uint8 [rows * h, cols * w]
  int width = 0, height = 0, cols = 0, rows = 0;  // tile size (pixels) and grid
};
BandAtlas band_atlas(const torch::Tensor& cube,  // [H, W, N]
                     int max_px);

// RFC 4648 base64 (with padding).
std::string base64(const std::string& bytes);

// The PNG file of an image as a data: URI (data URIs keep a canvas readable
// in a page opened from disk). scratch: a file name it may use and removes.
std::string png_data_uri(const torch::Tensor& image,  // uint8 [H, W] or [H, W, C]
                         const std::filesystem::path& scratch);

// 256 viridis colours as [[r, g, b], ...] in 0..255, for the page's heatmaps.
nlohmann::json viridis_lut();
// The same for any colour map (RdYlGn for the 3D view's vegetation indices).
nlohmann::json colormap_lut(Colormap map);

}  // namespace ddhgs::eval
