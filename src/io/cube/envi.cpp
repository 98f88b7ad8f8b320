// ENVI cubes: a text header (.hdr) beside a raw data file.
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "io/cube/cube_formats.h"
#include "io/files/atomic_file.h"
#include "io/files/byte_count.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

struct EnviHeader {
  int64_t samples = 0, lines = 0, bands = 0;  // width, height, band count
  uint64_t offset = 0;                        // bytes before the samples in the data file
  SampleType type = SampleType::U8;
  EnviInterleave interleave = EnviInterleave::BSQ;
  bool big_endian = false;
  std::vector<double> wavelengths_nm;
  std::optional<double> ignore_value;
  std::optional<double> scale_factor;  // "reflectance scale factor"
  fs::path hdr, data;
};

using core::lower;
using core::trim;

// key = value pairs; a value opened with '{' runs, across lines, to its '}'.
std::map<std::string, std::string> parse_pairs(const std::string& text, const fs::path& hdr) {
  std::map<std::string, std::string> pairs;
  size_t pos = 0;
  auto next_line = [&](std::string* line) {
    if (pos >= text.size()) return false;
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    *line = text.substr(pos, end - pos);
    pos = end + 1;
    return true;
  };
  std::string line;
  while (next_line(&line) && trim(line).empty()) {
  }
  if (trim(line).rfind("ENVI", 0) != 0)
    throw core::Error(hdr, "not an ENVI header (its first line must be 'ENVI')");
  while (next_line(&line)) {
    size_t eq = line.find('=');
    if (eq == std::string::npos || trim(line).rfind(';', 0) == 0) continue;
    std::string key = lower(trim(line.substr(0, eq)));
    std::string value = trim(line.substr(eq + 1));
    if (!value.empty() && value[0] == '{') {
      std::string more;
      while (value.find('}') == std::string::npos) {
        if (!next_line(&more)) throw core::Error(hdr, "'" + key + "' list has no closing '}'");
        value += " " + trim(more);
      }
      value = trim(value.substr(1, value.find('}') - 1));
    }
    pairs[key] = value;
  }
  return pairs;
}

double parse_number(const std::string& text, const std::string& key, const fs::path& hdr) {
  std::string t = trim(text);
  char* end = nullptr;
  double v = std::strtod(t.c_str(), &end);
  if (t.empty() || end != t.c_str() + t.size())
    throw core::Error(hdr, "'" + key + "' is '" + t + "', expected a number");
  return v;
}

int64_t required_int(const std::map<std::string, std::string>& pairs, const std::string& key,
                     const fs::path& hdr, int64_t min_value) {
  auto it = pairs.find(key);
  if (it == pairs.end()) throw core::Error(hdr, "missing required key '" + key + "'");
  double v = parse_number(it->second, key, hdr);
  if (v != std::floor(v) || v < double(min_value) || v > 9e15)
    throw core::Error(hdr, "'" + key + "' is '" + it->second +
                               "', expected an integer >= " + std::to_string(min_value));
  return int64_t(v);
}

SampleType envi_type(int64_t code, const fs::path& hdr) {
  switch (code) {
    case 1:
      return SampleType::U8;
    case 2:
      return SampleType::I16;
    case 3:
      return SampleType::I32;
    case 4:
      return SampleType::F32;
    case 5:
      return SampleType::F64;
    case 12:
      return SampleType::U16;
    default:
      throw core::Error(hdr, "unsupported data type " + std::to_string(code) +
                                 " (expected 1 uint8, 2 int16, 3 int32, 4 float32, 5 float64 "
                                 "or 12 uint16)");
  }
}

int envi_code(SampleType type) {
  switch (type) {
    case SampleType::U8:
      return 1;
    case SampleType::I16:
      return 2;
    case SampleType::I32:
      return 3;
    case SampleType::F32:
      return 4;
    case SampleType::F64:
      return 5;
    case SampleType::U16:
      return 12;
    case SampleType::F16:
      break;
  }
  return 0;
}

// Multiplier from the header's wavelength unit to nm; 0 if it is not a length.
double nm_per_unit(const std::string& units, const std::vector<double>& values) {
  std::string u = lower(trim(units));
  if (u == "nanometers" || u == "nanometer" || u == "nm") return 1.0;
  if (u == "micrometers" || u == "micrometer" || u == "microns" || u == "micron" || u == "um" ||
      u == "\xc2\xb5m")
    return 1000.0;
  if (u == "millimeters" || u == "millimeter" || u == "mm") return 1e6;
  if (u.empty() || u == "unknown") {
    // Unlabelled values below 30 can only be micrometres for imaging spectra.
    double top = values.empty() ? 0.0 : *std::max_element(values.begin(), values.end());
    return top < 30.0 ? 1000.0 : 1.0;
  }
  return 0.0;
}

std::vector<double> parse_wavelengths(const std::map<std::string, std::string>& pairs,
                                      int64_t bands, const fs::path& hdr) {
  auto it = pairs.find("wavelength");
  if (it == pairs.end()) return {};
  std::vector<double> values;
  std::string list = it->second;
  size_t pos = 0;
  while (pos <= list.size()) {
    size_t comma = std::min(list.find(',', pos), list.size());
    std::string item = trim(list.substr(pos, comma - pos));
    if (!item.empty()) values.push_back(parse_number(item, "wavelength", hdr));
    pos = comma + 1;
  }
  if (int64_t(values.size()) != bands)
    throw core::Error(hdr, "'wavelength' lists " + std::to_string(values.size()) + " values for " +
                               std::to_string(bands) + " bands");
  auto units = pairs.find("wavelength units");
  double scale = nm_per_unit(units == pairs.end() ? "" : units->second, values);
  if (scale == 0.0) {
    core::log_warn(hdr.string() + ": wavelength units '" + units->second +
                   "' are not a length; wavelengths ignored");
    return {};
  }
  for (double& v : values) {
    // Bands outside the selected range are dropped: a wavelength <= 0 would
    // vanish without a word.
    if (!(v > 0))
      throw core::Error(hdr, "'wavelength' holds " + std::to_string(v) + ", expected values > 0");
    v *= scale;
  }
  return values;
}

fs::path find_data_file(const fs::path& hdr) {
  fs::path stem = fs::path(hdr).replace_extension();
  std::error_code ec;
  for (const char* ext : {"", ".img", ".raw", ".dat", ".bsq", ".bil", ".bip", ".IMG", ".RAW",
                          ".DAT", ".BSQ", ".BIL", ".BIP"}) {
    fs::path candidate = stem.string() + ext;
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  throw core::Error(hdr, "no data file beside the header (looked for " + stem.filename().string() +
                             " with no extension or .img/.raw/.dat/.bsq/.bil/.bip)");
}

fs::path find_header(const fs::path& path) {
  std::string ext = lower(path.extension().string());
  if (ext == ".hdr") return path;
  std::error_code ec;
  for (const fs::path& candidate :
       {fs::path(path).replace_extension(".hdr"), fs::path(path).replace_extension(".HDR"),
        fs::path(path.string() + ".hdr")}) {
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  throw core::Error(path, "no ENVI header beside the data file (expected " +
                              fs::path(path).replace_extension(".hdr").filename().string() + ")");
}

EnviHeader read_header(const fs::path& path) {
  EnviHeader h;
  h.hdr = find_header(path);
  std::string text = read_file(h.hdr);
  if (trim(text).empty()) throw core::Error(h.hdr, "empty file, expected an ENVI header");
  auto pairs = parse_pairs(text, h.hdr);
  h.samples = required_int(pairs, "samples", h.hdr, 1);
  h.lines = required_int(pairs, "lines", h.hdr, 1);
  h.bands = required_int(pairs, "bands", h.hdr, 1);
  h.type = envi_type(required_int(pairs, "data type", h.hdr, 0), h.hdr);
  if (pairs.count("header offset"))
    h.offset = uint64_t(required_int(pairs, "header offset", h.hdr, 0));
  if (pairs.count("byte order")) {
    int64_t order = required_int(pairs, "byte order", h.hdr, 0);
    if (order > 1) throw core::Error(h.hdr, "'byte order' must be 0 or 1");
    h.big_endian = order == 1;
  }
  std::string interleave = lower(pairs.count("interleave") ? pairs["interleave"] : "bsq");
  if (interleave == "bsq") {
    h.interleave = EnviInterleave::BSQ;
  } else if (interleave == "bil") {
    h.interleave = EnviInterleave::BIL;
  } else if (interleave == "bip") {
    h.interleave = EnviInterleave::BIP;
  } else {
    throw core::Error(h.hdr, "interleave '" + interleave + "' is not bsq, bil or bip");
  }
  h.wavelengths_nm = parse_wavelengths(pairs, h.bands, h.hdr);
  if (pairs.count("data ignore value"))
    h.ignore_value = parse_number(pairs["data ignore value"], "data ignore value", h.hdr);
  if (pairs.count("reflectance scale factor")) {
    const char* key = "reflectance scale factor";
    double factor = parse_number(pairs[key], key, h.hdr);
    if (!(factor > 0) || !std::isfinite(factor))
      throw core::Error(
          h.hdr, "'reflectance scale factor' is '" + pairs[key] + "', expected a positive number");
    h.scale_factor = factor;
  }
  h.data = find_data_file(h.hdr);
  return h;
}

uint64_t checked_data_bytes(const EnviHeader& h) {
  std::error_code ec;
  uint64_t size = fs::file_size(h.data, ec);
  if (ec) throw core::Error(h.data, "cannot read the file size");
  if (size == 0) throw core::Error(h.data, "empty data file");
  if (size < h.offset)
    throw core::Error(h.data, "truncated: the header " + h.hdr.filename().string() +
                                  " puts the samples at byte " + std::to_string(h.offset) +
                                  ", the file holds " + std::to_string(size));
  return require_present(h.data, "the header " + h.hdr.filename().string(),
                         {uint64_t(h.lines), uint64_t(h.samples), uint64_t(h.bands)},
                         bytes_per_sample(h.type), size - h.offset);
}

}  // namespace

namespace detail {

Cube read_envi(const fs::path& path) {
  EnviHeader h = read_header(path);
  uint64_t bytes = checked_data_bytes(h);
  std::vector<int64_t> shape;
  switch (h.interleave) {
    case EnviInterleave::BSQ:
      shape = {h.bands, h.lines, h.samples};
      break;
    case EnviInterleave::BIL:
      shape = {h.lines, h.bands, h.samples};
      break;
    case EnviInterleave::BIP:
      shape = {h.lines, h.samples, h.bands};
      break;
  }
  torch::Tensor data = torch::empty(shape, torch::TensorOptions(tensor_dtype(h.type)));
  std::ifstream in(h.data, std::ios::binary);
  in.seekg(std::streamoff(h.offset));
  in.read(static_cast<char*>(data.data_ptr()), std::streamsize(bytes));
  if (!in || uint64_t(in.gcount()) != bytes) throw core::Error(h.data, "read failed");
  if (h.big_endian) swap_bytes(data);
  // Both are per-view transposes: BSQ [B, H*W] -> [H*W, B], BIL [B, W] per line.
  if (h.interleave == EnviInterleave::BSQ)
    data = transpose_last_two(data.view({1, h.bands, -1})).view({h.lines, h.samples, h.bands});
  if (h.interleave == EnviInterleave::BIL) data = transpose_last_two(data);
  Cube cube;
  cube.type = h.type;
  cube.data = data;
  cube.wavelengths_nm = h.wavelengths_nm;
  cube.ignore_value = h.ignore_value;
  cube.scale_factor = h.scale_factor;
  require_finite(cube.data, h.data);
  return cube;
}

CubeInfo probe_envi(const fs::path& path) {
  EnviHeader h = read_header(path);
  checked_data_bytes(h);
  CubeInfo info;
  info.height = h.lines, info.width = h.samples, info.bands = h.bands;
  info.type = h.type;
  info.wavelengths_nm = h.wavelengths_nm;
  info.scale_factor = h.scale_factor;
  return info;
}

}  // namespace detail

void write_envi(const fs::path& hdr_path, const torch::Tensor& data,
                const std::vector<double>& wavelengths_nm, EnviInterleave interleave,
                SampleType type_if_u16) {
  if (lower(hdr_path.extension().string()) != ".hdr")
    throw core::Error(hdr_path, "an ENVI header name must end in .hdr");
  torch::Tensor cube = data.cpu();
  if (cube.dim() == 2) cube = cube.unsqueeze(2);
  if (cube.dim() != 3) throw core::Error(hdr_path, "write_envi expects a cube [H, W, B]");
  // ENVI has no half-precision type.
  if (cube.scalar_type() == torch::kHalf) cube = cube.to(torch::kFloat);
  SampleType type = detail::sample_type_of(cube.scalar_type(), hdr_path);
  if (type == SampleType::I16) type = type_if_u16 == SampleType::U16 ? SampleType::U16 : type;
  if (!wavelengths_nm.empty() && int64_t(wavelengths_nm.size()) != cube.size(2))
    throw core::Error(hdr_path, std::to_string(wavelengths_nm.size()) + " wavelengths for " +
                                    std::to_string(cube.size(2)) + " bands");
  int64_t height = cube.size(0), width = cube.size(1), bands = cube.size(2);
  const char* name = "bsq";
  if (interleave == EnviInterleave::BSQ) cube = cube.permute({2, 0, 1});
  if (interleave == EnviInterleave::BIL) cube = cube.permute({0, 2, 1}), name = "bil";
  if (interleave == EnviInterleave::BIP) name = "bip";
  cube = cube.contiguous();

  std::string header = "ENVI\ndescription = {written by ddhgs}\n";
  header += "samples = " + std::to_string(width) + "\nlines = " + std::to_string(height) +
            "\nbands = " + std::to_string(bands) + "\n";
  header += "header offset = 0\nfile type = ENVI Standard\n";
  header += "data type = " + std::to_string(envi_code(type)) + "\n";
  header += std::string("interleave = ") + name + "\nbyte order = 0\n";
  if (!wavelengths_nm.empty()) {
    header += "wavelength units = Nanometers\nwavelength = {";
    char number[32];
    for (size_t i = 0; i < wavelengths_nm.size(); ++i) {
      std::snprintf(number, sizeof(number), "%.12g", wavelengths_nm[i]);
      header += (i ? ", " : "") + std::string(number);
    }
    header += "}\n";
  }
  // The data first: a header never points at a missing or stale data file.
  std::string_view samples(static_cast<const char*>(cube.data_ptr()), size_t(cube.nbytes()));
  write_parts_atomically(fs::path(hdr_path).replace_extension(".img"), {samples});
  write_file_atomically(hdr_path, header);
}

}  // namespace ddhgs::io
