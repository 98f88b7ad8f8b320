#include "io/files/output_file.h"

#include <cctype>

#include "core/error.h"
#include "core/text.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

using core::lower;

}  // namespace

void require_extension(const fs::path& path, const std::string& flag,
                       std::initializer_list<const char*> extensions) {
  const std::string ext = lower(path.extension().string());
  std::string list;
  for (const char* e : extensions) {
    if (ext == e) return;
    list += (list.empty() ? "" : " or ") + std::string(e);
  }
  throw core::Error(flag + " " + path.string() + ": expected a file name ending in " + list);
}

bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
  const fs::path ca = fs::weakly_canonical(fs::absolute(a, ec), ec);
  const fs::path cb = fs::weakly_canonical(fs::absolute(b, ec), ec);
  return ca.lexically_normal() == cb.lexically_normal();
}

void require_distinct(const fs::path& path, const std::string& flag,
                      const std::vector<std::pair<std::string, fs::path>>& others) {
  for (const auto& [what, other] : others)
    if (!other.empty() && same_file(path, other))
      throw core::Error(flag + " " + path.string() + ": is " + what +
                        "; refusing to overwrite it (choose another file name)");
}

}  // namespace ddhgs::io
