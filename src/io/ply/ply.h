// PLY files: N-band Gaussian models and sparse point clouds with spectra.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <vector>

namespace ddhgs::io {

// N-band 3DGS PLY (binary little endian, float32):
//   x y z nx ny nz f_dc_0..f_dc_{N-1} f_rest_0..f_rest_{N*K-1} opacity
//   scale_0..2 rot_0..3
// f_rest is band-major: f_rest_{b*K+k} is band b, SH coefficient k+1, with
// K = (degree+1)^2 - 1. A "comment wavelengths w0 w1 ..." header line (nm).
// A latent colour model (model/colour_model.h) has C channels instead of N
// bands in f_dc_* and f_rest_*, and N header lines
// "comment band_basis m_b B_b0 .. B_b(C-1)": band b's mean and basis row.
struct GaussianPly {
  torch::Tensor means;                 // [G, 3] float32
  torch::Tensor log_scales;            // [G, 3]
  torch::Tensor quats;                 // [G, 4] (w, x, y, z)
  torch::Tensor logit_opacities;       // [G, 1]
  torch::Tensor sh_dc;                 // [G, C]; C = N per band
  torch::Tensor sh_rest;               // [G, C, K], K in {0, 3, 8, 15}
  std::vector<double> wavelengths_nm;  // may be empty
  torch::Tensor basis;                 // [N, C] latent colour model, else undefined
  torch::Tensor mean;                  // [N] with basis

  int64_t bands() const { return basis.defined() ? basis.size(0) : sh_dc.size(1); }
  int sh_degree() const;  // from K
};

GaussianPly read_gaussian_ply(const std::filesystem::path& path);
void write_gaussian_ply(const std::filesystem::path& path, const GaussianPly& ply);

// Sparse points for initialisation: x y z [red green blue] [spec_0..spec_{N-1}].
struct PointCloud {
  torch::Tensor xyz;      // [P, 3] float32
  torch::Tensor rgb;      // [P, 3] uint8, or undefined
  torch::Tensor spectra;  // [P, N] float32 in [0, 1], or undefined
};

// Reads ASCII or binary little-endian PLY vertex elements (3DGS, COLMAP
// exports, and our own points.ply).
PointCloud read_point_ply(const std::filesystem::path& path);
void write_point_ply(const std::filesystem::path& path, const PointCloud& points);

}  // namespace ddhgs::io
