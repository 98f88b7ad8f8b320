// Data of the report's 3D spectral view (internal to report.cpp): the
// Gaussians in a compact form, their band values as a quantised basis, the
// weights that turn band values into pseudo-RGB, the training cameras and a
// starting view.
//
// Band values (the view-independent colour max(C0 dc + 0.5, 0) of every band)
// are stored as K 8-bit coefficients per Gaussian on a K-vector basis over
// the bands (principal components of the model's own spectra, K <= 16 and
// <= N): a band, a band range's mean and pseudo-RGB are all linear in the
// band values, so the page recolours every splat from the same coefficients
// by changing K weights, without touching the model on the GPU.
#pragma once
#include <nlohmann/json.hpp>

#include <vector>

#include "core/tensor.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

constexpr int kMaxBasisVectors = 16;  // the page's shader reads 4 RGBA texels per splat

// Band values of the model, double [G, N] (max(C0 dc + 0.5, 0), clamped to 1).
torch::Tensor band_values(const model::Gaussians& gaussians);

// A basis of K vectors for rows of `values` ([G, N]): the mean and the
// leading principal components; K is the fewest components whose discarded
// variance is at most (tolerance)^2 per value, at most max_vectors and N.
struct SpectralBasis {
  torch::Tensor mean;          // double [N]
  torch::Tensor vectors;       // double [K, N], orthonormal rows
  torch::Tensor coefficients;  // uint8 [G, K]: (c - low) / (high - low) * 255, rounded
  torch::Tensor low, high;     // double [K]: range of each coefficient
  double rmse = 0;             // of the reconstruction from the 8-bit coefficients, per value

  torch::Tensor reconstruct() const;  // double [G, N]
};
SpectralBasis spectral_basis(const torch::Tensor& values,  // [G, N]
                             double tolerance, int max_vectors = kMaxBasisVectors);

// Everything the page's 3D view needs, as JSON with base64 arrays.
nlohmann::json splat_view_data(const model::Gaussians& gaussians, const io::Scene& scene,
                               const torch::Tensor& background,  // [N]
                               int start_view);                  // scene view the camera starts at

}  // namespace ddhgs::eval
