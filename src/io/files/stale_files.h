// Temporaries left by a ddhgs process that died (kill -9, power loss) in the
// middle of an atomic write: ".NAME.tmp-PID-N" files, ".NAME.tmp-PID" and
// ".NAME.old-PID" folders. The next write into the same folder removes those
// it can prove are ddhgs's, once the process that made them is gone; a name
// alone proves nothing (a user's ".notes.tmp-999999-1" stays).
#pragma once
#include <filesystem>
#include <optional>
#include <string>

namespace ddhgs::io {

// A name of one of ddhgs's temporaries, taken apart.
struct TemporaryName {
  long owner = 0;        // process id of the writer
  bool is_file = false;  // ".NAME.tmp-PID-N" (a file); else a folder's name
};
// nullopt when file_name is not one of ddhgs's temporaries.
std::optional<TemporaryName> parse_temporary_name(const std::string& file_name);

// Removes the temporaries in folder (not below it) whose owner is no longer
// running, where ddhgs can tell they are its own: a temporary folder only
// when it is empty or holds nothing but an output marker, a temporary file
// only inside a folder that is itself a ddhgs output (io/files/output_folder.h).
// Anything else named like a temporary may be a user's file: it is left, and
// named in a warning. Errors are ignored: this is tidying.
void remove_stale_temporaries(const std::filesystem::path& folder);
// The same, at most once per folder and process (for every atomic write).
void remove_stale_temporaries_once(const std::filesystem::path& folder);

}  // namespace ddhgs::io
