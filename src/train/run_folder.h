// The run folder contract (read by `ddhgs eval` and `ddhgs render`):
//   RUN/config.json          resolved config, every key (train/config.h)
//   RUN/gaussians.ply        final model (io::write_gaussian_ply)
//   RUN/checkpoint.pt        latest checkpoint; RUN/checkpoints/ckpt_<iter>.pt
//   RUN/metrics.jsonl        one JSON object per logged iteration
//   RUN/train_summary.json   iterations, seconds, it/s, final G, bytes per Gaussian, peak RSS
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"

namespace ddhgs::train {

struct RunPaths {
  std::filesystem::path root;
  std::filesystem::path config() const { return root / "config.json"; }
  std::filesystem::path gaussians() const { return root / "gaussians.ply"; }
  std::filesystem::path checkpoint() const { return root / "checkpoint.pt"; }
  std::filesystem::path checkpoint_at(int64_t iteration) const;
  std::filesystem::path metrics() const { return root / "metrics.jsonl"; }
  std::filesystem::path summary() const { return root / "train_summary.json"; }
  // The background spectrum a run learned or took from its views
  // (model.learn_background, model.background_from_views).
  std::filesystem::path learned_background() const { return root / "background.json"; }
  // The band cameras' corrections a rig run learned (camera_refinement.rig).
  std::filesystem::path rig_corrections() const { return root / "rig_corrections.json"; }
  // The scene's georeference as the run was trained on it (io/geo/georef.h).
  std::filesystem::path georef() const { return root / "georef.json"; }
  // The distillation's pseudo-view targets while it runs (removed at the end).
  std::filesystem::path pseudo_views() const { return root / "pseudo_views.pt"; }
};

// The top-level names a run folder's files have (recorded in its marker as
// ddhgs's; `--force` refuses a run holding anything else).
std::vector<std::string> run_entry_names();

// A run folder while `train` writes it: locked against a second writer for
// the writer's life (io/files/folder_lock.h) and marked as a ddhgs run.
class RunWriter {
 public:
  // A new run: creates the folder and writes config.json. An existing run
  // folder is replaced only with `replace` (--force), or when it is the
  // remains of a run that stopped before its first checkpoint; it is kept
  // beside as RUN.previous until the new run finishes (io::FolderReplacement).
  // Anything that is not a ddhgs run, and any folder holding one of `inputs`,
  // is refused (io::check_output_folder).
  static std::unique_ptr<RunWriter> create(const RunPaths& run, const nlohmann::json& config,
                                           bool replace,
                                           const std::vector<std::filesystem::path>& inputs);
  // What create() would refuse, checked before any work is done.
  static void check(const RunPaths& run, bool replace,
                    const std::vector<std::filesystem::path>& inputs);
  // An existing run continued by --resume.
  static std::unique_ptr<RunWriter> reopen(const RunPaths& run);

  // Training finished: the run this one replaced, if any, is deleted.
  void finished();
  // Training failed: a run without a checkpoint is removed and the run it
  // replaced comes back; a run with one is kept for --resume, its metrics
  // cut back to the last checkpoint saved, and a resumed run that saved no
  // new checkpoint gets its config.json back as it was before --resume.
  void failed();

  // --resume continues from `iteration` and is about to rewrite config.json,
  // which held `config_text`.
  void resumed(int64_t iteration, std::string config_text);
  // A checkpoint of `iteration` is on disk.
  void saved(int64_t iteration) { saved_iteration_ = iteration; }

 private:
  RunWriter(const RunPaths& run, io::OutputRequest request);
  int64_t saved_iteration_ = -1, resumed_from_ = -1;
  std::string config_before_resume_;
  RunPaths run_;
  io::FolderReplacement replacement_;
  io::FolderLock lock_;
};

// True when the folder holds a ddhgs run that never reached a checkpoint
// (config.json and an empty log at most): nothing there is worth keeping.
bool is_unstarted_run(const RunPaths& run);

// Reads and validates RUN/config.json (format_version, keys, types).
nlohmann::json read_run_config(const RunPaths& run);

// Rewinds a run that trained past its Gaussian iterations (into the
// denoiser's fine-tuning) to their end: RUN/checkpoint.pt becomes a copy of
// the checkpoint kept at `iterations`, train_summary.json goes (the run is
// unfinished again) and config.json becomes `config`. Used by --resume with
// new --iterations and by ablations whose rows differ only in the
// fine-tuning. core::Error naming the checkpoint when it is missing.
void rewind_to_gaussian_end(const RunPaths& run, int64_t iterations, const nlohmann::json& config);

// Appends JSON lines, each with one write(2) so a crash loses at most one and
// a full disk is reported as such.
class MetricsLog {
 public:
  // Keeps the existing lines whose "iter" <= keep_until (a resumed run
  // rewrites what it will log again); keep_until < 0 starts empty.
  MetricsLog(const std::filesystem::path& path, int64_t keep_until);
  ~MetricsLog();
  MetricsLog(const MetricsLog&) = delete;
  MetricsLog& operator=(const MetricsLog&) = delete;
  void write(const nlohmann::json& record);
  // Drops the lines after the last whose "iter" <= iteration, in place (no
  // room needed: it runs when a full disk ended training).
  static void truncate_after(const std::filesystem::path& path, int64_t iteration);

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

// Peak resident set size of this process, MiB.
double peak_rss_mib();

}  // namespace ddhgs::train
