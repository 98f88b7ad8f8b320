#include "io/files/output_marker.h"

#include <algorithm>
#include <cstring>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

constexpr OutputKind kKinds[] = {OutputKind::Scene,   OutputKind::Run,  OutputKind::Report,
                                 OutputKind::Renders, OutputKind::Eval, OutputKind::Ablation,
                                 OutputKind::Blocks};
constexpr const char* kPendingLine = "replacing";
constexpr const char* kManifestLine = "manifest";
constexpr const char* kEntryPrefix = "wrote ";

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    lines.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return lines;
}

void collect_foreign(const fs::path& folder, const OutputMarker& marker, const std::string& prefix,
                     std::vector<std::string>& out) {
  for (const std::string& name : folder_entries(folder)) {
    if (std::find(marker.entries.begin(), marker.entries.end(), name) != marker.entries.end())
      continue;
    std::error_code ec;
    const fs::path path = folder / name;
    const auto nested =
        fs::is_directory(fs::symlink_status(path, ec)) ? read_output_marker(path) : std::nullopt;
    if (nested && nested->listed)
      collect_foreign(path, *nested, prefix + name + "/", out);
    else
      out.push_back(prefix + name + (nested ? "/" : ""));
  }
}

}  // namespace

std::optional<OutputMarker> read_output_marker(const fs::path& folder) {
  std::error_code ec;
  const fs::path path = folder / kOutputMarker;
  const fs::file_status status = fs::symlink_status(path, ec);
  if (!fs::is_regular_file(status) || fs::file_size(path, ec) > (1 << 20)) return std::nullopt;
  std::string text;
  try {
    text = read_file(path);
  } catch (const core::Error&) {
    return std::nullopt;
  }
  const std::vector<std::string> lines = lines_of(text);
  if (lines.empty()) return std::nullopt;
  std::optional<OutputMarker> marker;
  for (OutputKind kind : kKinds)
    if (lines.front() == "ddhgs " + to_string(kind)) marker = OutputMarker{kind, false, false, {}};
  if (!marker) return std::nullopt;
  for (size_t i = 1; i < lines.size(); ++i) {
    if (lines[i] == kPendingLine) marker->pending = true;
    if (lines[i] == kManifestLine) marker->listed = true;
    if (lines[i].rfind(kEntryPrefix, 0) == 0)
      marker->entries.push_back(lines[i].substr(std::strlen(kEntryPrefix)));
  }
  return marker;
}

void write_output_marker(const fs::path& folder, const OutputMarker& marker) {
  std::string text = "ddhgs " + to_string(marker.kind) + "\n";
  if (marker.pending) text += std::string(kPendingLine) + "\n";
  text += std::string(kManifestLine) + "\n";
  std::vector<std::string> entries = marker.entries;
  std::sort(entries.begin(), entries.end());
  entries.erase(std::unique(entries.begin(), entries.end()), entries.end());
  for (const std::string& name : entries) text += kEntryPrefix + name + "\n";
  write_file_atomically(folder / kOutputMarker, text);
}

std::vector<std::string> folder_entries(const fs::path& folder) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (name != kOutputMarker && name != kLockFile) names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::vector<std::string> foreign_entries(const fs::path& folder, const OutputMarker& marker) {
  std::vector<std::string> out;
  collect_foreign(folder, marker, "", out);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace ddhgs::io
