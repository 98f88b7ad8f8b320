#include "io/files/input_file.h"

#include "core/error.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

void require_regular_file(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);  // follows symbolic links
  switch (status.type()) {
    case fs::file_type::regular:
      return;
    case fs::file_type::not_found:
      throw core::Error(path, "file not found");
    case fs::file_type::directory:
      throw core::Error(path, "is a folder, expected a file");
    case fs::file_type::fifo:
      throw core::Error(path, "is a FIFO (named pipe), expected a regular file");
    case fs::file_type::socket:
      throw core::Error(path, "is a socket, expected a regular file");
    case fs::file_type::block:
    case fs::file_type::character:
      throw core::Error(path, "is a device, expected a regular file");
    default:
      throw core::Error(path,
                        ec ? "cannot be read (" + ec.message() + ")" : "is not a regular file");
  }
}

}  // namespace ddhgs::io
