#include "io/files/output_folder.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"
#include "io/files/output_marker.h"
#include "io/files/stale_files.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Absolute, without "." / ".." and without a trailing separator, so that
// filename() and parent_path() name the folder itself.
fs::path absolute_folder(const fs::path& folder) {
  fs::path p = fs::absolute(folder).lexically_normal();
  if (p.filename().empty() && p != p.root_path()) p = p.parent_path();
  return p;
}

// Symbolic links resolved where the path exists, so that two spellings of
// one folder compare equal.
fs::path resolved(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(absolute_folder(path), ec);
  return ec ? absolute_folder(path) : absolute_folder(p);
}

// True when `outer` is `inner` or one of its ancestors.
bool contains(const fs::path& outer, const fs::path& inner) {
  auto o = outer.begin(), i = inner.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *o != *i) return false;
  }
  return true;
}

bool default_is_mount_point(const fs::path& path) {
  struct stat self {
  }, parent{};
  if (::stat(path.c_str(), &self) != 0) return false;  // absent: not a mount point
  if (::stat((path / "..").c_str(), &parent) != 0) return true;
  // A root is its own parent; a mount point sits on another device than its parent.
  return self.st_dev != parent.st_dev || self.st_ino == parent.st_ino;
}

std::optional<fs::path> home_folder(const PathContext& context) {
  if (context.home) return context.home;
  const char* home = std::getenv("HOME");
  if (home && *home) return fs::path(home);
  return std::nullopt;
}

std::string refusal(const fs::path& folder, const std::string& why) {
  return folder.string() + ": " + why + "; nothing was touched";
}

// Replacing an output deletes it: refused while it holds anything ddhgs did
// not write (a user's notes, a dataset, a preset), or when it cannot tell.
void refuse_foreign_entries(const fs::path& folder, const OutputMarker& marker) {
  if (!marker.listed)
    throw core::Error(refusal(folder,
                              "was written by an older ddhgs that kept no list of its files, so "
                              "they cannot be told from yours; delete it yourself or give another "
                              "folder"));
  const std::vector<std::string> foreign = foreign_entries(folder, marker);
  if (foreign.empty()) return;
  throw core::Error(refusal(folder, "holds files ddhgs did not write (" +
                                        core::format_names(foreign) +
                                        "); move them out first, or give another folder"));
}

}  // namespace

std::string to_string(OutputKind kind) {
  switch (kind) {
    case OutputKind::Scene:
      return "scene";
    case OutputKind::Run:
      return "run";
    case OutputKind::Report:
      return "report";
    case OutputKind::Renders:
      return "renders";
    case OutputKind::Eval:
      return "eval";
    case OutputKind::Ablation:
      return "ablation";
    case OutputKind::Blocks:
      return "blocks";
  }
  return "output";
}

std::string protected_reason(const fs::path& folder, const std::vector<fs::path>& inputs,
                             const PathContext& context) {
  const fs::path target = resolved(folder);
  if (target == target.root_path()) return "is a filesystem root";
  const auto is_mount_point =
      context.is_mount_point ? context.is_mount_point : default_is_mount_point;
  if (is_mount_point(target)) return "is a mount point";
  std::error_code ec;
  const fs::path cwd = resolved(context.cwd.empty() ? fs::current_path(ec) : context.cwd);
  if (contains(target, cwd))
    return target == cwd ? "is the current directory" : "contains the current directory";
  if (auto home = home_folder(context)) {
    const fs::path h = resolved(*home);
    if (contains(target, h))
      return target == h ? "is your home folder" : "contains your home folder";
  }
  for (const auto& input : inputs) {
    if (input.empty()) continue;
    const fs::path in = resolved(input);
    if (contains(target, in))
      return target == in ? "is one of this command's inputs"
                          : "contains this command's input " + in.string();
  }
  return "";
}

std::optional<OutputKind> output_kind(const fs::path& folder) {
  const auto marker = read_output_marker(folder);
  if (!marker) return std::nullopt;
  return marker->kind;
}

void mark_output_folder(const fs::path& folder, OutputKind kind) {
  write_output_marker(folder, {kind, false, true, folder_entries(folder)});
}

OutputState check_output_folder(const OutputRequest& request, const PathContext& context) {
  const fs::path folder = absolute_folder(request.folder);
  const std::string kind = to_string(request.kind);
  std::error_code ec;
  const fs::file_status link = fs::symlink_status(folder, ec);
  const bool exists = fs::exists(link);
  if (exists && fs::is_symlink(link))
    throw core::Error(refusal(folder, "is a symbolic link; give the folder it points to"));
  if (exists && !fs::is_directory(link))
    throw core::Error(refusal(folder, "exists and is not a folder"));
  const std::string reason = protected_reason(folder, request.inputs, context);
  if (!reason.empty()) throw core::Error(refusal(folder, reason));
  if (!exists) return OutputState::Absent;
  if (fs::is_empty(folder, ec) && !ec) return OutputState::Empty;
  const std::optional<OutputMarker> marker = read_output_marker(folder);
  const std::optional<OutputKind> found =
      marker ? std::optional<OutputKind>(marker->kind) : std::nullopt;
  if (!found)
    throw core::Error(refusal(folder, "holds files ddhgs did not write (no " +
                                          std::string(kOutputMarker) +
                                          " marker); give a new or empty folder"));
  if (*found != request.kind)
    throw core::Error(refusal(
        folder, "is a ddhgs " + to_string(*found) + ", not a " + kind + "; give another folder"));
  if (!request.replace)
    throw core::Error(folder, "a ddhgs " + kind + " already exists here" +
                                  (request.replace_flag.empty()
                                       ? std::string()
                                       : "; pass " + request.replace_flag + " to replace it"));
  if (!request.merge) refuse_foreign_entries(folder, *marker);
  return OutputState::Ours;
}

namespace {

// The temporary sibling an output is built in, marked, filled by build; on
// failure it is removed and the error passed on.
fs::path build_apart(const fs::path& folder, OutputKind kind,
                     const std::function<void(const fs::path& tmp)>& build) {
  const fs::path parent = folder.parent_path();
  std::error_code ec;
  const CreatedFolders created = create_folders(parent, ec);
  if (ec) throw core::Error(parent, "cannot create the folder (" + ec.message() + ")");
  remove_stale_temporaries_once(parent);
  const fs::path tmp =
      parent / ("." + folder.filename().string() + ".tmp-" + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  try {
    fs::create_directory(tmp);
    mark_output_folder(tmp, kind);
    build(tmp);
    mark_output_folder(tmp, kind);  // everything in it is ddhgs's
  } catch (...) {
    std::error_code ignored;  // the original error matters, not this one
    fs::remove_all(tmp, ignored);
    created.remove_if_empty();  // no empty RUN/renders/ left by a failed render
    throw;
  }
  return tmp;
}

// Removes the names of `superseded` that ddhgs wrote into folder (its
// marker lists them) and that the new files did not replace, and drops them
// from the marker.
void remove_superseded(const fs::path& folder, const std::vector<std::string>& superseded,
                       const std::vector<std::string>& added, OutputMarker& marker) {
  const auto has = [](const std::vector<std::string>& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  bool changed = false;
  for (const std::string& name : superseded) {
    if (has(added, name) || !has(marker.entries, name)) continue;
    std::error_code ec;
    const fs::path path = folder / name;
    if (!fs::is_regular_file(fs::symlink_status(path, ec)) || !fs::remove(path, ec)) continue;
    marker.entries.erase(std::remove(marker.entries.begin(), marker.entries.end(), name),
                         marker.entries.end());
    changed = true;
  }
  if (changed) write_output_marker(folder, marker);
}

}  // namespace

fs::path write_folder_atomically(const OutputRequest& request,
                                 const std::function<void(const fs::path& tmp)>& build) {
  const OutputState state = check_output_folder(request);
  const fs::path folder = absolute_folder(request.folder);
  const fs::path tmp = build_apart(folder, request.kind, build);
  const fs::path old = folder.parent_path() /
                       ("." + folder.filename().string() + ".old-" + std::to_string(::getpid()));
  std::error_code ec;
  if (state == OutputState::Ours) {
    fs::rename(folder, old, ec);
    if (ec) {
      fs::remove_all(tmp, ec);
      throw core::Error(folder, "cannot move the earlier " + to_string(request.kind) + " aside (" +
                                    ec.message() + ")");
    }
  } else if (state == OutputState::Empty) {
    fs::remove(folder, ec);  // an empty folder only: remove() refuses anything else
  }
  fs::rename(tmp, folder, ec);
  if (ec) {
    const std::string why = ec.message();
    std::error_code ignored;
    if (state == OutputState::Ours) fs::rename(old, folder, ignored);
    fs::remove_all(tmp, ignored);
    throw core::Error(folder,
                      "cannot put the new " + to_string(request.kind) + " in place (" + why + ")");
  }
  if (state == OutputState::Ours) fs::remove_all(old, ec);
  return folder;
}

fs::path write_into_folder_atomically(const OutputRequest& request,
                                      const std::function<void(const fs::path& tmp)>& build) {
  OutputRequest merge = request;
  merge.replace = true;  // adds to an earlier output of its kind, never to anything else
  merge.merge = true;
  const OutputState state = check_output_folder(merge);
  const fs::path folder = absolute_folder(request.folder);
  if (state != OutputState::Ours) {
    merge.merge = false;
    return write_folder_atomically(merge, build);
  }
  const fs::path tmp = build_apart(folder, request.kind, build);
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(tmp)) {
    if (entry.path().filename() == kOutputMarker) continue;
    const fs::path target = folder / entry.path().filename();
    // A folder in the way of a file (or the reverse) would be destroyed by rename.
    if (fs::exists(fs::symlink_status(target, ec)) &&
        fs::is_directory(fs::symlink_status(target, ec)) != entry.is_directory(ec)) {
      fs::remove_all(tmp, ec);
      throw core::Error(target, "is in the way of a new file of the same name; nothing was added");
    }
  }
  OutputMarker marker = *read_output_marker(folder);
  const std::vector<std::string> added = folder_entries(tmp);
  for (const std::string& name : added) marker.entries.push_back(name);
  write_output_marker(folder, marker);
  for (const auto& entry : fs::directory_iterator(tmp)) {
    if (entry.path().filename() == kOutputMarker) continue;
    fs::rename(entry.path(), folder / entry.path().filename(), ec);
    if (ec) {
      const std::string why = ec.message();
      fs::remove_all(tmp, ec);
      throw core::Error(folder / entry.path().filename(), "cannot put it in place (" + why + ")");
    }
  }
  fs::remove_all(tmp, ec);
  remove_superseded(folder, request.superseded, added, marker);
  return folder;
}

fs::path FolderReplacement::aside() const {
  const fs::path folder = absolute_folder(request_.folder);
  return folder.parent_path() / (folder.filename().string() + ".previous");
}

void FolderReplacement::begin(const PathContext& context) {
  const OutputState state = check_output_folder(request_, context);
  folder_ = absolute_folder(request_.folder);
  std::error_code ec;
  if (state == OutputState::Ours) {
    const fs::path previous = aside();
    if (fs::exists(fs::symlink_status(previous, ec)))
      throw core::Error(refusal(folder_, "an earlier replacement did not finish and " +
                                             previous.string() +
                                             " may hold the only good copy; move or delete it "
                                             "first"));
    fs::rename(folder_, previous, ec);
    if (ec)
      throw core::Error(folder_, "cannot move the earlier " + to_string(request_.kind) +
                                     " aside (" + ec.message() + ")");
    replacing_ = true;
  }
  bool created = false;
  try {
    created = fs::create_directories(folder_);
    write_output_marker(folder_, {request_.kind, replacing_, true, request_.entries});
  } catch (const std::exception& e) {
    const auto* fs_error = dynamic_cast<const fs::filesystem_error*>(&e);
    const std::string why = fs_error ? fs_error->code().message() : core::message_of(e);
    // Made here, but its marker did not fit (a full disk): still empty, so
    // remove(), which never deletes contents, takes it away.
    if (created) fs::remove(folder_, ec);
    rollback();
    throw core::Error(folder_, "cannot create the folder (" + why + ")");
  }
}

bool FolderReplacement::restore_interrupted() {
  folder_ = absolute_folder(request_.folder);
  const auto marker = read_output_marker(folder_);
  if (!marker || marker->kind != request_.kind || !marker->pending ||
      output_kind(aside()) != request_.kind)
    return false;
  refuse_foreign_entries(folder_, *marker);  // nothing of the user's goes with it
  std::error_code ec;
  fs::remove_all(folder_, ec);
  if (!ec) fs::rename(aside(), folder_, ec);
  if (ec)
    throw core::Error(aside(), "cannot bring the earlier " + to_string(request_.kind) +
                                   " back to " + folder_.string() + " (" + ec.message() +
                                   "); move it there yourself");
  return true;
}

void FolderReplacement::resume() {
  folder_ = absolute_folder(request_.folder);
  const auto marker = read_output_marker(folder_);
  replacing_ = marker && marker->kind == request_.kind && marker->pending &&
               output_kind(aside()) == request_.kind;
}

void FolderReplacement::commit() {
  if (!replacing_) return;
  std::error_code ec;
  if (output_kind(aside()) == request_.kind) fs::remove_all(aside(), ec);
  if (auto marker = read_output_marker(folder_)) {
    marker->pending = false;
    write_output_marker(folder_, *marker);
  }
  replacing_ = false;
}

void FolderReplacement::rollback() {
  std::error_code ec;
  if (!folder_.empty() && output_kind(folder_) == request_.kind) fs::remove_all(folder_, ec);
  if (replacing_) fs::rename(aside(), folder_, ec);
  replacing_ = false;
}

}  // namespace ddhgs::io
