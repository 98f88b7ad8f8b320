// Output folders: what ddhgs may create, replace or delete, and how.
//
// Every folder ddhgs writes (a scene, a run, a report, renders, evaluation
// results, an ablation) carries a marker file naming its kind and listing
// what ddhgs wrote there (io/files/output_marker.h). An existing folder is
// only ever replaced when it carries the marker of the same kind and holds
// nothing else (a user's notes, a dataset, a preset: the command refuses,
// naming them),
// and never when it is, or contains, a filesystem root, a mount point, the
// current directory, the user's home or one of the command's inputs: a
// mistyped --out must not delete anything ddhgs did not write. A replaced
// output is kept until the new one is complete and comes back if it fails.
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::io {

enum class OutputKind { Scene, Run, Report, Renders, Eval, Ablation, Blocks };

// "scene", "run", ...: the word in the marker and in messages.
std::string to_string(OutputKind kind);

// The marker's file name inside an output folder.
constexpr const char* kOutputMarker = ".ddhgs-output";

struct OutputRequest {
  std::filesystem::path folder;
  OutputKind kind = OutputKind::Run;
  // Replace an earlier output of the same kind (--force); report, render
  // and eval replace their own earlier output without it.
  bool replace = false;
  // The command's inputs: the output may neither be nor contain one of them.
  std::vector<std::filesystem::path> inputs;
  // The flag to name when refusing to replace ("--force"); empty when the
  // command has no such flag.
  std::string replace_flag = "--force";
  // Adding files to an earlier output (write_into_folder_atomically), not
  // replacing it: what else it holds stays, so it is no reason to refuse.
  bool merge = false;
  // For an output written in place (FolderReplacement): the top-level names
  // it writes, recorded in its marker as ddhgs's. Outputs built apart list
  // what their build wrote.
  std::vector<std::string> entries = {};
  // For write_into_folder_atomically: names in the folder that the new files
  // make stale (a frame's cube in another format), removed with the new
  // files' arrival when ddhgs wrote them.
  std::vector<std::string> superseded = {};
};

enum class OutputState {
  Absent,  // nothing there yet
  Empty,   // an empty folder
  Ours,    // an earlier output of the requested kind, to be replaced
};

// What the process sees as its surroundings; the defaults read the real
// ones. Tests substitute their own, so that no test needs to point at a real
// root, mount point or home folder.
struct PathContext {
  std::filesystem::path cwd;                  // empty: the current directory
  std::optional<std::filesystem::path> home;  // unset: $HOME
  // True when path is a mount point (or a filesystem root). Null: compare
  // device numbers with the parent folder.
  std::function<bool(const std::filesystem::path&)> is_mount_point;
};

// Why folder must never be created into, replaced or deleted, or "" when it
// may: it is a filesystem root or a mount point, or it is (or contains) the
// current directory, the home folder or one of the inputs.
std::string protected_reason(const std::filesystem::path& folder,
                             const std::vector<std::filesystem::path>& inputs,
                             const PathContext& context = {});

// The kind named by folder's marker; nullopt when it has none (or an unreadable one).
std::optional<OutputKind> output_kind(const std::filesystem::path& folder);

// Checks that the request may proceed and says what is there; throws
// core::Error with one line naming the folder and why it was not touched.
OutputState check_output_folder(const OutputRequest& request, const PathContext& context = {});

// Writes the marker of kind into folder (which must exist), listing what the
// folder holds now as ddhgs's.
void mark_output_folder(const std::filesystem::path& folder, OutputKind kind);

// Builds an output folder under a temporary sibling name (build(tmp) fills
// it; the marker is already there), then puts it in place: an earlier output
// is moved aside, the new one renamed in, the earlier one deleted. If build
// throws, the temporary folder is removed and the earlier output untouched.
// Returns the folder's normalised absolute path.
std::filesystem::path write_folder_atomically(
    const OutputRequest& request,
    const std::function<void(const std::filesystem::path& tmp)>& build);

// Like write_folder_atomically, but adds the files build(tmp) writes to the
// folder instead of replacing it (an earlier output's other files stay): the
// files are built apart and then renamed in, replacing files of the same
// name, so a failed build adds nothing; then request.superseded go. For
// outputs several commands write into (renders of several band selections,
// evaluations of several splits).
std::filesystem::path write_into_folder_atomically(
    const OutputRequest& request,
    const std::function<void(const std::filesystem::path& tmp)>& build);

// For an output written in place over a long time (a training run): begin()
// moves an earlier output aside (to aside()), creates the folder and marks
// it, noting in the marker that a replacement is pending; commit() deletes
// what was moved aside; rollback() removes the new folder and brings the
// earlier one back. An interrupted output that is continued later (train
// --resume) picks the pending replacement up again with resume().
class FolderReplacement {
 public:
  explicit FolderReplacement(OutputRequest request) : request_(std::move(request)) {}
  // Checks (check_output_folder) and prepares the folder. Refuses when
  // aside() already exists: an earlier replacement never finished, and what
  // it kept aside may be the only copy of a good output.
  void begin(const PathContext& context = {});
  // For an existing output of the requested kind: a replacement is pending
  // when its marker says so and aside() is still there.
  void resume();
  // A replacement killed before the new output held anything worth keeping
  // (the caller knows what is: a run's first checkpoint) left the folder
  // marked pending and the earlier output in aside(): removes the folder
  // (refused if it holds anything ddhgs did not write) and brings aside()
  // back. Returns whether it did; false when there is nothing to restore.
  bool restore_interrupted();
  void commit();
  void rollback();
  // Where an earlier output waits while the new one is written: FOLDER.previous.
  std::filesystem::path aside() const;
  const std::filesystem::path& folder() const { return folder_; }
  bool replacing() const { return replacing_; }

 private:
  OutputRequest request_;
  std::filesystem::path folder_;
  bool replacing_ = false;
};

}  // namespace ddhgs::io
