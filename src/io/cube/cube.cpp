// Cube format dispatch and the conversions shared by every cube reader.
#include "io/cube/cube.h"

#include <algorithm>
#include <cctype>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "io/cube/cube_formats.h"
#include "io/files/input_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

std::string to_string(SampleType type) {
  switch (type) {
    case SampleType::U8:
      return "uint8";
    case SampleType::U16:
      return "uint16";
    case SampleType::I16:
      return "int16";
    case SampleType::I32:
      return "int32";
    case SampleType::F16:
      return "float16";
    case SampleType::F32:
      return "float32";
    case SampleType::F64:
      return "float64";
  }
  return "unknown";
}

size_t bytes_per_sample(SampleType type) {
  switch (type) {
    case SampleType::U8:
      return 1;
    case SampleType::U16:
    case SampleType::I16:
    case SampleType::F16:
      return 2;
    case SampleType::I32:
    case SampleType::F32:
      return 4;
    case SampleType::F64:
      return 8;
  }
  return 0;
}

double default_scale(SampleType type) {
  switch (type) {
    case SampleType::U8:
      return 255.0;
    case SampleType::U16:
      return 65535.0;
    case SampleType::I16:
      return 32767.0;
    case SampleType::I32:
      return 2147483647.0;
    default:
      return 1.0;
  }
}

namespace detail {

bool bands_first(int64_t d0, int64_t d1, int64_t d2, BandLayout layout) {
  if (layout != BandLayout::Auto) return layout == BandLayout::BandsFirst;
  auto clearly_smallest = [](int64_t a, int64_t b, int64_t c) { return 2 * a <= std::min(b, c); };
  return clearly_smallest(d0, d1, d2) && !clearly_smallest(d2, d0, d1);
}

namespace {

template <typename T>
void transpose_columns(const T* src, T* dst, int64_t rows, int64_t cols, int64_t c_begin,
                       int64_t c_end) {
  // 32 x 32 blocks keep both the read and the write side in cache.
  constexpr int64_t kBlock = 32;
  for (int64_t c0 = c_begin; c0 < c_end; c0 += kBlock)
    for (int64_t r0 = 0; r0 < rows; r0 += kBlock) {
      int64_t c1 = std::min(c0 + kBlock, c_end), r1 = std::min(r0 + kBlock, rows);
      for (int64_t c = c0; c < c1; ++c)
        for (int64_t r = r0; r < r1; ++r) dst[c * rows + r] = src[r * cols + c];
    }
}

template <typename T>
void transpose_batch(const torch::Tensor& in, torch::Tensor& out) {
  int64_t n = in.size(0), rows = in.size(1), cols = in.size(2);
  const T* src = static_cast<const T*>(in.data_ptr());
  T* dst = static_cast<T*>(out.data_ptr());
  int64_t blocks = (cols + 31) / 32;
  core::parallel_for(0, n * blocks, 1, [&](int64_t begin, int64_t end) {
    for (int64_t task = begin; task < end; ++task) {
      int64_t i = task / blocks, c0 = (task % blocks) * 32;
      transpose_columns(src + i * rows * cols, dst + i * rows * cols, rows, cols, c0,
                        std::min(c0 + 32, cols));
    }
  });
}

}  // namespace

torch::Tensor transpose_last_two(const torch::Tensor& data) {
  torch::Tensor in = data.contiguous();
  torch::Tensor out = torch::empty({in.size(0), in.size(2), in.size(1)}, in.options());
  switch (in.element_size()) {
    case 1:
      transpose_batch<uint8_t>(in, out);
      break;
    case 2:
      transpose_batch<uint16_t>(in, out);
      break;
    case 4:
      transpose_batch<uint32_t>(in, out);
      break;
    case 8:
      transpose_batch<uint64_t>(in, out);
      break;
    default:
      out.copy_(in.transpose(1, 2));
  }
  return out;
}

void require_rows(const fs::path& path, int64_t height, int64_t y0, int64_t y1) {
  if (y0 < 0 || y0 >= y1 || y1 > height)
    throw core::Error(path, "rows " + std::to_string(y0) + " to " + std::to_string(y1) +
                                " lie outside the cube's " + std::to_string(height) + " rows");
}

Cube slice_rows(Cube cube, const fs::path& path, int64_t y0, int64_t y1) {
  require_rows(path, cube.height(), y0, y1);
  cube.data = cube.data.slice(0, y0, y1).contiguous();
  return cube;
}

torch::Tensor to_bands_last(const torch::Tensor& data, BandLayout layout, const fs::path& path) {
  if (data.dim() == 2) return data.unsqueeze(2).contiguous();
  if (data.dim() != 3)
    throw core::Error(path, "array has " + std::to_string(data.dim()) +
                                " dimensions, expected 2 (H x W) or 3 (H x W x B or B x H x W)");
  if (bands_first(data.size(0), data.size(1), data.size(2), layout))
    return transpose_last_two(data.reshape({1, data.size(0), -1}))
        .view({data.size(1), data.size(2), data.size(0)});
  return data.contiguous();
}

torch::ScalarType tensor_dtype(SampleType type) {
  switch (type) {
    case SampleType::U8:
      return torch::kUInt8;
    case SampleType::U16:
    case SampleType::I16:
      return torch::kInt16;
    case SampleType::I32:
      return torch::kInt32;
    case SampleType::F16:
      return torch::kHalf;
    case SampleType::F32:
      return torch::kFloat;
    case SampleType::F64:
      return torch::kDouble;
  }
  return torch::kFloat;
}

SampleType sample_type_of(torch::ScalarType dtype, const fs::path& path) {
  switch (dtype) {
    case torch::kUInt8:
      return SampleType::U8;
    case torch::kInt16:
      return SampleType::I16;
    case torch::kInt32:
      return SampleType::I32;
    case torch::kHalf:
      return SampleType::F16;
    case torch::kFloat:
      return SampleType::F32;
    case torch::kDouble:
      return SampleType::F64;
    default:
      throw core::Error(path, std::string("unsupported tensor dtype ") + c10::toString(dtype) +
                                  " (expected uint8, int16, int32, float16, float32 or float64)");
  }
}

void require_finite(const torch::Tensor& data, const fs::path& path) {
  if (!data.is_floating_point()) return;
  if (!torch::isfinite(data).all().item<bool>())
    throw core::Error(path, "contains NaN or Inf values");
}

void swap_bytes(torch::Tensor& data) {
  int64_t width = data.element_size();
  if (width == 1) return;
  torch::Tensor bytes = data.contiguous().view(torch::kUInt8).view({-1, width}).flip({1});
  data = bytes.contiguous().view(data.scalar_type()).view(data.sizes());
}

}  // namespace detail

namespace {

enum class Format { Npy, Pt, Envi, Tiff, Image };

std::string lower_extension(const fs::path& path) {
  return core::lower(path.extension().string());
}

Format format_of(const fs::path& path) {
  require_regular_file(path);
  std::error_code ec;
  std::string ext = lower_extension(path);
  if (ext == ".npy") return Format::Npy;
  if (ext == ".pt" || ext == ".pth") return Format::Pt;
  if (ext == ".hdr" || ext == ".raw" || ext == ".img" || ext == ".dat" || ext == ".bsq" ||
      ext == ".bil" || ext == ".bip")
    return Format::Envi;
  if (ext == ".tif" || ext == ".tiff") return Format::Tiff;
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") return Format::Image;
  // ENVI data files often have no extension at all, only a sibling header.
  if (ext.empty() && fs::exists(fs::path(path.string() + ".hdr"), ec)) return Format::Envi;
  throw core::Error(path,
                    "unknown cube format (expected .npy, .pt, ENVI .hdr/.img/.raw/.dat, "
                    ".tif/.tiff, .png or .jpg)");
}

}  // namespace

Cube read_cube(const fs::path& path, const CubeReadOptions& options) {
  switch (format_of(path)) {
    case Format::Npy:
      return detail::read_npy(path, options);
    case Format::Pt:
      return detail::read_pt(path, options);
    case Format::Envi:
      return detail::read_envi(path);
    case Format::Tiff:
      return detail::read_tiff(path);
    case Format::Image:
      return detail::read_image_cube(path);
  }
  throw core::Error(path, "unknown cube format");
}

Cube read_cube_rows(const fs::path& path, int64_t y0, int64_t y1, const CubeReadOptions& options) {
  if (format_of(path) == Format::Npy) return detail::read_npy_rows(path, y0, y1, options);
  return detail::slice_rows(read_cube(path, options), path, y0, y1);
}

CubeInfo probe_cube(const fs::path& path, const CubeReadOptions& options) {
  switch (format_of(path)) {
    case Format::Npy:
      return detail::probe_npy(path, options);
    case Format::Envi:
      return detail::probe_envi(path);
    case Format::Tiff:
      return detail::probe_tiff(path);
    case Format::Image:
      return detail::probe_image(path);
    case Format::Pt: {
      // A pickle has no separate header: the tensor must be loaded to see its shape.
      Cube cube = detail::read_pt(path, options);
      return {cube.height(), cube.width(),        cube.bands(),
              cube.type,     cube.wavelengths_nm, cube.scale_factor};
    }
  }
  throw core::Error(path, "unknown cube format");
}

namespace {

// samples[i] / scale in float32, the arithmetic of the general path below
// (a float tensor divided by a scalar divides by float(scale)), in one pass
// into a pooled buffer: training converts one view per iteration.
template <typename T>
torch::Tensor samples_to_float(const torch::Tensor& raw, float scale) {
  torch::Tensor out = core::pooled_empty(raw.sizes());
  // Rows of row_length samples, row_stride apart (a window of a whole view).
  const int64_t rows = raw.dim() == 3 ? raw.size(0) : 1;
  const int64_t row_length = rows > 0 ? raw.numel() / rows : 0;
  const int64_t row_stride = raw.is_contiguous() ? row_length : raw.stride(0);
  const T* src = static_cast<const T*>(raw.data_ptr());
  float* dst = out.data_ptr<float>();
  const int64_t grain = std::max<int64_t>(1, (int64_t(1) << 16) / std::max<int64_t>(1, row_length));
  core::parallel_for(0, rows, grain, [&](int64_t begin, int64_t end) {
    for (int64_t r = begin; r < end; ++r) {
      const T* in = src + r * row_stride;
      float* o = dst + r * row_length;
      for (int64_t i = 0; i < row_length; ++i) o[i] = float(in[i]) / scale;
    }
  });
  return out;
}

// Whether a tensor's rows (its last two dimensions) are each contiguous, as
// in a window of a contiguous [H, W, B] view.
bool rows_contiguous(const torch::Tensor& t) {
  return t.is_contiguous() || (t.dim() == 3 && t.stride(2) == 1 && t.stride(1) == t.size(2));
}

}  // namespace

torch::Tensor cube_to_float(const Cube& cube, double scale) {
  if (scale <= 0) scale = cube.scale_factor ? *cube.scale_factor : default_scale(cube.type);
  torch::Tensor raw = cube.data;
  // A window of a view (Scene::image) keeps its rows in place; any other
  // layout is copied first.
  if (!rows_contiguous(raw)) raw = raw.contiguous();
  if (!cube.ignore_value && raw.scalar_type() == detail::tensor_dtype(cube.type)) {
    switch (cube.type) {
      case SampleType::U8:
        return samples_to_float<uint8_t>(raw, float(scale));
      case SampleType::U16:  // kept in an int16 tensor (see cube.h)
        return samples_to_float<uint16_t>(raw, float(scale));
      case SampleType::I16:
        return samples_to_float<int16_t>(raw, float(scale));
      case SampleType::F32:
        return samples_to_float<float>(raw, float(scale));
      default:
        break;
    }
  }
  // Wide types go through double: int32 and float64 samples lose digits in float32
  // before the ignore-value comparison.
  bool wide = cube.type == SampleType::I32 || cube.type == SampleType::F64;
  torch::Tensor values;
  if (cube.type == SampleType::U16) {
    values = raw.to(torch::kInt32).bitwise_and_(0xFFFF).to(torch::kFloat);
  } else {
    values = raw.to(wide ? torch::kDouble : torch::kFloat);
  }
  torch::Tensor ignored;
  if (cube.ignore_value) ignored = values == *cube.ignore_value;
  // In place only on a fresh copy: a float32 cube converts to itself.
  if (values.data_ptr() == raw.data_ptr()) {
    values = values / scale;
  } else {
    values.div_(scale);
  }
  values = values.to(torch::kFloat);
  if (ignored.defined()) values.masked_fill_(ignored, 0.0);
  return values.contiguous();
}

}  // namespace ddhgs::io
