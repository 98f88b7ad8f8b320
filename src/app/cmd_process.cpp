// `ddhgs process CUBES_DIR --out SCENE`: raw hyperspectral captures -> a
// trainable scene (pseudo-RGB, COLMAP poses and sparse points with spectra).
#include <memory>

#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/threads.h"
#include "process/process.h"
#include "process/pseudo_rgb_images.h"

namespace ddhgs::app {
namespace {

struct ProcessArgs {
  std::string cubes_dir, out, pseudo_rgb = "cie", wl_range, poses;
  process::ColmapOptions colmap;
  bool skip_colmap = false, force = false;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<ProcessArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "process", "Pose a folder of hyperspectral cubes with COLMAP and write a trainable scene");
  cmd->add_option("CUBES_DIR", args->cubes_dir, "Folder of cubes (.npy .pt ENVI .hdr .tif)")
      ->required();
  cmd->add_option("--out", args->out, "Output scene folder")->required();
  cmd->add_option("--matcher", args->colmap.matcher,
                  "exhaustive (any capture) or sequential (views in capture order)")
      ->capture_default_str();
  cmd->add_option("--camera-model", args->colmap.camera_model,
                  "SIMPLE_PINHOLE (square pixels), PINHOLE (fx, fy), or a lens model COLMAP "
                  "refines (SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, ...; the views are "
                  "undistorted when the scene loads); one camera for all views")
      ->capture_default_str();
  cmd->add_option("--pseudo-rgb", args->pseudo_rgb,
                  "cie[:D65|A|E], bands:R,G,B (nm) or matrix:FILE (3 rows of N weights)")
      ->capture_default_str();
  cmd->add_option("--wl-range", args->wl_range,
                  "MIN:MAX first and last band centre (nm), for cubes that name no wavelengths");
  cmd->add_option("--colmap-set", args->colmap.settings,
                  "COLMAP option Section.key=value (e.g. SiftExtraction.peak_threshold=0.004), "
                  "repeatable");
  cmd->add_option("--colmap", args->colmap.binary,
                  "COLMAP executable (default: $DDHGS_COLMAP, else colmap on PATH)");
  cmd->add_flag("--skip-colmap", args->skip_colmap, "Take poses from --poses instead of COLMAP");
  cmd->add_option("--poses", args->poses,
                  "With --skip-colmap: COLMAP model folder (.bin/.txt) or transforms.json");
  cmd->add_flag("--force", args->force, "Replace an existing non-empty output folder");
  return [args] {
    core::require(args->skip_colmap == !args->poses.empty(),
                  args->skip_colmap ? "--skip-colmap: expected --poses FILE with the poses"
                                    : "--poses: only used with --skip-colmap");
    process::ProcessOptions options;
    options.cubes_dir = args->cubes_dir;
    options.out = args->out;
    options.pseudo_rgb_spec = args->pseudo_rgb;
    options.pseudo_rgb = process::parse_sfm_pseudo_rgb(args->pseudo_rgb);
    if (!args->wl_range.empty())
      options.wavelengths = process::parse_wavelength_range(args->wl_range);
    options.colmap = args->colmap;
    options.colmap.threads = core::thread_count();
    options.poses = args->poses;
    options.force = args->force;
    process::ProcessResult result = process::process_cubes(options);
    core::log_info("process: " + std::to_string(result.registered) + " of " +
                   std::to_string(result.views) + " views posed, " + std::to_string(result.points) +
                   " points -> " + args->out + " in " + core::format_duration(result.seconds));
    return 0;
  };
}

Registrar registrar("process", 15, setup);

}  // namespace
}  // namespace ddhgs::app
