// `ddhgs report RUN`: a self-contained HTML report of a trained run (metrics,
// curves, per-band quality, pictures and a spectral viewer).
#include <cstdio>
#include <filesystem>

#include "app/registry.h"
#include "app/trained_run.h"
#include "core/error.h"
#include "eval/report.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "train/run_folder.h"

namespace ddhgs::app {
namespace cmd_report {
namespace fs = std::filesystem;

struct ReportArgs {
  std::string run;
  std::string out;
  std::string data;
  int views = 4;
  int viewer_views = 2;
  int viewer_px = 192;
  double diff_max = 0.1;
};

nlohmann::json read_json_if_present(const fs::path& path) {
  if (!fs::exists(path)) return nullptr;
  try {
    return nlohmann::json::parse(io::read_file(path));
  } catch (const nlohmann::json::exception&) {
    throw core::Error(path, "is not valid JSON");
  }
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "report",
      "Write an HTML report of a trained run (RUN/report/index.html): metrics, training curves, "
      "per-band PSNR/RMSE and SAM, ground truth | render | error pictures and a spectral viewer; "
      "opens from disk");
  cmd->add_option("run", args->run, "Run folder written by ddhgs train")->required();
  cmd->add_option("--out", args->out, "Report folder (default RUN/report); replaced if it exists");
  cmd->add_option("--data", args->data, "Dataset folder, if it moved since training");
  cmd->add_option("--views", args->views, "Test views shown as pictures")
      ->check(within(1, 10000))
      ->capture_default_str();
  cmd->add_option("--viewer-views", args->viewer_views,
                  "Test views in the spectral viewer (each adds every band as images, MBs for "
                  "100+ bands)")
      ->check(within(1, 10000))
      ->capture_default_str();
  cmd->add_option("--viewer-px", args->viewer_px,
                  "Longer side of the viewer's band images, pixels (area-averaged down)")
      ->check(within(8, 4096))
      ->capture_default_str();
  cmd->add_option("--diff-max", args->diff_max,
                  "Reflectance error at the top of the heatmap colour map")
      ->check(within(1e-12, 1e12))
      ->capture_default_str();
  return [args] {
    TrainedRun run = open_trained_run(args->run, args->data);
    io::FolderLock lock(run.root, "report");
    train::RunPaths paths{run.root};
    eval::RunRecords records;
    fs::path name = fs::absolute(run.root).lexically_normal();
    records.name = (name.filename().empty() ? name.parent_path() : name).filename().string();
    records.config = run.config.resolved;
    records.metrics_log = eval::read_metrics_log(paths.metrics());
    records.train_summary = read_json_if_present(paths.summary());
    records.eval_metrics = read_json_if_present(run.root / "eval" / "metrics.json");
    eval::ReportOptions options;
    options.out_dir = args->out.empty() ? run.root / "report" : fs::path(args->out);
    options.inputs = {run.root, run.scene->root};
    options.max_views = args->views;
    options.viewer_views = args->viewer_views;
    options.viewer_max_px = args->viewer_px;
    options.diff_max = args->diff_max;
    fs::path index =
        eval::write_report(*run.scene, run.gaussians, run.background, records, options);
    uintmax_t bytes = 0;
    for (const auto& entry : fs::recursive_directory_iterator(index.parent_path()))
      if (entry.is_regular_file()) bytes += entry.file_size();
    std::printf("report: %s (%.1f MB)\n", index.string().c_str(), double(bytes) / 1e6);
    return 0;
  };
}

Registrar registrar("report", 55, setup);

}  // namespace cmd_report
}  // namespace ddhgs::app
