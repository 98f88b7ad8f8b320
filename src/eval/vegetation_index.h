// Normalised-difference vegetation indices of rendered bands: NDVI, NDRE,
// GNDVI, (A - B) / (A + B) for two broad bands A and B, as plant scientists
// compute them from multispectral cameras. Each broad band is the mean of the
// model's bands inside its window (centre +- FWHM / 2, MicaSense RedEdge-MX's
// bands), or, where no band lies inside it, the interpolation at its centre:
// a 5-band camera's red band is its own red band, a 141-band sensor's red is
// the mean of its 2-3 bands around 668 nm.
#pragma once
#include "core/tensor.h"

#include <string>
#include <vector>

#include "eval/colormap.h"

namespace ddhgs::eval {

struct BroadBand {
  const char* name;  // "NIR", "red", "red edge", "green"
  double centre_nm;  // window centre
  double fwhm_nm;    // window width
};

struct VegetationIndex {
  std::string name;  // "ndvi"
  BroadBand a, b;    // index = (a - b) / (a + b)
};

// ndvi (NIR, red), ndre (NIR, red edge), gndvi (NIR, green).
const std::vector<VegetationIndex>& vegetation_indices();
// By name (lower case); core::Error naming `option` and the choices otherwise.
const VegetationIndex& find_vegetation_index(const std::string& name, const std::string& option);

// [2, N] float64: rows A and B of the index as weights over the bands.
// core::Error naming the broad band when it lies outside the bands' range.
torch::Tensor index_band_map(const VegetationIndex& index,
                             const std::vector<double>& wavelengths_nm);

// The index of every pixel, float32 [H, W], from an [H, W, N] image; NaN
// where A + B is at most min_sum (no signal: black backdrop).
torch::Tensor index_values(const torch::Tensor& image, const torch::Tensor& band_map,
                           double min_sum = 1e-3);

// A picture of index values in [-1, 1] through RdYlGn (-1 red, 0 yellow, 1
// green), NaN as mid grey: float32 [H, W, 3].
torch::Tensor index_picture(const torch::Tensor& values);

}  // namespace ddhgs::eval
