// NumPy .npy arrays (format versions 1.0, 2.0 and 3.0).
#include <cstring>
#include <fstream>

#include "core/buffer_pool.h"
#include "core/error.h"
#include "io/cube/cube_formats.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"
#include "io/files/little_endian.h"

#if __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .npy and ENVI readers assume a little-endian host"
#endif

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

const char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicSize = 6;

struct NpyHeader {
  SampleType type = SampleType::F32;
  bool big_endian = false;
  bool fortran_order = false;
  std::vector<int64_t> shape;
  uint64_t data_offset = 0;  // bytes from the start of the file
};

// The text after `'key':` in the header's Python dict literal, or empty.
std::string dict_value(const std::string& dict, const std::string& key) {
  for (const char* quote : {"'", "\""}) {
    std::string token = quote + key + quote;
    size_t at = dict.find(token);
    if (at == std::string::npos) continue;
    at = dict.find(':', at + token.size());
    if (at == std::string::npos) return {};
    size_t start = dict.find_first_not_of(" \t", at + 1);
    return start == std::string::npos ? std::string() : dict.substr(start);
  }
  return {};
}

SampleType parse_descr(const std::string& value, bool* big_endian, const fs::path& path) {
  auto fail = [&](const std::string& descr) -> SampleType {
    throw core::Error(path, "unsupported dtype '" + descr +
                                "' (expected uint8, uint16, int16, int32, float16, float32 "
                                "or float64)");
  };
  if (value.empty() || (value[0] != '\'' && value[0] != '"')) fail(value.substr(0, 20));
  size_t end = value.find(value[0], 1);
  if (end == std::string::npos) throw core::Error(path, "malformed .npy header (descr)");
  std::string descr = value.substr(1, end - 1);
  if (descr.size() < 3) fail(descr);
  char order = descr[0];
  *big_endian = order == '>';
  if (order != '<' && order != '>' && order != '|' && order != '=') fail(descr);
  std::string code = descr.substr(1);
  if (code == "u1") return SampleType::U8;
  if (code == "u2") return SampleType::U16;
  if (code == "i2") return SampleType::I16;
  if (code == "i4") return SampleType::I32;
  if (code == "f2") return SampleType::F16;
  if (code == "f4") return SampleType::F32;
  if (code == "f8") return SampleType::F64;
  return fail(descr);
}

std::vector<int64_t> parse_shape(const std::string& value, const fs::path& path) {
  size_t close = value.find(')');
  if (value.empty() || value[0] != '(' || close == std::string::npos)
    throw core::Error(path, "malformed .npy header (shape)");
  std::vector<int64_t> shape;
  std::string inner = value.substr(1, close - 1);
  size_t pos = 0;
  while (pos < inner.size()) {
    size_t comma = inner.find(',', pos);
    std::string item =
        inner.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
    size_t first = item.find_first_not_of(" \t");
    if (first != std::string::npos) {
      char* end = nullptr;
      long long dim = std::strtoll(item.c_str() + first, &end, 10);
      if (end == item.c_str() + first || dim < 0)
        throw core::Error(path,
                          "malformed .npy header (shape '" + value.substr(0, close + 1) + "')");
      shape.push_back(dim);
    }
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return shape;
}

NpyHeader read_header(std::istream& in, uint64_t file_size, const fs::path& path) {
  if (file_size == 0) throw core::Error(path, "empty file, expected a .npy array");
  char prefix[12] = {};
  in.read(prefix, 10);
  if (in.gcount() < std::streamsize(kMagicSize) || std::memcmp(prefix, kMagic, kMagicSize) != 0)
    throw core::Error(path, "not a .npy file (bad magic)");
  if (in.gcount() < 10) throw core::Error(path, "truncated .npy header");
  int major = static_cast<unsigned char>(prefix[6]);
  uint64_t header_len = 0, prefix_len = 0;
  if (major == 1) {
    header_len = little_endian({prefix, 10}, 8, 2);
    prefix_len = 10;
  } else if (major == 2 || major == 3) {
    in.read(prefix + 10, 2);
    if (in.gcount() < 2) throw core::Error(path, "truncated .npy header");
    header_len = little_endian({prefix, 12}, 8, 4);
    prefix_len = 12;
  } else {
    throw core::Error(
        path, "unsupported .npy format version " + std::to_string(major) + " (expected 1, 2 or 3)");
  }
  if (prefix_len + header_len > file_size) throw core::Error(path, "truncated .npy header");
  std::string dict(header_len, '\0');
  in.read(dict.data(), std::streamsize(header_len));
  if (uint64_t(in.gcount()) != header_len) throw core::Error(path, "truncated .npy header");

  NpyHeader header;
  header.type = parse_descr(dict_value(dict, "descr"), &header.big_endian, path);
  std::string fortran = dict_value(dict, "fortran_order");
  if (fortran.rfind("True", 0) == 0) {
    header.fortran_order = true;
  } else if (fortran.rfind("False", 0) != 0) {
    throw core::Error(path, "malformed .npy header (fortran_order)");
  }
  header.shape = parse_shape(dict_value(dict, "shape"), path);
  header.data_offset = prefix_len + header_len;
  return header;
}

struct OpenNpy {
  std::ifstream in;
  uint64_t file_size = 0;
  NpyHeader header;
};

void open_npy(const fs::path& path, OpenNpy* npy) {
  std::error_code ec;
  require_regular_file(path);
  npy->file_size = fs::file_size(path, ec);
  npy->in.open(path, std::ios::binary);
  if (ec || !npy->in) throw core::Error(path, "cannot open the file for reading");
  npy->header = read_header(npy->in, npy->file_size, path);
  size_t dims = npy->header.shape.size();
  if (dims != 2 && dims != 3)
    throw core::Error(path, "array has " + std::to_string(dims) +
                                " dimensions, expected 2 (H x W) or 3 (H x W x B or B x H x W)");
}

// Byte count of the array, checked against the file so that a corrupt shape
// can neither overflow nor trigger a huge allocation.
uint64_t data_bytes(const OpenNpy& npy, const fs::path& path) {
  uint64_t available = npy.file_size - npy.header.data_offset;
  uint64_t bytes = bytes_per_sample(npy.header.type);
  for (int64_t dim : npy.header.shape) {
    if (dim == 0) throw core::Error(path, "array is empty (a dimension of its shape is 0)");
    if (bytes > available / uint64_t(dim))
      throw core::Error(path, "truncated: the header describes more data than the " +
                                  std::to_string(available) + " bytes the file holds");
    bytes *= uint64_t(dim);
  }
  if (bytes < available)
    throw core::Error(path, "file holds " + std::to_string(available - bytes) +
                                " bytes more than its header describes");
  return bytes;
}

}  // namespace

namespace detail {

Cube read_npy(const fs::path& path, const CubeReadOptions& options) {
  OpenNpy npy;
  open_npy(path, &npy);
  uint64_t bytes = data_bytes(npy, path);
  const NpyHeader& h = npy.header;
  std::vector<int64_t> stored_shape = h.shape;
  if (h.fortran_order) std::reverse(stored_shape.begin(), stored_shape.end());
  // Pooled: a training run that holds fewer views than it trains on reads a
  // view into the block of one its cache let go, not into fresh pages.
  torch::Tensor data = core::pooled_empty(stored_shape, tensor_dtype(h.type));
  npy.in.read(static_cast<char*>(data.data_ptr()), std::streamsize(bytes));
  if (uint64_t(npy.in.gcount()) != bytes) throw core::Error(path, "read failed (truncated data)");
  if (h.big_endian) swap_bytes(data);
  // A Fortran-order array is the C-order array of the reversed shape, transposed.
  if (h.fortran_order)
    data =
        data.permute(data.dim() == 3 ? std::vector<int64_t>{2, 1, 0} : std::vector<int64_t>{1, 0});
  Cube cube;
  cube.type = h.type;
  cube.data = to_bands_last(data, options.layout, path);
  require_finite(cube.data, path);
  return cube;
}

Cube read_npy_rows(const fs::path& path, int64_t y0, int64_t y1, const CubeReadOptions& options) {
  OpenNpy npy;
  open_npy(path, &npy);
  data_bytes(npy, path);
  const NpyHeader& h = npy.header;
  const std::vector<int64_t>& s = h.shape;
  // Only a C-order [H, W, B] or [H, W] array holds a row range as one run of
  // bytes; any other layout is read whole.
  const bool rows_contiguous =
      !h.fortran_order && (s.size() == 2 || !bands_first(s[0], s[1], s[2], options.layout));
  if (!rows_contiguous) return slice_rows(read_npy(path, options), path, y0, y1);
  require_rows(path, s[0], y0, y1);
  std::vector<int64_t> shape = s;
  shape[0] = y1 - y0;
  const uint64_t row_bytes =
      uint64_t(s[1]) * (s.size() == 3 ? uint64_t(s[2]) : 1) * bytes_per_sample(h.type);
  const uint64_t bytes = row_bytes * uint64_t(y1 - y0);
  torch::Tensor data = core::pooled_empty(shape, tensor_dtype(h.type));
  npy.in.seekg(std::streamoff(h.data_offset + row_bytes * uint64_t(y0)));
  npy.in.read(static_cast<char*>(data.data_ptr()), std::streamsize(bytes));
  if (uint64_t(npy.in.gcount()) != bytes) throw core::Error(path, "read failed (truncated data)");
  if (h.big_endian) swap_bytes(data);
  Cube cube;
  cube.type = h.type;
  cube.data = data.dim() == 2 ? data.unsqueeze(2) : data;
  require_finite(cube.data, path);
  return cube;
}

CubeInfo probe_npy(const fs::path& path, const CubeReadOptions& options) {
  OpenNpy npy;
  open_npy(path, &npy);
  data_bytes(npy, path);
  const std::vector<int64_t>& s = npy.header.shape;
  CubeInfo info;
  info.type = npy.header.type;
  if (s.size() == 2) {
    info.height = s[0], info.width = s[1], info.bands = 1;
  } else if (bands_first(s[0], s[1], s[2], options.layout)) {
    info.bands = s[0], info.height = s[1], info.width = s[2];
  } else {
    info.height = s[0], info.width = s[1], info.bands = s[2];
  }
  return info;
}

}  // namespace detail

void write_npy(const fs::path& path, const torch::Tensor& data, SampleType type_if_u16) {
  std::string descr;
  switch (data.scalar_type()) {
    case torch::kUInt8:
      descr = "|u1";
      break;
    case torch::kInt16:
      descr = type_if_u16 == SampleType::U16 ? "<u2" : "<i2";
      break;
    case torch::kInt32:
      descr = "<i4";
      break;
    case torch::kHalf:
      descr = "<f2";
      break;
    case torch::kFloat:
      descr = "<f4";
      break;
    case torch::kDouble:
      descr = "<f8";
      break;
    default:
      throw core::Error(
          path, std::string("cannot write a .npy of dtype ") + c10::toString(data.scalar_type()));
  }
  torch::Tensor contiguous = data.cpu().contiguous();
  std::string shape;
  for (int64_t dim : contiguous.sizes()) shape += (shape.empty() ? "" : ", ") + std::to_string(dim);
  if (contiguous.dim() == 1) shape += ",";  // Python's one-element tuple
  std::string dict =
      "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" + shape + "), }";
  // NumPy pads the header with spaces and a newline so the data starts 64-byte aligned.
  size_t total = 10 + dict.size() + 1;
  dict.append((64 - total % 64) % 64, ' ');
  dict.push_back('\n');
  std::string prefix(kMagic, kMagicSize);
  prefix += '\x01';
  prefix += '\x00';
  prefix += char(dict.size() & 0xff);
  prefix += char(dict.size() >> 8);
  std::string_view samples(static_cast<const char*>(contiguous.data_ptr()),
                           size_t(contiguous.nbytes()));
  write_parts_atomically(path, {prefix, dict, samples});
}

}  // namespace ddhgs::io
