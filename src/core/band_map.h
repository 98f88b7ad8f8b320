// Linear maps from a sensor's N bands to other output channels: bands at
// wavelengths that were not captured, or what another sensor's spectral
// response functions would see. A colour model applies such a map after
// decoding (model::ColourModel::mapped), so every model renders through it.
#pragma once
#include "core/tensor.h"

#include <string>
#include <vector>

namespace ddhgs::core {

// [M, N] float64: each target wavelength as the linear interpolation of the
// two captured bands around it (a captured wavelength maps to its band).
// from_nm strictly increasing; a target outside [from_nm.front(),
// from_nm.back()] throws core::Error naming it (no extrapolation).
torch::Tensor interpolation_map(const std::vector<double>& from_nm,
                                const std::vector<double>& to_nm);

// [R, N] float64 that picks band rows[j] as output row j (one 1 per row).
torch::Tensor selection_map(int64_t bands, const std::vector<int64_t>& rows);

// "A:B:S" -> A, A + S, ... up to B (inclusive within 1e-9 S); "A,B,C" a list.
// Throws core::Error naming `option` for anything else.
std::vector<double> parse_wavelength_list(const std::string& text, const std::string& option);

// Spectral response functions: sampled at increasing wavelengths, one column
// per output channel (values >= 0).
struct ResponseFunctions {
  std::vector<double> wavelengths_nm;  // [S]
  std::vector<std::string> channels;   // [C] names
  torch::Tensor values;                // [S, C] float64
};

struct ResponseMap {
  torch::Tensor map;               // [C, N] float64, each row sums to 1
  std::vector<double> centres_nm;  // [C] response-weighted mean wavelength
  std::vector<double> captured;    // [C] share of each response inside the bands' range
};

// Each channel as the response-weighted mean of the band values interpolated
// to the response's sample wavelengths (trapezoid weights), so that
// map . bands = sum_s w_s r(s) bands(s) / sum_s w_s r(s) over the samples s
// inside the captured range. A channel with no response there throws.
ResponseMap response_map(const ResponseFunctions& response, const std::vector<double>& from_nm);

// The trapezoid weights w_s of the samples (sum_s w_s f(s) integrates f).
std::vector<double> trapezoid_weights(const std::vector<double>& wavelengths_nm);

}  // namespace ddhgs::core
