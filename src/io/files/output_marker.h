// The marker file of a ddhgs output (FOLDER/.ddhgs-output) and the list of
// what ddhgs wrote there, which decides what --force may replace.
//
//   ddhgs run            the output's kind
//   replacing            while an earlier output waits beside (FolderReplacement)
//   manifest             the list follows (markers before it had none)
//   wrote config.json    one line per top-level entry ddhgs wrote
//
// Names only, not sizes: a run appends to metrics.jsonl and rewrites its
// checkpoint, so a size recorded once would soon be wrong.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::io {

enum class OutputKind;

struct OutputMarker {
  OutputKind kind;
  bool pending = false;  // "replacing"
  bool listed = false;   // has a manifest (written by this version or later)
  std::vector<std::string> entries;
};

// nullopt when the folder has no marker, a marker that is not a regular file
// (a link to another folder's marker counts as none), or an unreadable one.
std::optional<OutputMarker> read_output_marker(const std::filesystem::path& folder);
void write_output_marker(const std::filesystem::path& folder, const OutputMarker& marker);

// The top-level names in folder, less the marker and the lock.
std::vector<std::string> folder_entries(const std::filesystem::path& folder);

// What in folder ddhgs did not write, as paths relative to it: entries its
// manifest does not list, except nested ddhgs outputs (a run's report/,
// eval/), which are searched in turn. A nested output without a manifest
// counts as foreign. Sorted.
std::vector<std::string> foreign_entries(const std::filesystem::path& folder,
                                         const OutputMarker& marker);

}  // namespace ddhgs::io
