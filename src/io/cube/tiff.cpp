// Multi-band TIFF through libtiff: bands as samples of one page (contiguous
// or separate planes) or one single-sample page per band.
#include <tiffio.h>

#include <cstdarg>
#include <cstring>

#include "core/error.h"
#include "core/log.h"
#include "io/cube/cube_formats.h"
#include "io/cube/tiff_open.h"
#include "io/files/atomic_file.h"
#include "io/files/byte_count.h"
#include "io/files/input_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// libtiff reports problems through callbacks; keep the last error per handle
// so it can go into the one-line core::Error instead of stderr.
int keep_error(TIFF*, void* user_data, const char*, const char* fmt, va_list ap) {
  char text[512];
  std::vsnprintf(text, sizeof(text), fmt, ap);
  *static_cast<std::string*>(user_data) = text;
  return 1;
}
int ignore_warning(TIFF*, void*, const char*, const char*, va_list) {
  return 1;
}

}  // namespace

TIFF* open_tiff_quietly(const fs::path& path, const char* mode, std::string* error) {
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  TIFFOpenOptionsSetErrorHandlerExtR(options, keep_error, error);
  TIFFOpenOptionsSetWarningHandlerExtR(options, ignore_warning, nullptr);
  TIFF* tif = TIFFOpenExt(path.c_str(), mode, options);
  TIFFOpenOptionsFree(options);
  return tif;
}

namespace {

class TiffFile {
 public:
  TiffFile(const fs::path& path, const char* mode)
      : path_(path), tif_(open_tiff_quietly(path, mode, &error_)) {}
  ~TiffFile() {
    if (tif_) TIFFClose(tif_);
  }
  TiffFile(const TiffFile&) = delete;
  TiffFile& operator=(const TiffFile&) = delete;

  TIFF* get() const { return tif_; }
  // Closing flushes the last directory: its failure is a write failure.
  void close() {
    TIFF* tif = tif_;
    tif_ = nullptr;
    TIFFClose(tif);
  }
  // libtiff reports some damage (a broken page chain) only through the handler.
  void require_no_error(const fs::path& named) const {
    if (!error_.empty()) fail(named, "corrupt TIFF file");
  }
  [[noreturn]] void fail(const fs::path& named, const std::string& what) const {
    throw core::Error(named, what + (error_.empty() ? "" : " (" + error_ + ")"));
  }

 private:
  fs::path path_;
  std::string error_;
  TIFF* tif_ = nullptr;
};

struct PageFormat {
  uint32_t width = 0, height = 0;
  uint16_t samples = 1, bits = 8, sample_format = SAMPLEFORMAT_UINT, planar = PLANARCONFIG_CONTIG;
  uint16_t compression = COMPRESSION_NONE;
  bool same_as(const PageFormat& o) const {
    return width == o.width && height == o.height && samples == o.samples && bits == o.bits &&
           sample_format == o.sample_format;
  }
};

PageFormat page_format(TIFF* tif) {
  PageFormat f;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &f.width);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &f.height);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &f.samples);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &f.bits);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &f.sample_format);
  TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &f.planar);
  TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &f.compression);
  return f;
}

SampleType sample_type(const PageFormat& f, const fs::path& path) {
  bool is_uint = f.sample_format == SAMPLEFORMAT_UINT, is_int = f.sample_format == SAMPLEFORMAT_INT,
       is_float = f.sample_format == SAMPLEFORMAT_IEEEFP;
  if (f.bits == 8 && is_uint) return SampleType::U8;
  if (f.bits == 16 && is_uint) return SampleType::U16;
  if (f.bits == 16 && is_int) return SampleType::I16;
  if (f.bits == 32 && is_int) return SampleType::I32;
  if (f.bits == 32 && is_float) return SampleType::F32;
  if (f.bits == 64 && is_float) return SampleType::F64;
  throw core::Error(path, "unsupported TIFF samples: " + std::to_string(f.bits) + "-bit format " +
                              std::to_string(f.sample_format) +
                              " (expected 8/16-bit unsigned, 16/32-bit signed, 32/64-bit float)");
}

// The layout of a file: pages holding one band each, or one page holding all.
struct TiffLayoutInfo {
  PageFormat first;
  SampleType type = SampleType::U8;
  int64_t bands = 0;
  bool page_per_band = false;
  bool compressed = false;  // any page
};

// The cube the header declares must fit in the file: exactly when the
// samples are stored raw, within a compression ratio otherwise.
void require_declared_size_fits(const TiffLayoutInfo& info, const fs::path& path) {
  std::error_code ec;
  const uint64_t file_bytes = fs::file_size(path, ec);
  const std::initializer_list<uint64_t> dims{info.first.height, info.first.width,
                                             uint64_t(info.bands)};
  if (info.compressed)
    require_decodable(
        path,
        checked_product({checked_product(dims).value_or(UINT64_MAX), bytes_per_sample(info.type)}),
        file_bytes);
  else
    require_present(path, "the TIFF header", dims, bytes_per_sample(info.type), file_bytes);
}

TiffLayoutInfo inspect(TiffFile& file, const fs::path& path) {
  TIFF* tif = file.get();
  TiffLayoutInfo info;
  info.first = page_format(tif);
  if (info.first.width == 0 || info.first.height == 0)
    throw core::Error(path, "TIFF page has no width or height");
  info.type = sample_type(info.first, path);
  int pages = TIFFNumberOfDirectories(tif);
  file.require_no_error(path);
  info.page_per_band = pages > 1 && info.first.samples == 1;
  info.bands = info.page_per_band ? pages : info.first.samples;
  info.compressed = info.first.compression != COMPRESSION_NONE;
  if (pages > 1 && !info.page_per_band)
    core::log_warn(path.string() + ": reads the first of " + std::to_string(pages) +
                   " multi-sample TIFF pages");
  for (int page = 1; info.page_per_band && page < pages; ++page) {
    if (!TIFFSetDirectory(tif, tdir_t(page)))
      file.fail(path, "cannot read TIFF page " + std::to_string(page + 1));
    const PageFormat format = page_format(tif);
    if (!format.same_as(info.first))
      throw core::Error(path, "TIFF page " + std::to_string(page + 1) +
                                  " differs in size or sample format from page 1; expected one "
                                  "band per page");
    info.compressed = info.compressed || format.compression != COMPRESSION_NONE;
  }
  TIFFSetDirectory(tif, 0);
  require_declared_size_fits(info, path);
  return info;
}

template <typename T>
void scatter_one(const uint8_t* src, int64_t pixels, uint8_t* dst, int64_t bands) {
  for (int64_t p = 0; p < pixels; ++p)
    std::memcpy(dst + size_t(p * bands) * sizeof(T), src + size_t(p) * sizeof(T), sizeof(T));
}

// Copies pixels of `count` samples each into a [H, W, B] buffer at band `band`.
// One page per band (count 1) is the common slow case: typed copies there.
void scatter(const uint8_t* src, int64_t pixels, int64_t count, size_t sample_bytes, uint8_t* dst,
             int64_t bands) {
  size_t src_stride = size_t(count) * sample_bytes, dst_stride = size_t(bands) * sample_bytes;
  if (count == bands) {
    std::memcpy(dst, src, size_t(pixels) * src_stride);
  } else if (count == 1 && sample_bytes == 1) {
    scatter_one<uint8_t>(src, pixels, dst, bands);
  } else if (count == 1 && sample_bytes == 2) {
    scatter_one<uint16_t>(src, pixels, dst, bands);
  } else if (count == 1 && sample_bytes == 4) {
    scatter_one<uint32_t>(src, pixels, dst, bands);
  } else {
    for (int64_t p = 0; p < pixels; ++p)
      std::memcpy(dst + size_t(p) * dst_stride, src + size_t(p) * src_stride, src_stride);
  }
}

// Reads the current page into bands [band, band + samples) of out [H, W, B].
void read_page(TiffFile& file, const PageFormat& f, int64_t band, torch::Tensor& out,
               const fs::path& path) {
  TIFF* tif = file.get();
  size_t bytes = out.element_size();
  int64_t bands = out.size(2), width = f.width;
  auto* base = static_cast<uint8_t*>(out.data_ptr());
  bool separate = f.planar == PLANARCONFIG_SEPARATE && f.samples > 1;
  int64_t per_pixel = separate ? 1 : f.samples;
  int planes = separate ? f.samples : 1;
  auto pixel = [&](int64_t row, int64_t col, int plane) {
    return base + ((row * width + col) * bands + band + plane) * int64_t(bytes);
  };
  if (TIFFIsTiled(tif)) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
    if (tw == 0 || th == 0) file.fail(path, "TIFF tiles of zero size");
    std::vector<uint8_t> tile(size_t(TIFFTileSize(tif)));
    // Subsampled (YCbCr) tiles are smaller than the pixels they decode to.
    if (uint64_t(tile.size()) < uint64_t(tw) * th * per_pixel * bytes)
      file.fail(path, "unsupported TIFF tile layout (subsampled samples?)");
    for (int plane = 0; plane < planes; ++plane)
      for (uint32_t y = 0; y < f.height; y += th)
        for (uint32_t x = 0; x < f.width; x += tw) {
          if (TIFFReadTile(tif, tile.data(), x, y, 0, uint16_t(plane)) < 0)
            file.fail(path, "truncated or corrupt TIFF tile");
          int64_t cols = std::min<int64_t>(tw, f.width - x);
          for (uint32_t ty = 0; ty < th && y + ty < f.height; ++ty)
            scatter(tile.data() + size_t(ty) * tw * per_pixel * bytes, cols, per_pixel, bytes,
                    pixel(y + ty, x, plane), bands);
        }
    return;
  }
  std::vector<uint8_t> line(size_t(TIFFScanlineSize(tif)));
  if (uint64_t(line.size()) < uint64_t(width) * per_pixel * bytes)
    file.fail(path, "unsupported TIFF row layout (subsampled samples?)");
  for (int plane = 0; plane < planes; ++plane)
    for (uint32_t row = 0; row < f.height; ++row) {
      if (TIFFReadScanline(tif, line.data(), row, uint16_t(plane)) < 0)
        file.fail(path, "truncated or corrupt TIFF data at row " + std::to_string(row));
      scatter(line.data(), width, per_pixel, bytes, pixel(row, 0, plane), bands);
    }
}

void open_for_reading(TiffFile& file, const fs::path& path) {
  if (!file.get()) file.fail(path, "not a readable TIFF file");
}

void require_nonempty(const fs::path& path) {
  require_regular_file(path);
  std::error_code ec;
  if (fs::file_size(path, ec) == 0) throw core::Error(path, "empty file, expected a TIFF image");
}

}  // namespace

namespace detail {

Cube read_tiff(const fs::path& path) {
  require_nonempty(path);
  TiffFile file(path, "r");
  open_for_reading(file, path);
  TiffLayoutInfo info = inspect(file, path);
  Cube cube;
  cube.type = info.type;
  cube.data = torch::empty({int64_t(info.first.height), int64_t(info.first.width), info.bands},
                           torch::TensorOptions(tensor_dtype(info.type)));
  int64_t pages = info.page_per_band ? info.bands : 1;
  for (int64_t page = 0; page < pages; ++page) {
    if (!TIFFSetDirectory(file.get(), tdir_t(page)))
      file.fail(path, "cannot read TIFF page " + std::to_string(page + 1));
    read_page(file, page_format(file.get()), page, cube.data, path);
  }
  file.require_no_error(path);
  require_finite(cube.data, path);
  return cube;
}

CubeInfo probe_tiff(const fs::path& path) {
  require_nonempty(path);
  TiffFile file(path, "r");
  open_for_reading(file, path);
  TiffLayoutInfo layout = inspect(file, path);
  CubeInfo info;
  info.height = layout.first.height, info.width = layout.first.width, info.bands = layout.bands;
  info.type = layout.type;
  info.compressed = layout.compressed;
  return info;
}

}  // namespace detail

void write_tiff(const fs::path& path, const torch::Tensor& data, TiffLayout layout,
                SampleType type_if_u16) {
  torch::Tensor cube = data.cpu();
  if (cube.dim() == 2) cube = cube.unsqueeze(2);
  if (cube.dim() != 3 || cube.numel() == 0)
    throw core::Error(path, "write_tiff expects a non-empty cube [H, W, B]");
  SampleType type = detail::sample_type_of(cube.scalar_type(), path);
  if (type == SampleType::I16 && type_if_u16 == SampleType::U16) type = SampleType::U16;
  uint16_t format = type == SampleType::F16 || type == SampleType::F32 || type == SampleType::F64
                        ? SAMPLEFORMAT_IEEEFP
                    : type == SampleType::U8 || type == SampleType::U16 ? SAMPLEFORMAT_UINT
                                                                        : SAMPLEFORMAT_INT;
  if (type == SampleType::F16) throw core::Error(path, "TIFF cubes cannot hold float16");
  int64_t height = cube.size(0), width = cube.size(1), bands = cube.size(2);
  bool pages = layout == TiffLayout::Pages && bands > 1;
  bool separate = layout == TiffLayout::Separate && bands > 1;
  // Rows of one plane, contiguous: [planes, H, W * samples].
  torch::Tensor rows = (pages || separate) ? cube.permute({2, 0, 1}).contiguous()
                                           : cube.contiguous().view({1, height, width * bands});
  uint16_t samples = uint16_t(pages ? 1 : bands);
  write_atomically(path, [&](const fs::path& tmp) {
    TiffFile file(tmp, "w");
    if (!file.get()) file.fail(path, "cannot create the TIFF file");
    TIFF* tif = file.get();
    for (int64_t page = 0; page < (pages ? bands : 1); ++page) {
      TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(width));
      TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(height));
      TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, samples);
      TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(8 * bytes_per_sample(type)));
      TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, format);
      TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
      TIFFSetField(tif, TIFFTAG_PLANARCONFIG,
                   separate ? PLANARCONFIG_SEPARATE : PLANARCONFIG_CONTIG);
      TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(tif, 0));
      if (samples > 1) {
        // Bands beyond the first are "extra samples" of unspecified meaning.
        std::vector<uint16_t> extra(samples - 1, EXTRASAMPLE_UNSPECIFIED);
        TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, uint16_t(extra.size()), extra.data());
      }
      for (int64_t plane = 0; plane < (separate ? bands : 1); ++plane)
        for (int64_t row = 0; row < height; ++row) {
          auto* src = static_cast<uint8_t*>(rows[pages ? page : plane][row].data_ptr());
          if (TIFFWriteScanline(tif, src, uint32_t(row), uint16_t(plane)) < 0)
            file.fail(path, "TIFF write failed");
        }
      if (!TIFFWriteDirectory(tif)) file.fail(path, "TIFF write failed");
    }
    file.close();
  });
}

}  // namespace ddhgs::io
