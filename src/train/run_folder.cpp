#include "train/run_folder.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <mutex>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"
#include "train/config.h"

namespace ddhgs::train {

namespace fs = std::filesystem;

fs::path RunPaths::checkpoint_at(int64_t iteration) const {
  return root / "checkpoints" / ("ckpt_" + std::to_string(iteration) + ".pt");
}

std::vector<std::string> run_entry_names() {
  // export/: `ddhgs export`'s default output. Nested outputs (eval/,
  // report/, renders/) carry markers of their own and are checked as such.
  return {"config.json",   "gaussians.ply",      "checkpoint.pt",        "checkpoints",
          "metrics.jsonl", "train_summary.json", "background.json",      "denoiser.pt",
          "export",        "pseudo_views.pt",    "rig_corrections.json", "georef.json"};
}

RunWriter::RunWriter(const RunPaths& run, io::OutputRequest request)
    : run_(run), replacement_(std::move(request)) {}

std::unique_ptr<RunWriter> RunWriter::create(const RunPaths& run, const nlohmann::json& config,
                                             bool replace, const std::vector<fs::path>& inputs) {
  // A run being written by another process must not be moved away under it.
  io::FolderLock earlier;
  if (io::output_kind(run.root) == io::OutputKind::Run) earlier = io::FolderLock(run.root, "train");
  // `train --force` killed before its first checkpoint left RUN.previous
  // (the earlier run) and an unstarted RUN: the earlier run comes back.
  if (is_unstarted_run(run) &&
      io::FolderReplacement({run.root, io::OutputKind::Run, true, {}}).restore_interrupted()) {
    earlier.release();
    earlier = io::FolderLock(run.root, "train");
    core::log_warn(run.root.string() + ": an earlier `train --force` stopped before its first " +
                   "checkpoint; the run it was replacing is back from " + run.root.string() +
                   ".previous");
  }
  const bool unstarted = is_unstarted_run(run);
  if (unstarted)
    core::log_info(run.root.string() +
                   " holds a run that stopped before its first checkpoint; "
                   "replacing it");
  io::OutputRequest request{run.root, io::OutputKind::Run, replace || unstarted, inputs};
  request.entries = run_entry_names();
  std::unique_ptr<RunWriter> writer(new RunWriter(run, std::move(request)));
  writer->replacement_.begin();
  try {
    writer->lock_ = io::FolderLock(run.root, "train");
    earlier.release();
    fs::create_directories(run.root / "checkpoints");
    io::write_file_atomically(run.config(), config.dump(2) + "\n");
  } catch (const std::exception& e) {
    const std::string why = core::message_of(e);
    writer->replacement_.rollback();
    throw core::Error(run.root, "cannot create the run folder (" + why + ")");
  }
  if (writer->replacement_.replacing())
    core::log_info("the earlier run is kept in " + writer->replacement_.aside().string() +
                   " until this one finishes");
  return writer;
}

void RunWriter::check(const RunPaths& run, bool replace, const std::vector<fs::path>& inputs) {
  io::check_output_folder(
      {run.root, io::OutputKind::Run, replace || is_unstarted_run(run), inputs});
}

std::unique_ptr<RunWriter> RunWriter::reopen(const RunPaths& run) {
  std::unique_ptr<RunWriter> writer(new RunWriter(run, {run.root, io::OutputKind::Run, true, {}}));
  if (io::output_kind(run.root) != io::OutputKind::Run)
    throw core::Error(run.root,
                      "not a ddhgs run folder (no " + std::string(io::kOutputMarker) + " marker)");
  writer->lock_ = io::FolderLock(run.root, "train");
  writer->replacement_.resume();
  return writer;
}

void RunWriter::finished() {
  if (replacement_.replacing())
    core::log_info("removing " + replacement_.aside().string() + ", the run this one replaced");
  replacement_.commit();
}

void RunWriter::resumed(int64_t iteration, std::string config_text) {
  saved_iteration_ = resumed_from_ = iteration;
  config_before_resume_ = std::move(config_text);
}

void RunWriter::failed() {
  if (fs::exists(run_.checkpoint())) {
    // What the checkpoint holds, and nothing of the iterations after it.
    try {
      if (saved_iteration_ >= 0) MetricsLog::truncate_after(run_.metrics(), saved_iteration_);
      if (resumed_from_ >= 0 && saved_iteration_ == resumed_from_)
        io::write_file_atomically(run_.config(), config_before_resume_);
    } catch (const std::exception& e) {
      core::log_warn(run_.root.string() + ": could not put the log and config.json back to " +
                     "the last checkpoint (" + core::message_of(e) + ")");
    }
    core::log_warn(run_.root.string() + " is kept; continue it with: ddhgs train --resume " +
                   run_.root.string());
    return;
  }
  if (replacement_.replacing())
    core::log_info("restoring the earlier run from " + replacement_.aside().string());
  lock_.release();
  replacement_.rollback();
}

bool is_unstarted_run(const RunPaths& run) {
  std::error_code ec;
  if (io::output_kind(run.root) != io::OutputKind::Run) return false;
  if (fs::exists(run.checkpoint(), ec) || fs::exists(run.gaussians(), ec)) return false;
  if (fs::is_directory(run.root / "checkpoints", ec) && !fs::is_empty(run.root / "checkpoints", ec))
    return false;
  return true;
}

nlohmann::json read_run_config(const RunPaths& run) {
  if (!fs::exists(run.config())) throw core::Error(run.config(), "missing: not a ddhgs run folder");
  nlohmann::json config = nlohmann::json::parse(io::read_file(run.config()), nullptr, false);
  if (config.is_discarded()) throw core::Error(run.config(), "not valid JSON");
  const std::vector<std::string> filled = fill_added_keys(config, run.config().string());
  if (!filled.empty()) {
    std::string list;
    for (const std::string& f : filled) list += (list.empty() ? "" : ", ") + f;
    static std::mutex mutex;
    static std::set<std::string> told;  // once per file, however often it is read
    std::lock_guard<std::mutex> lock(mutex);
    if (told.insert(fs::absolute(run.config()).string()).second)
      core::log_info(
          run.config().string() +
          " is from an earlier ddhgs; reading it with the values it trained with: " + list);
  }
  validate_config(config, run.config().string());
  return config;
}

void rewind_to_gaussian_end(const RunPaths& run, int64_t iterations, const nlohmann::json& config) {
  const fs::path at_end = run.checkpoint_at(iterations);
  if (!fs::exists(at_end))
    throw core::Error(at_end, "missing: the run cannot go back to the end of its " +
                                  std::to_string(iterations) +
                                  " Gaussian iterations (resume without --iterations to "
                                  "finish it as configured)");
  io::copy_file_atomically(at_end, run.checkpoint());
  fs::remove(run.summary());
  fs::remove(run.pseudo_views());  // made from the Gaussians being rewound
  io::write_file_atomically(run.config(), config.dump(2) + "\n");
}

MetricsLog::MetricsLog(const fs::path& path, int64_t keep_until) : path_(path) {
  std::string kept;
  if (keep_until >= 0 && fs::exists(path)) {
    std::istringstream lines(io::read_file(path));
    for (std::string line; std::getline(lines, line);) {
      auto record = nlohmann::json::parse(line, nullptr, false);
      if (record.is_object() && record.value("iter", int64_t(-1)) <= keep_until)
        kept += line + "\n";
    }
  }
  io::write_file_atomically(path, kept);
  fd_ = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd_ < 0) throw core::Error(path, "cannot open for writing: " + io::system_error_text(errno));
}

void MetricsLog::truncate_after(const fs::path& path, int64_t iteration) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return;
  const std::string text = io::read_file(path);
  size_t keep = 0;
  for (size_t start = 0; start < text.size();) {
    size_t end = text.find('\n', start);
    end = end == std::string::npos ? text.size() : end + 1;
    auto record = nlohmann::json::parse(text.substr(start, end - start), nullptr, false);
    if (!record.is_object() || record.value("iter", int64_t(-1)) > iteration) break;
    keep = start = end;
  }
  if (keep == text.size()) return;
  if (::truncate(path.c_str(), off_t(keep)) != 0)
    throw core::Error(path, "cannot cut it back: " + io::system_error_text(errno));
}

MetricsLog::~MetricsLog() {
  if (fd_ >= 0) ::close(fd_);
}

void MetricsLog::write(const nlohmann::json& record) {
  const std::string line = record.dump() + "\n";
  ssize_t n;
  do {
    n = ::write(fd_, line.data(), line.size());
  } while (n < 0 && errno == EINTR);
  if (n < 0) throw core::Error(path_, "write failed: " + io::system_error_text(errno));
  if (size_t(n) != line.size()) throw core::Error(path_, "write failed: no space left on device");
}

double peak_rss_mib() {
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

}  // namespace ddhgs::train
