// Hyperspectral cube files: .npy, PyTorch .pt, ENVI (.hdr + raw), multi-band
// TIFF, and PNG/JPEG as 3-band cubes. Cubes stay in their stored sample type
// in memory (a BaySpec scene is 20 GB as uint8) and convert to float per use.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::io {

// Sample types found in cube files. LibTorch 1.13 has no uint16, so U16
// samples are held bit-for-bit in an int16 tensor and reinterpreted on use.
enum class SampleType { U8, U16, I16, I32, F16, F32, F64 };

std::string to_string(SampleType type);
size_t bytes_per_sample(SampleType type);
// Default divisor that maps integer samples to [0, 1] (255, 65535, ...); 1 for floats.
double default_scale(SampleType type);

enum class BandLayout {
  Auto,        // H x W x B unless the first axis is clearly the band axis
  BandsLast,   // H x W x B
  BandsFirst,  // B x H x W
};

struct CubeReadOptions {
  BandLayout layout = BandLayout::Auto;
};

struct Cube {
  torch::Tensor data;  // [H, W, B] contiguous, stored sample type (see SampleType)
  SampleType type = SampleType::F32;
  std::vector<double> wavelengths_nm;  // from the file's metadata; empty if none
  std::optional<double> ignore_value;  // ENVI "data ignore value"
  // ENVI "reflectance scale factor": samples are reflectance times this.
  std::optional<double> scale_factor;

  int64_t height() const { return data.size(0); }
  int64_t width() const { return data.size(1); }
  int64_t bands() const { return data.size(2); }
  size_t bytes() const { return size_t(data.numel()) * bytes_per_sample(type); }
};

// Reads any supported cube, chosen by extension (.npy .pt .hdr/.raw/.img/.dat
// .tif/.tiff .png/.jpg/.jpeg). Throws core::Error naming the file on malformed
// input: missing, empty, truncated, wrong magic, unsupported dtype, NaN/Inf.
Cube read_cube(const std::filesystem::path& path, const CubeReadOptions& options = {});

// Rows [y0, y1) of the cube at path: equal to slicing read_cube's data
// (same type, metadata and checks, over those rows). A C-order, bands-last
// .npy reads only their bytes; any other file is read whole and sliced.
Cube read_cube_rows(const std::filesystem::path& path, int64_t y0, int64_t y1,
                    const CubeReadOptions& options = {});

// Reads only the header: shape [H, W, B], type and wavelengths, no samples.
struct CubeInfo {
  int64_t height = 0, width = 0, bands = 0;
  SampleType type = SampleType::F32;
  std::vector<double> wavelengths_nm;
  std::optional<double> scale_factor;  // as in Cube
  // Samples that only decoding proves whole (compressed TIFF, PNG, JPEG);
  // a raw cube is whole when its header and size agree.
  bool compressed = false;
};
CubeInfo probe_cube(const std::filesystem::path& path, const CubeReadOptions& options = {});

// Float32 [H, W, B] in [0, 1]: samples / scale. scale <= 0: the cube's own
// scale_factor when it has one, else default_scale(type). Samples equal to
// the ignore value become 0.
torch::Tensor cube_to_float(const Cube& cube, double scale = 0);

// Writers (atomic: temporary name, then rename). data: [H, W, B]; dtype
// uint8, int16 (as U16 when type says so), float16 or float32.
void write_npy(const std::filesystem::path& path, const torch::Tensor& data,
               SampleType type_if_u16 = SampleType::I16);
enum class EnviInterleave { BSQ, BIL, BIP };
// Writes path (.hdr) and its data file (same stem, .img).
// dtype uint8, int16 (data type 12 when type_if_u16 is U16), int32, float16
// (stored as float32), float32 or float64; little-endian.
void write_envi(const std::filesystem::path& hdr_path, const torch::Tensor& data,
                const std::vector<double>& wavelengths_nm,
                EnviInterleave interleave = EnviInterleave::BSQ,
                SampleType type_if_u16 = SampleType::I16);

// Bands as the samples of one page (contiguous or separate planes), or one
// single-sample page per band. dtype uint8, int16 (unsigned when type_if_u16 is
// U16), int32, float32 or float64.
enum class TiffLayout { Contiguous, Separate, Pages };
void write_tiff(const std::filesystem::path& path, const torch::Tensor& data,
                TiffLayout layout = TiffLayout::Contiguous,
                SampleType type_if_u16 = SampleType::I16);

}  // namespace ddhgs::io
