// N-band Gaussian PLY files and point-cloud PLY files on top of the PLY
// container (io/ply_format.h).
#include "io/ply/ply.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/camera.h"
#include "core/error.h"
#include "core/log.h"
#include "core/number_range.h"
#include "core/text.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"
#include "io/ply/ply_format.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

using ply::Column;
using ply::Element;
using ply::Type;

constexpr const char* kWavelengthsComment = "wavelengths";
constexpr const char* kBasisComment = "band_basis";

struct OpenPly {
  std::ifstream in;
  ply::Header header;
  int vertex = -1;
  const Element& element() const { return header.elements[size_t(vertex)]; }
};

// Opens the file and parses the header; the file must have a vertex element.
void open_ply(const fs::path& path, OpenPly& ply) {
  require_regular_file(path);
  ply.in.open(path, std::ios::binary);
  if (!ply.in) throw core::Error(path, "cannot open for reading");
  ply.header = ply::read_header(ply.in, path);
  ply.vertex = ply.header.find("vertex");
  if (ply.vertex < 0) throw core::Error(path, "PLY file has no 'vertex' element");
  ply::check_file_size(path, ply.header, ply.vertex);
}

int require_property(const fs::path& path, const Element& vertex, const std::string& name,
                     const std::string& kind) {
  int index = vertex.find(name);
  if (index < 0) throw core::Error(path, "missing vertex property '" + name + "' (" + kind + ")");
  return index;
}

// Properties prefix0, prefix1, ... in index order; they must be numbered 0..n-1.
std::vector<int> numbered_properties(const fs::path& path, const Element& vertex,
                                     const std::string& prefix) {
  size_t n = 0;
  for (const auto& property : vertex.properties)
    if (property.name.rfind(prefix, 0) == 0) ++n;
  std::vector<int> indices;
  for (size_t i = 0; i < n; ++i) {
    int index = vertex.find(prefix + std::to_string(i));
    if (index < 0)
      throw core::Error(path, "vertex properties " + prefix + "* are not numbered 0.." +
                                  std::to_string(n - 1) + ": " + prefix + std::to_string(i) +
                                  " is missing");
    indices.push_back(index);
  }
  return indices;
}

// Columns filling `count` consecutive floats per entry of a [entries, count] tensor.
void add_columns(std::vector<Column>& columns, const std::vector<int>& properties,
                 torch::Tensor& target) {
  // No entries: no storage, and no offset may be applied to its null pointer
  // (undefined behaviour, found by UBSan); nothing is written through it.
  float* base = target.numel() > 0 ? target.data_ptr<float>() : nullptr;
  const int64_t stride = target.numel() / std::max<int64_t>(target.size(0), 1);
  for (size_t i = 0; i < properties.size(); ++i)
    columns.push_back({properties[i], base ? base + i : nullptr, nullptr, stride});
}

// One number of a header comment line ("comment wavelengths 450 ...",
// line 1 of them), finite and within core::kMaxFileNumber.
double comment_number(const fs::path& path, const std::string& word, const std::string& line) {
  double value = 0;
  auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  const bool whole = end == word.data() + word.size();
  if (error == std::errc::result_out_of_range && whole)
    value = HUGE_VAL;
  else if (error != std::errc() || !whole || std::isnan(value))
    throw core::Error(path, line + " has a non-number " + core::quoted_value(word));
  if (!core::renderable_number(value))
    throw core::Error(path, line + ": " + core::quoted_value(word) + " is out of range (at most " +
                                core::format_g(core::kMaxFileNumber) + " in magnitude)");
  return value;
}

std::vector<double> parse_wavelengths(const fs::path& path, const ply::Header& header) {
  std::vector<double> wavelengths;
  for (const auto& comment : header.comments) {
    std::istringstream words(comment);
    std::string first;
    words >> first;
    if (first != kWavelengthsComment) continue;
    std::string word;
    while (words >> word)
      wavelengths.push_back(comment_number(path, word, "'comment wavelengths'"));
  }
  return wavelengths;
}

// The "band_basis" lines in order: [N, C + 1] (mean, then the basis row), or
// undefined when there are none.
torch::Tensor parse_band_basis(const fs::path& path, const ply::Header& header, int64_t channels) {
  std::vector<double> values;
  int64_t rows = 0;
  for (const auto& comment : header.comments) {
    std::istringstream words(comment);
    std::string first, word;
    words >> first;
    if (first != kBasisComment) continue;
    int64_t count = 0;
    const std::string line = "'comment band_basis' line " + std::to_string(rows + 1);
    while (words >> word) {
      values.push_back(comment_number(path, word, line));
      ++count;
    }
    if (count != channels + 1)
      throw core::Error(path, "'comment band_basis' line " + std::to_string(rows + 1) + " has " +
                                  std::to_string(count) + " numbers; expected " +
                                  std::to_string(channels + 1) +
                                  " (the mean and one per f_dc_* channel)");
    ++rows;
  }
  if (rows == 0) return {};
  return torch::tensor(values, torch::kFloat64).reshape({rows, channels + 1}).to(torch::kFloat32);
}

// Shortest text that reads back as the same double.
std::string format_number(double value) {
  char buffer[32];
  auto [end, error] = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, end);
}

// t as float32 [rows, prod(rest of shape)] after checking it has exactly `shape`.
torch::Tensor as_float_rows(const fs::path& path, const torch::Tensor& t,
                            std::vector<int64_t> shape, const std::string& name) {
  if (!t.defined() || t.sizes() != c10::IntArrayRef(shape)) {
    std::string expected;
    for (int64_t size : shape) expected += (expected.empty() ? "" : ", ") + std::to_string(size);
    throw core::Error(path, "cannot write PLY: " + name + " must be [" + expected + "]");
  }
  int64_t width = 1;
  for (size_t i = 1; i < shape.size(); ++i) width *= shape[i];
  return t.detach().to(torch::kCPU, torch::kFloat32).contiguous().reshape({shape[0], width});
}

// Writes the header, then rows of float32/uint8 fields gathered from
// per-entry blocks, a chunk of entries at a time.
struct Block {
  torch::Tensor data;  // [entries, width] contiguous, float32 or uint8
};

void write_rows(const fs::path& path, const std::string& header, int64_t entries,
                const std::vector<Block>& blocks) {
  int64_t record = 0;
  for (const auto& block : blocks) record += block.data.size(1) * block.data.element_size();
  write_stream_atomically(path, [&](FileSink& out) {
    out.write(header.data(), header.size());
    const int64_t chunk = std::max<int64_t>(1, (int64_t(1) << 22) / std::max<int64_t>(record, 1));
    std::vector<char> buffer(size_t(std::min(chunk, entries) * record));
    for (int64_t first = 0; first < entries; first += chunk) {
      const int64_t n = std::min(chunk, entries - first);
      char* p = buffer.data();
      for (int64_t i = first; i < first + n; ++i)
        for (const auto& block : blocks) {
          const int64_t bytes = block.data.size(1) * block.data.element_size();
          std::memcpy(p, static_cast<const char*>(block.data.data_ptr()) + i * bytes,
                      size_t(bytes));
          p += bytes;
        }
      out.write(buffer.data(), size_t(n * record));
    }
  });
}

}  // namespace

int GaussianPly::sh_degree() const {
  const int64_t K = sh_rest.defined() ? sh_rest.size(2) : 0;
  switch (K) {
    case 0:
      return 0;
    case 3:
      return 1;
    case 8:
      return 2;
    case 15:
      return 3;
  }
  throw core::Error("Gaussian PLY: sh_rest has " + std::to_string(K) +
                    " coefficients per band; expected 0, 3, 8 or 15");
}

namespace {

// The largest scale_* accepted (a natural logarithm): a Gaussian e^20 = 4.9e8
// units wide, 50 times the largest scene (core::kMaxSceneExtent), whose
// covariance stays finite in float32 when projected.
constexpr double kMaxLogScale = 20;

// Values no renderer can use end the read, naming the file and the
// property, instead of failing later inside the rasterizer.
void require_renderable(const fs::path& path, const GaussianPly& ply) {
  if (ply.means.size(0) == 0) return;
  const std::pair<const torch::Tensor*, const char*> all[] = {
      {&ply.means, "x y z"},  {&ply.log_scales, "scale_*"},
      {&ply.quats, "rot_*"},  {&ply.logit_opacities, "opacity"},
      {&ply.sh_dc, "f_dc_*"}, {&ply.sh_rest, "f_rest_*"}};
  for (const auto& [tensor, name] : all) {
    if (tensor->numel() == 0) continue;
    const torch::Tensor rows = tensor->reshape({tensor->size(0), -1});
    const torch::Tensor bad = ~torch::isfinite(rows).all(1);
    if (bad.any().item<bool>())
      throw core::Error(path, std::string(name) + " of Gaussian " +
                                  std::to_string(bad.nonzero()[0][0].item<int64_t>()) +
                                  " is NaN or infinite");
    const torch::Tensor large = (rows.abs() > core::kMaxFileNumber).any(1);
    if (large.any().item<bool>()) {
      const int64_t g = large.nonzero()[0][0].item<int64_t>();
      throw core::Error(path, std::string(name) + " of Gaussian " + std::to_string(g) + " is " +
                                  core::format_g(rows[g].abs().max().item<double>()) +
                                  " (at most " + core::format_g(core::kMaxFileNumber) +
                                  " in magnitude)");
    }
  }
  // scale_* are logarithms: exp(kMaxLogScale) is far beyond any scene.
  const torch::Tensor widest_of_each = std::get<0>(ply.log_scales.max(1));  // [G]
  const double widest = widest_of_each.max().item<double>();
  if (widest > kMaxLogScale)
    throw core::Error(path, "scale_* of Gaussian " +
                                std::to_string(widest_of_each.argmax().item<int64_t>()) + " is " +
                                core::format_g(widest) + ", a width of " +
                                core::format_g(std::exp(widest)) +
                                " units (scale_* are natural "
                                "logarithms; at most " +
                                core::format_g(kMaxLogScale) + ")");
  const double far = ply.means.abs().max().item<double>();
  if (far > core::kMaxSceneExtent)
    throw core::Error(path, "a Gaussian lies " + std::to_string(far) +
                                " units from the origin (x y z; at most 1e7)");
  const torch::Tensor zero = ply.quats.abs().sum(1) == 0;
  if (zero.any().item<bool>())
    throw core::Error(path, "rot_0..3 of Gaussian " +
                                std::to_string(zero.nonzero()[0][0].item<int64_t>()) +
                                " are all 0 (no rotation quaternion)");
}

}  // namespace

GaussianPly read_gaussian_ply(const fs::path& path) {
  OpenPly file;
  open_ply(path, file);
  const Element& vertex = file.element();
  const std::string kind = "an N-band Gaussian PLY needs x y z f_dc_* opacity scale_0..2 rot_0..3";
  auto named = [&](std::initializer_list<const char*> names) {
    std::vector<int> indices;
    for (const char* name : names) indices.push_back(require_property(path, vertex, name, kind));
    return indices;
  };
  const auto xyz = named({"x", "y", "z"});
  const auto opacity = named({"opacity"});
  const auto scales = named({"scale_0", "scale_1", "scale_2"});
  const auto rots = named({"rot_0", "rot_1", "rot_2", "rot_3"});
  const auto dc = numbered_properties(path, vertex, "f_dc_");
  const auto rest = numbered_properties(path, vertex, "f_rest_");
  if (dc.empty()) throw core::Error(path, "missing vertex properties f_dc_0.. (" + kind + ")");
  const int64_t N = int64_t(dc.size()), R = int64_t(rest.size());
  const int64_t K = R / N;
  if (R % N != 0 || (K != 0 && K != 3 && K != 8 && K != 15))
    throw core::Error(path, std::to_string(R) + " f_rest_* properties for " + std::to_string(N) +
                                " bands: expected 0, 3N, 8N or 15N (SH degree 0-3)");

  GaussianPly ply;
  ply.wavelengths_nm = parse_wavelengths(path, file.header);
  if (const torch::Tensor rows = parse_band_basis(path, file.header, N); rows.defined()) {
    ply.mean = rows.select(1, 0).contiguous();
    ply.basis = rows.slice(1, 1).contiguous();
  }
  // sh_dc is not read yet: the band count comes from the basis or f_dc_*.
  const int64_t bands = ply.basis.defined() ? ply.basis.size(0) : N;
  if (!ply.wavelengths_nm.empty() && int64_t(ply.wavelengths_nm.size()) != bands)
    throw core::Error(path,
                      "'comment wavelengths' lists " + std::to_string(ply.wavelengths_nm.size()) +
                          " values but the file has " + std::to_string(bands) +
                          (ply.basis.defined() ? " bands (band_basis lines)" : " bands (f_dc_*)"));
  const int64_t G = vertex.count;
  ply.means = torch::empty({G, 3});
  ply.log_scales = torch::empty({G, 3});
  ply.quats = torch::empty({G, 4});
  ply.logit_opacities = torch::empty({G, 1});
  ply.sh_dc = torch::empty({G, N});
  ply.sh_rest = torch::empty({G, N, K});
  std::vector<Column> columns;
  add_columns(columns, xyz, ply.means);
  add_columns(columns, scales, ply.log_scales);
  add_columns(columns, rots, ply.quats);
  add_columns(columns, opacity, ply.logit_opacities);
  add_columns(columns, dc, ply.sh_dc);
  // Band-major on disk and in memory: f_rest_{b*K+k} is sh_rest[g, b, k].
  if (K > 0) add_columns(columns, rest, ply.sh_rest);
  ply::read_element(file.in, path, file.header, file.vertex, columns);
  require_renderable(path, ply);
  return ply;
}

void write_gaussian_ply(const fs::path& path, const GaussianPly& ply) {
  if (!ply.means.defined() || ply.means.dim() != 2 || !ply.sh_dc.defined() || ply.sh_dc.dim() != 2)
    throw core::Error(path, "cannot write PLY: means must be [G, 3] and sh_dc [G, N]");
  const int64_t G = ply.means.size(0), N = ply.sh_dc.size(1);
  const int64_t K = ply.sh_rest.defined() ? ply.sh_rest.size(-1) : 0;
  if (N < 1) throw core::Error(path, "cannot write PLY: sh_dc has no bands");
  if (K != 0 && K != 3 && K != 8 && K != 15)
    throw core::Error(path, "cannot write PLY: sh_rest must be [G, N, K] with K in {0, 3, 8, 15}");
  if (!ply.wavelengths_nm.empty() && int64_t(ply.wavelengths_nm.size()) != ply.bands())
    throw core::Error(path, "cannot write PLY: " + std::to_string(ply.wavelengths_nm.size()) +
                                " wavelengths for " + std::to_string(ply.bands()) + " bands");
  if (ply.basis.defined() && (ply.basis.dim() != 2 || ply.basis.size(1) != N ||
                              !ply.mean.defined() || ply.mean.numel() != ply.basis.size(0)))
    throw core::Error(path, "cannot write PLY: a band basis must be [N, C] with C = " +
                                std::to_string(N) + " channels, and its mean [N]");
  std::vector<Block> blocks{{as_float_rows(path, ply.means, {G, 3}, "means")},
                            {torch::zeros({G, 3})},  // normals, unused by 3DGS tools
                            {as_float_rows(path, ply.sh_dc, {G, N}, "sh_dc")}};
  if (K > 0) blocks.push_back({as_float_rows(path, ply.sh_rest, {G, N, K}, "sh_rest")});
  const torch::Tensor& opacity = ply.logit_opacities;
  blocks.push_back(
      {as_float_rows(path, opacity.defined() && opacity.dim() == 1 ? opacity.unsqueeze(1) : opacity,
                     {G, 1}, "logit_opacities")});
  blocks.push_back({as_float_rows(path, ply.log_scales, {G, 3}, "log_scales")});
  blocks.push_back({as_float_rows(path, ply.quats, {G, 4}, "quats")});

  std::vector<std::pair<std::string, Type>> properties;
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz"})
    properties.push_back({name, Type::Float32});
  for (int64_t b = 0; b < N; ++b)
    properties.push_back({"f_dc_" + std::to_string(b), Type::Float32});
  for (int64_t i = 0; i < N * K; ++i)
    properties.push_back({"f_rest_" + std::to_string(i), Type::Float32});
  properties.push_back({"opacity", Type::Float32});
  for (const char* name : {"scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    properties.push_back({name, Type::Float32});
  std::vector<std::string> comments;
  if (!ply.wavelengths_nm.empty()) {
    std::string line = kWavelengthsComment;
    for (double w : ply.wavelengths_nm) line += " " + format_number(w);
    comments.push_back(line);
  }
  if (ply.basis.defined()) {
    const auto basis = ply.basis.detach().to(torch::kFloat32).contiguous();
    const auto mean = ply.mean.detach().to(torch::kFloat32).contiguous();
    for (int64_t b = 0; b < basis.size(0); ++b) {
      std::string line = std::string(kBasisComment) + " " + format_number(mean[b].item<float>());
      for (int64_t c = 0; c < N; ++c) line += " " + format_number(basis[b][c].item<float>());
      comments.push_back(line);
    }
  }
  write_rows(path, ply::binary_header(comments, "vertex", G, properties), G, blocks);
}

PointCloud read_point_ply(const fs::path& path) {
  OpenPly file;
  open_ply(path, file);
  const Element& vertex = file.element();
  std::vector<int> xyz;
  for (const char* name : {"x", "y", "z"})
    xyz.push_back(require_property(path, vertex, name, "a point cloud needs x y z"));
  const int64_t P = vertex.count;
  PointCloud points;
  points.xyz = torch::empty({P, 3});
  std::vector<Column> columns;
  add_columns(columns, xyz, points.xyz);
  const int red = vertex.find("red"), green = vertex.find("green"), blue = vertex.find("blue");
  if (red >= 0 && green >= 0 && blue >= 0) {
    points.rgb = torch::empty({P, 3}, torch::kUInt8);
    // As in add_columns: no offset on the null pointer of zero points.
    uint8_t* base = P > 0 ? points.rgb.data_ptr<uint8_t>() : nullptr;
    for (int c : {0, 1, 2})
      columns.push_back({std::array{red, green, blue}[c], nullptr, base ? base + c : nullptr, 3});
  }
  const auto spectra = numbered_properties(path, vertex, "spec_");
  if (!spectra.empty()) {
    points.spectra = torch::empty({P, int64_t(spectra.size())});
    add_columns(columns, spectra, points.spectra);
  }
  ply::read_element(file.in, path, file.header, file.vertex, columns);
  // Float32 splats cannot place a point beyond this (core/camera.h).
  if (P > 0) {
    const double far = points.xyz.abs().max().item<double>();
    if (!(far <= core::kMaxSceneExtent))
      throw core::Error(path, "a point coordinate is " + std::to_string(far) +
                                  " (NaN, infinite or beyond 1e7 scene units)");
    if (points.spectra.defined() && !torch::isfinite(points.spectra).all().item<bool>())
      throw core::Error(path, "a point's spectrum holds NaN or infinite values");
  }
  return points;
}

void write_point_ply(const fs::path& path, const PointCloud& points) {
  if (!points.xyz.defined() || points.xyz.dim() != 2 || points.xyz.size(1) != 3)
    throw core::Error(path, "cannot write PLY: xyz must be [P, 3]");
  const int64_t P = points.xyz.size(0);
  std::vector<Block> blocks{{as_float_rows(path, points.xyz, {P, 3}, "xyz")}};
  std::vector<std::pair<std::string, Type>> properties{
      {"x", Type::Float32}, {"y", Type::Float32}, {"z", Type::Float32}};
  if (points.rgb.defined()) {
    if (points.rgb.dim() != 2 || points.rgb.size(0) != P || points.rgb.size(1) != 3 ||
        points.rgb.scalar_type() != torch::kUInt8)
      throw core::Error(path, "cannot write PLY: rgb must be uint8 [P, 3]");
    blocks.push_back({points.rgb.contiguous()});
    for (const char* name : {"red", "green", "blue"}) properties.push_back({name, Type::UInt8});
  }
  if (points.spectra.defined()) {
    const int64_t N = points.spectra.dim() == 2 ? points.spectra.size(1) : 0;
    blocks.push_back(
        {as_float_rows(path, points.spectra, {P, std::max<int64_t>(N, 1)}, "spectra")});
    for (int64_t b = 0; b < N; ++b)
      properties.push_back({"spec_" + std::to_string(b), Type::Float32});
  }
  write_rows(path, ply::binary_header({}, "vertex", P, properties), P, blocks);
}

}  // namespace ddhgs::io
