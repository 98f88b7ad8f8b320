// Structure from motion for hyperspectral captures (`ddhgs process`): a folder
// of cubes (raw counts first become reflectance through white and dark
// references, process/reflectance.h) -> pseudo-RGB PNGs -> COLMAP (feature extraction, matching,
// mapping; CPU SIFT, run as subprocesses) -> a scene folder the trainer reads:
// transforms.json (nerfstudio axes, wavelengths, cube paths), the pseudo-RGB
// images, points.ply with per-band mean spectra of the sparse points, the
// chosen COLMAP model under sparse/0, colmap.log and process.json.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/colour.h"
#include "process/colmap_runner.h"
#include "process/cube_set.h"
#include "process/reflectance.h"

namespace ddhgs::process {

struct ProcessOptions {
  std::filesystem::path cubes_dir, out;
  core::PseudoRgbOptions pseudo_rgb;
  std::string pseudo_rgb_spec = "cie";
  std::optional<WavelengthRange> wavelengths;  // for cubes that name none
  // Raw counts to reflectance (process/reflectance.h) before anything else:
  // the scene holds the reflectance cubes (reflectance/<name>.npy).
  ReflectanceOptions reflectance;
  ColmapOptions colmap;
  std::filesystem::path poses;  // --skip-colmap: COLMAP model folder or transforms.json
  bool force = false;
};

struct ProcessResult {
  int views = 0, registered = 0;
  std::vector<std::string> unregistered;  // cube names without a pose
  int64_t points = 0;
  double seconds = 0;
};

// Builds the scene in a temporary sibling of out and renames it at the end:
// a failure leaves no output folder (a failed COLMAP run leaves its log as
// <out>.colmap.log). Fewer than 3 posed views is an error.
ProcessResult process_cubes(const ProcessOptions& options);

// The output folder as the temporary sibling needs it: "scene/" is the
// folder scene.
std::filesystem::path output_folder(const std::filesystem::path& requested);

// Where COLMAP's log waits beside out while the scene is built, so that a
// failed run keeps it: <out>.colmap.log, its folder made and an old one
// removed.
std::filesystem::path colmap_log_beside(const std::filesystem::path& out);

// Poses given with --poses: a COLMAP model folder (.bin or .txt) or a
// transforms.json, as a COLMAP model. core::Error naming the path otherwise.
io::ColmapModel read_given_poses(const std::filesystem::path& poses);

// The largest model COLMAP wrote under sparse/ (a log line when there were several).
io::ColmapModel largest_colmap_model(const std::filesystem::path& sparse);

}  // namespace ddhgs::process
