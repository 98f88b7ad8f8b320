#include "train/run_folder.h"

#include <sys/resource.h>

#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "io/atomic_file.h"
#include "train/config.h"

namespace ddhgs::train {

namespace fs = std::filesystem;

fs::path RunPaths::checkpoint_at(int64_t iteration) const {
  return root / "checkpoints" / ("ckpt_" + std::to_string(iteration) + ".pt");
}

fs::path RunPaths::previous() const {
  fs::path r = root;
  if (r.filename().empty()) r = r.parent_path();
  return r.parent_path() / (r.filename().string() + ".previous");
}

void create_run_folder(const RunPaths& run, const nlohmann::json& config, bool force) {
  std::error_code ec;
  const bool occupied =
      fs::exists(run.root, ec) && (!fs::is_directory(run.root) || !fs::is_empty(run.root, ec));
  if (occupied) {
    if (!force)
      throw core::Error(run.root,
                        "already exists; pass --force to replace it (it is kept until "
                        "the new run finishes) or --resume to continue it");
    fs::remove_all(run.previous(), ec);
    fs::rename(run.root, run.previous(), ec);
    if (ec)
      throw core::Error(run.root, "cannot move the existing run aside (" + ec.message() + ")");
  }
  fs::create_directories(run.root / "checkpoints", ec);
  if (ec) throw core::Error(run.root, "cannot create the run folder (" + ec.message() + ")");
  io::write_file_atomically(run.config(), config.dump(2) + "\n");
}

void finish_replacing(const RunPaths& run) {
  std::error_code ec;
  fs::remove_all(run.previous(), ec);
}

nlohmann::json read_run_config(const RunPaths& run) {
  if (!fs::exists(run.config())) throw core::Error(run.config(), "missing: not a ddhgs run folder");
  nlohmann::json config = nlohmann::json::parse(io::read_file(run.config()), nullptr, false);
  if (config.is_discarded()) throw core::Error(run.config(), "not valid JSON");
  if (config.is_object()) upgrade_run_config(config, run.config().string());
  const auto added = add_missing_keys(config);
  if (!added.empty()) {
    std::string names;
    for (const auto& key : added) names += (names.empty() ? "" : ", ") + key;
    core::log_info(run.config().string() +
                   ": made by an older ddhgs; new keys take their defaults (" + names + ")");
  }
  validate_config(config, run.config().string());
  return config;
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
  out_.open(path, std::ios::app);
  if (!out_) throw core::Error(path, "cannot open for writing");
}

void MetricsLog::write(const nlohmann::json& record) {
  out_ << record.dump() << "\n" << std::flush;
  if (!out_) throw core::Error(path_, "write failed (disk full?)");
}

double peak_rss_mib() {
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
}

}  // namespace ddhgs::train
