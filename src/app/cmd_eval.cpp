// `ddhgs eval RUN`: metrics of a trained run on its test views (or another
// split), against the stored views and, for synthetic scenes, clean ground
// truth; render speed.
#include <filesystem>
#include <iostream>

#include "app/registry.h"
#include "app/trained_run.h"
#include "eval/evaluate.h"

namespace ddhgs::app {
namespace {
namespace fs = std::filesystem;

struct EvalArgs {
  std::string run;
  std::string split = "test";
  int fps_repeats = 5;
  std::string data;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "eval",
      "Evaluate a trained run: PSNR, SSIM, SAM, RMSE, per-band PSNR and FPS; writes "
      "RUN/eval/metrics.json and RUN/eval/per_view.csv (metrics_<split>.json and "
      "per_view_<split>.csv for a split other than test)");
  cmd->add_option("run", args->run, "Run folder written by ddhgs train")->required();
  cmd->add_option("--split", args->split, "Views to evaluate")
      ->check(CLI::IsMember({"test", "train", "all"}))
      ->capture_default_str();
  cmd->add_option("--fps-repeats", args->fps_repeats,
                  "Timed passes over the test views for FPS (0: skip timing)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--data", args->data, "Dataset folder, if it moved since training");
  return [args] {
    TrainedRun run = open_trained_run(args->run, args->data);
    std::vector<int> views = eval::split_views(*run.scene, args->split);
    eval::EvalOptions options;
    options.fps_repeats = args->fps_repeats;
    eval::EvalReport report =
        eval::evaluate(*run.scene, run.gaussians, run.background, views, args->split, options);

    fs::path out = run.root / "eval";
    fs::create_directories(out);
    std::string suffix = args->split == "test" ? "" : "_" + args->split;
    fs::path metrics = out / ("metrics" + suffix + ".json");
    fs::path per_view = out / ("per_view" + suffix + ".csv");
    eval::write_metrics_json(metrics, report);
    eval::write_per_view_csv(per_view, report);
    std::cout << eval::format_report(report) << "wrote " << metrics.string() << " and "
              << per_view.string() << "\n";
    return 0;
  };
}

Registrar registrar("eval", 50, setup);

}  // namespace
}  // namespace ddhgs::app
