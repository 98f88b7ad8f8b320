// `ddhgs process CUBES_DIR --out SCENE`: raw hyperspectral captures -> a
// trainable scene (reflectance through white and dark references, pseudo-RGB,
// COLMAP poses and sparse points with spectra).
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "app/number_list.h"
#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/threads.h"
#include "process/process.h"
#include "process/pseudo_rgb_images.h"
#include "process/rig.h"

namespace ddhgs::app {
namespace cmd_process {

struct ProcessArgs {
  std::string cubes_dir, out, pseudo_rgb = "cie", wl_range, poses;
  // raw counts to reflectance
  std::string white, dark, white_reflectance = "1";
  double saturation = 0;
  process::ColmapOptions colmap;
  bool skip_colmap = false, force = false;
  // --rig: multispectral rig captures
  bool rig = false;
  std::string panel, panel_albedo;
  std::vector<std::string> panel_regions;
  int reference_camera = 0;
  CLI::Option* reference_option = nullptr;
};

// "x,y,w,h" (every camera) or "CAMERA:x,y,w,h" -> the regions by rig index.
io::PanelRegions parse_panel_regions(const std::vector<std::string>& values) {
  io::PanelRegions regions;
  for (const std::string& value : values) {
    const size_t colon = value.find(':');
    int camera = -1;
    std::string box = value;
    if (colon != std::string::npos) {
      const std::vector<double> index =
          parse_number_list(value.substr(0, colon), "--panel-region camera");
      core::require(index.size() == 1 && index[0] >= 0 && index[0] == double(int(index[0])),
                    "--panel-region '" + value +
                        "': expected CAMERA:x,y,w,h with a rig camera "
                        "number before the colon");
      camera = int(index[0]);
      box = value.substr(colon + 1);
    }
    const std::vector<double> v = parse_number_list(box, "--panel-region");
    core::require(v.size() == 4, "--panel-region '" + value +
                                     "': expected x,y,w,h (pixels), optionally after CAMERA:");
    std::array<int64_t, 4> b{};
    for (size_t i = 0; i < 4; ++i) {
      core::require(v[i] == double(int64_t(v[i])),
                    "--panel-region '" + value + "': x, y, w, h are whole pixels");
      b[i] = int64_t(v[i]);
    }
    core::require(regions.emplace(camera, b).second,
                  "--panel-region: camera " + std::to_string(camera) + " given twice");
  }
  return regions;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<ProcessArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "process",
      "Pose a folder of hyperspectral cubes (or multispectral rig captures, --rig) with COLMAP "
      "and write a trainable scene");
  cmd->add_option("CUBES_DIR", args->cubes_dir,
                  "Folder of cubes (.npy .pt ENVI .hdr .tif), of Specim IQ capture folders (each "
                  "with capture/: the raw cube, WHITEREF_* and DARKREF_*, used to make "
                  "reflectance), or of rig captures with --rig")
      ->required();
  cmd->add_option("--white", args->white,
                  "White reference (a cube file of a few lines or frames, averaged over its rows "
                  "into one value per column and band): the cubes are raw counts, made "
                  "reflectance = (raw - dark) / (white - dark) x its reflectance");
  cmd->add_option("--dark", args->dark, "Dark reference for --white (same form)");
  cmd->add_option("--white-reflectance", args->white_reflectance,
                  "The white reference's reflectance: a number, or a file of one value per band "
                  "or of wavelength_nm,reflectance lines (interpolated at the bands)")
      ->capture_default_str();
  cmd->add_option("--saturation", args->saturation,
                  "Raw count at which the sensor saturates (default: the sample type's top, e.g. "
                  "65535; a 12-bit sensor stored in 16 bits: 4095)")
      ->check(within(1, 1e12));
  cmd->add_flag("--rig", args->rig,
                "CUBES_DIR holds multispectral rig captures (one raw TIFF per band camera, "
                "MicaSense layout): write a band-per-view scene of their reflectance");
  cmd->add_option("--panel", args->panel,
                  "With --rig: folder of one calibration-panel capture (reflectance from the "
                  "panel; without it, from each capture's DLS irradiance)");
  cmd->add_option("--panel-albedo", args->panel_albedo,
                  "With --panel: the panel's albedo per band camera, in rig order (a,b,c,...)");
  cmd->add_option("--panel-region", args->panel_regions,
                  "With --panel: where the panel lies, x,y,w,h in pixels, for every band "
                  "image of the panel capture or CAMERA:x,y,w,h for one camera (rig number); "
                  "repeatable (default: the panel is found in each band image)");
  args->reference_option = cmd->add_option(
      "--reference-camera", args->reference_camera,
      "With --rig: the band camera (the rig's own number, RigCameraIndex) whose images COLMAP "
      "poses; the others follow by their rig rotations (default: the camera with the "
      "brightest reflectance)");
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
    if (!args->rig)
      for (const auto& [flag, given] :
           {std::pair<const char*, bool>{"--panel", !args->panel.empty()},
            {"--panel-albedo", !args->panel_albedo.empty()},
            {"--panel-region", !args->panel_regions.empty()},
            {"--reference-camera", args->reference_option->count() > 0}})
        core::require(!given, std::string(flag) + ": only used with --rig");
    if (args->rig)
      for (const auto& [flag, given] :
           {std::pair<const char*, bool>{"--white", !args->white.empty()},
            {"--dark", !args->dark.empty()},
            {"--white-reflectance", args->white_reflectance != "1"},
            {"--saturation", args->saturation > 0}})
        core::require(!given, std::string(flag) +
                                  ": for hyperspectral cubes; a rig's captures become reflectance "
                                  "through --panel or the DLS");
    if (args->rig) {
      process::RigProcessOptions options;
      options.captures_dir = args->cubes_dir;
      options.out = args->out;
      options.panel_dir = args->panel;
      if (!args->panel_albedo.empty())
        options.panel_albedo = parse_number_list(args->panel_albedo, "--panel-albedo");
      if (args->reference_option->count() > 0) options.reference_camera = args->reference_camera;
      core::require(args->panel_regions.empty() || !args->panel.empty(),
                    "--panel-region: only used with --panel");
      options.panel_regions = parse_panel_regions(args->panel_regions);
      options.colmap = args->colmap;
      options.colmap.threads = core::thread_count();
      options.poses = args->poses;
      options.force = args->force;
      process::ProcessResult result = process::process_rig(options);
      core::log_info("process: " + std::to_string(result.registered) + " of " +
                     std::to_string(result.views) + " band images posed, " +
                     std::to_string(result.points) + " points -> " + args->out + " in " +
                     core::format_duration(result.seconds));
      return 0;
    }
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
    options.reflectance.white = args->white;
    options.reflectance.dark = args->dark;
    options.reflectance.white_reflectance = args->white_reflectance;
    if (args->saturation > 0) options.reflectance.saturation = args->saturation;
    process::ProcessResult result = process::process_cubes(options);
    core::log_info("process: " + std::to_string(result.registered) + " of " +
                   std::to_string(result.views) + " views posed, " + std::to_string(result.points) +
                   " points -> " + args->out + " in " + core::format_duration(result.seconds));
    return 0;
  };
}

Registrar registrar("process", 15, setup);

}  // namespace cmd_process
}  // namespace ddhgs::app
