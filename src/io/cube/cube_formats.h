// Per-format cube readers behind read_cube/probe_cube (private to io).
#pragma once
#include <filesystem>

#include "io/cube/cube.h"

namespace ddhgs::io::detail {

Cube read_npy(const std::filesystem::path& path, const CubeReadOptions& options);
CubeInfo probe_npy(const std::filesystem::path& path, const CubeReadOptions& options);
// Rows [y0, y1) of a .npy cube, read alone when the file stores them as one
// run of bytes (C order, bands last), else read whole and sliced.
Cube read_npy_rows(const std::filesystem::path& path, int64_t y0, int64_t y1,
                   const CubeReadOptions& options);
// Throws core::Error naming path unless 0 <= y0 < y1 <= height.
void require_rows(const std::filesystem::path& path, int64_t height, int64_t y0, int64_t y1);
// Rows [y0, y1) of a whole cube, contiguous (require_rows first).
Cube slice_rows(Cube cube, const std::filesystem::path& path, int64_t y0, int64_t y1);

Cube read_pt(const std::filesystem::path& path, const CubeReadOptions& options);

Cube read_envi(const std::filesystem::path& path);
CubeInfo probe_envi(const std::filesystem::path& path);

Cube read_tiff(const std::filesystem::path& path);
CubeInfo probe_tiff(const std::filesystem::path& path);

Cube read_image_cube(const std::filesystem::path& path);
CubeInfo probe_image(const std::filesystem::path& path);

// Decides which axis of a 3-D array [d0, d1, d2] holds bands; true when it
// is d0. Auto picks d0 only when it is clearly the smallest axis and d2 is not.
bool bands_first(int64_t d0, int64_t d1, int64_t d2, BandLayout layout);

// data: [H, W] or [H, W, B] / [B, H, W] per layout -> contiguous [H, W, B].
torch::Tensor to_bands_last(const torch::Tensor& data, BandLayout layout,
                            const std::filesystem::path& path);

// [N, R, C] contiguous -> [N, C, R] contiguous: a cache-blocked transpose,
// several times faster than LibTorch's strided copy for 1- and 2-byte samples
// (band-sequential files are this transpose per view).
torch::Tensor transpose_last_two(const torch::Tensor& data);

// The tensor dtype that holds samples of this type (U16 lives in int16).
torch::ScalarType tensor_dtype(SampleType type);
// Inverse of tensor_dtype for uint8/int16/int32/half/float/double tensors.
SampleType sample_type_of(torch::ScalarType dtype, const std::filesystem::path& path);

// core::Error naming path if a float cube holds NaN or Inf.
void require_finite(const torch::Tensor& data, const std::filesystem::path& path);

// Swaps the byte order of every element in place (big-endian files).
void swap_bytes(torch::Tensor& data);

}  // namespace ddhgs::io::detail
