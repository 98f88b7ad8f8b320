// Pictures of N-band renders: pseudo-RGB, one band or a band range as grey or
// a colour map, error heatmaps against ground truth, and side-by-side
// comparisons (ground truth | render | error) as the paper's figures show.
#pragma once
#include "core/tensor.h"

#include <string>
#include <vector>

#include "eval/colormap.h"

namespace ddhgs::eval {

// Which bands a picture shows.
struct BandSelection {
  bool pseudo_rgb = true;  // all bands through core::pseudo_rgb
  int64_t first = 0;       // else the mean of bands [first, last] (indices)
  int64_t last = 0;
  std::string label = "rgb";  // for file names: "rgb", "band42", "750-768nm"
};

// "--band 42" (an index) or "--bands 750:768" (nm, inclusive; every band whose
// wavelength lies in the range). Both empty: pseudo-RGB. core::Error naming
// the option when the band or range selects nothing.
BandSelection select_bands(const std::string& band_index, const std::string& band_range_nm,
                           const std::vector<double>& wavelengths_nm);

// Mean over the selected bands, float [H, W]; all bands for pseudo-RGB.
torch::Tensor band_mean(const torch::Tensor& image,  // [H, W, N]
                        const BandSelection& bands);

// Display picture, float [H, W, 3] in [0, 1]: pseudo-RGB, or the band mean
// (reflectance 0..1 on a fixed scale) through the colour map.
torch::Tensor picture(const torch::Tensor& image,  // [H, W, N]
                      const std::vector<double>& wavelengths_nm, const BandSelection& bands,
                      Colormap map);

// |render - truth| averaged over the selected bands, divided by max_error and
// colour-mapped (errors above max_error saturate): float [H, W, 3].
torch::Tensor error_heatmap(const torch::Tensor& render,  // [H, W, N]
                            const torch::Tensor& truth,   // [H, W, N]
                            const BandSelection& bands, double max_error, Colormap map);

// A horizontal colour bar from 0 to 1 of the map: float [height, width, 3].
torch::Tensor colour_bar(int64_t height, int64_t width, Colormap map);

// Pictures side by side with a white gap of gap_px; heights must agree.
torch::Tensor side_by_side(const std::vector<torch::Tensor>& pictures,  // each [H, W_i, 3]
                           int64_t gap_px = 4);

// Stacks a picture above another (widths padded with white to the wider).
torch::Tensor stacked(const torch::Tensor& top,     // [H1, W1, 3]
                      const torch::Tensor& bottom,  // [H2, W2, 3]
                      int64_t gap_px = 4);

// truth | render | error side by side, with the error's colour bar (bar_px
// high) under the error panel only: float [H', W', 3].
torch::Tensor comparison_panels(const torch::Tensor& truth,   // [H, W, 3] picture
                                const torch::Tensor& render,  // [H, W, 3] picture
                                const torch::Tensor& error,   // [H, W, 3] heatmap
                                Colormap map, int64_t bar_px, int64_t gap_px = 4);

}  // namespace ddhgs::eval
