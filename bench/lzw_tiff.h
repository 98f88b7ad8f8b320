// A smooth 16-bit cube written as a capture tool writes it: LZW-compressed
// (horizontal predictor) in strips of 16 rows, band-interleaved by pixel.
// Shared by the benchmarks that time decoding compressed views.
#pragma once
#include <tiffio.h>

#include <filesystem>
#include <vector>

#include "core/tensor.h"

namespace ddhgs::bench {

// values: [H, W, B], rounded and clamped to 0-65535.
inline void write_lzw_tiff(const std::filesystem::path& path, const torch::Tensor& values) {
  const int64_t h = values.size(0), w = values.size(1), b = values.size(2);
  const torch::Tensor i32 = values.round().clamp(0, 65535).to(torch::kInt32).contiguous();
  std::vector<uint16_t> samples(i32.data_ptr<int32_t>(), i32.data_ptr<int32_t>() + i32.numel());
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(w));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(h));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(b));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(16));
  TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_LZW);
  TIFFSetField(tif, TIFFTAG_PREDICTOR, PREDICTOR_HORIZONTAL);
  TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, uint32_t(16));
  for (int64_t y = 0; y < h; ++y)
    TIFFWriteScanline(tif, samples.data() + y * w * b, uint32_t(y), 0);
  TIFFClose(tif);
}

}  // namespace ddhgs::bench
