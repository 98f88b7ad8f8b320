// PyTorch .pt files written by torch.save holding one tensor.
#include <torch/csrc/jit/serialization/pickle.h>

#include "core/error.h"
#include "io/cube/cube_formats.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

// First line of a LibTorch error: the rest is a C++ stack trace.
std::string first_line(const char* what) {
  std::string text(what);
  return text.substr(0, text.find('\n'));
}

}  // namespace

Cube read_pt(const fs::path& path, const CubeReadOptions& options) {
  std::string bytes = read_file(path);
  if (bytes.empty()) throw core::Error(path, "empty file, expected a torch.save tensor");
  // torch.save writes a zip archive since PyTorch 1.6 ("PK" magic).
  if (bytes.size() < 4 || bytes.compare(0, 2, "PK") != 0)
    throw core::Error(path, "not a torch.save zip file (bad magic; save with PyTorch >= 1.6)");
  torch::IValue value;
  try {
    value = torch::pickle_load(std::vector<char>(bytes.begin(), bytes.end()));
  } catch (const c10::Error& e) {
    throw core::Error(path,
                      "not a readable torch.save file holding one tensor: " + first_line(e.what()));
  } catch (const std::exception& e) {
    throw core::Error(path,
                      "not a readable torch.save file holding one tensor: " + first_line(e.what()));
  }
  if (!value.isTensor())
    throw core::Error(path, "holds a " + value.tagKind() + ", expected a single tensor");
  torch::Tensor data = value.toTensor();
  Cube cube;
  cube.type = sample_type_of(data.scalar_type(), path);
  cube.data = to_bands_last(data, options.layout, path);
  require_finite(cube.data, path);
  return cube;
}

}  // namespace ddhgs::io::detail
