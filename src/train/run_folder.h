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
#include <fstream>

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
  // Where --force parks an earlier run until the new one has finished.
  std::filesystem::path previous() const;
};

// Creates a fresh run folder and writes config.json. An existing non-empty
// folder is refused unless force; with force it is moved to previous() (and
// an older previous() removed), to be deleted by finish_replacing().
void create_run_folder(const RunPaths& run, const nlohmann::json& config, bool force);
void finish_replacing(const RunPaths& run);

// Reads and validates RUN/config.json (format_version, keys, types).
nlohmann::json read_run_config(const RunPaths& run);

// Appends JSON lines, flushed per line so a crash loses at most one.
class MetricsLog {
 public:
  // Keeps the existing lines whose "iter" <= keep_until (a resumed run
  // rewrites what it will log again); keep_until < 0 starts empty.
  MetricsLog(const std::filesystem::path& path, int64_t keep_until);
  void write(const nlohmann::json& record);

 private:
  std::filesystem::path path_;
  std::ofstream out_;
};

// Peak resident set size of this process, MiB.
double peak_rss_mib();

}  // namespace ddhgs::train
