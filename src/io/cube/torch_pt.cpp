// PyTorch .pt files written by torch.save holding one tensor.
#include <caffe2/serialize/inline_container.h>
#include <torch/csrc/jit/serialization/unpickler.h>

#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <tuple>

#include "core/error.h"
#include "io/cube/cube_formats.h"
#include "io/cube/pickle_check.h"
#include "io/cube/zip_check.h"
#include "io/files/byte_count.h"
#include "io/files/input_file.h"

namespace ddhgs::io::detail {
namespace fs = std::filesystem;

namespace {

// First line of a LibTorch error: the rest is a C++ stack trace.
std::string first_line(const char* what) {
  std::string text(what);
  return text.substr(0, text.find('\n'));
}

void require_zip_magic(const fs::path& path) {
  std::error_code ec;
  require_regular_file(path);
  if (fs::file_size(path, ec) == 0)
    throw core::Error(path, "empty file, expected a torch.save tensor");
  char magic[2] = {};
  std::ifstream in(path, std::ios::binary);
  in.read(magic, 2);
  // torch.save writes a zip archive since PyTorch 1.6 ("PK" magic).
  if (in.gcount() < 2 || std::memcmp(magic, "PK", 2) != 0)
    throw core::Error(path, "not a torch.save zip file (bad magic; save with PyTorch >= 1.6)");
}

// The pickle stores each storage's element count, LibTorch trusts it, and the
// data record may be shorter: the stored size of every record read is kept,
// by the address LibTorch's storage will point at, for the caller to check.
using RecordBytes = std::map<const void*, size_t>;

torch::IValue unpickle(caffe2::serialize::PyTorchStreamReader& reader, RecordBytes* stored,
                       const fs::path& path) {
  std::tuple<at::DataPtr, size_t> record = reader.getRecord("data.pkl");
  const char* pickle = static_cast<const char*>(std::get<0>(record).get());
  const size_t size = std::get<1>(record);
  check_pickle(pickle, size, path);
  size_t pos = 0;
  auto read = [&](char* buffer, size_t n) {
    n = std::min(n, size - pos);
    if (n > 0) std::memcpy(buffer, pickle + pos, n);  // an empty data.pkl has no pointer
    pos += n;
    return n;
  };
  auto read_record = [&](const std::string& key) {
    auto [data, bytes] = reader.getRecord("data/" + key);
    (*stored)[data.get()] = bytes;
    return std::move(data);
  };
  torch::jit::Unpickler unpickler(read, nullptr, nullptr, read_record, c10::nullopt);
  unpickler.set_version(reader.version());
  return unpickler.parse_ivalue();
}

// Bytes from the storage start to the end of the last element the tensor
// views; nullopt when a stride is negative or the sum overflows.
std::optional<uint64_t> viewed_bytes(const torch::Tensor& t) {
  if (t.numel() == 0) return 0;
  uint64_t last = uint64_t(t.storage_offset());
  for (int64_t d = 0; d < t.dim(); ++d) {
    if (t.stride(d) < 0) return std::nullopt;
    std::optional<uint64_t> step =
        checked_product({uint64_t(t.size(d) - 1), uint64_t(t.stride(d))});
    if (!step || __builtin_add_overflow(last, *step, &last)) return std::nullopt;
  }
  return checked_product({last + 1, uint64_t(t.element_size())});
}

std::string shape_text(const torch::Tensor& t) {
  std::string text;
  for (int64_t size : t.sizes()) text += (text.empty() ? "" : " x ") + std::to_string(size);
  return "[" + text + "]";
}

void require_stored(const torch::Tensor& t, const RecordBytes& stored, const fs::path& path) {
  const void* data = t.storage().data_ptr().get();
  auto it = stored.find(data);
  const uint64_t present = it == stored.end() ? 0 : it->second;
  std::optional<uint64_t> needed = viewed_bytes(t);
  if (!needed)
    throw core::Error(path, "tensor " + shape_text(t) + " has invalid strides or offset");
  if (*needed > present)
    throw core::Error(path, "truncated: the tensor " + shape_text(t) + " needs " +
                                std::to_string(*needed) + " bytes, the file stores " +
                                std::to_string(present));
}

}  // namespace

Cube read_pt(const fs::path& path, const CubeReadOptions& options) {
  require_zip_magic(path);
  torch::Tensor data;
  try {
    // Before the reader: its constructor already extracts the version record.
    check_zip_record_sizes(path);
    caffe2::serialize::PyTorchStreamReader reader(path.string());
    RecordBytes stored;
    torch::IValue value = unpickle(reader, &stored, path);
    if (!value.isTensor())
      throw core::Error(path, "holds a " + value.tagKind() + ", expected a single tensor");
    data = value.toTensor();
    require_stored(data, stored, path);
  } catch (const c10::Error& e) {
    throw core::Error(path, "not a readable torch.save file holding one tensor: " +
                                first_line(e.what_without_backtrace()));
  } catch (const core::Error&) {
    throw;
  } catch (const std::exception& e) {
    throw core::Error(path,
                      "not a readable torch.save file holding one tensor: " + first_line(e.what()));
  }
  Cube cube;
  cube.type = sample_type_of(data.scalar_type(), path);
  cube.data = to_bands_last(data, options.layout, path);
  require_finite(cube.data, path);
  return cube;
}

}  // namespace ddhgs::io::detail
