// Structure from motion for hyperspectral captures (`ddhgs process`): a folder
// of cubes -> pseudo-RGB PNGs -> COLMAP (feature extraction, matching,
// mapping; CPU SIFT, run as subprocesses) -> a scene folder the trainer reads:
// transforms.json (nerfstudio axes, wavelengths, cube paths), the pseudo-RGB
// images, points.ply with per-band mean spectra of the sparse points, the
// chosen COLMAP model under sparse/0, colmap.log and process.json.
#pragma once
#include <torch/torch.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/colour.h"
#include "io/colmap.h"
#include "io/cube.h"
#include "io/transforms.h"

namespace ddhgs::io {

// The cubes of one capture, all of one size and band count.
struct CubeSet {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> files;  // sorted by file name
  std::vector<std::string> names;            // file stems, unique
  int64_t height = 0, width = 0, bands = 0;  // pixels, pixels, bands
  std::vector<double> wavelengths_nm;        // one per band
};

// First and last band centres (nm) of an evenly spaced grid.
struct WavelengthRange {
  double first_nm = 0, last_nm = 0;
};
// "MIN:MAX" in nm; core::Error naming the option otherwise.
WavelengthRange parse_wavelength_range(const std::string& text);

// Cube files of dir (.npy .pt .hdr .tif .tiff; an ENVI pair counts once, by
// its .hdr), headers only. range: the grid for cubes whose files name no
// wavelengths (.npy, .pt); files that name them must agree. core::Error
// naming the file or folder: no cubes, two cubes with one stem, unreadable
// header, band count or size differing from the first cube, no wavelengths.
CubeSet scan_cubes(const std::filesystem::path& dir,
                   const std::optional<WavelengthRange>& range = std::nullopt);

// "cie" (CIE 1931 + D65), "bands:R,G,B" (nearest bands to these wavelengths,
// nm) or "matrix:FILE" (3 rows of N weights, see core::parse_pseudo_rgb's
// map:FILE); the core spellings are accepted too.
core::PseudoRgbOptions parse_sfm_pseudo_rgb(const std::string& spec);

// Display-linear pseudo-RGB of each view [H, W, 3] -> 8-bit sRGB images with
// ONE contrast stretch for the whole scene: the low / high percentiles of all
// views' values map to 0 / 1, so a surface looks the same in every image and
// SIFT descriptors match across views.
struct Stretch {
  double low = 0, high = 1;  // display-linear values mapped to 0 and 1
};
// samples: display-linear values (any shape); low/high percentiles in [0, 100].
Stretch scene_stretch(const std::vector<torch::Tensor>& samples, double low_percent = 0.5,
                      double high_percent = 99.5);
// linear: float [H, W, 3] display-linear; returns uint8 [H, W, 3], sRGB-encoded
// when encode (CIE and bands modes), else stretched values as they are.
torch::Tensor apply_stretch(const torch::Tensor& linear, const Stretch& stretch, bool encode);
// Display-linear pseudo-RGB float [H, W, 3] of a float cube [H, W, N] in
// [0, 1]; values up to 16 x white survive (headroom for radiance cubes).
torch::Tensor pseudo_rgb_linear(const torch::Tensor& cube,
                                const std::vector<double>& wavelengths_nm,
                                const core::PseudoRgbOptions& options);
// Whether a mode's display values get the sRGB curve.
bool pseudo_rgb_encodes(const core::PseudoRgbOptions& options);

// Writes images_dir/<name>.png for every cube; returns the stretch used.
Stretch write_pseudo_rgb_images(const CubeSet& cubes, const core::PseudoRgbOptions& options,
                                const std::filesystem::path& images_dir);

// --- COLMAP -----------------------------------------------------------------

struct ColmapOptions {
  std::string binary;                  // empty: $DDHGS_COLMAP, else colmap on PATH
  std::string matcher = "exhaustive";  // or "sequential"
  // SIMPLE_PINHOLE (one focal length) by default: on a turntable capture a
  // PINHOLE fit let fy drift 46 % from fx (docs/benchmarks.md).
  std::string camera_model = "SIMPLE_PINHOLE";  // or PINHOLE
  std::vector<std::string> settings;            // "Section.key=value", routed by section
  int threads = 1;                              // COLMAP's num_threads for every stage
};

// Checks matcher and camera model (distorting models are refused: the
// renderer needs undistorted pinhole cameras) and the settings' syntax.
void check_colmap_options(const ColmapOptions& options);

// Absolute path of the COLMAP executable; core::Error saying how to install
// it when it cannot be found.
std::string find_colmap(const ColmapOptions& options);

// Runs feature_extractor, the matcher and mapper on work/database.db and
// images_dir, models to work/sparse/<k>, every line of output appended to
// log_path, one progress bar per stage. core::Error naming log_path when a
// stage fails.
void run_colmap(const ColmapOptions& options, const std::filesystem::path& images_dir,
                const std::filesystem::path& work, const std::filesystem::path& log_path);

// Index of the model with the most registered images (ties: most points);
// nullopt when models is empty.
std::optional<size_t> largest_model(const std::vector<ColmapModel>& models);

// --- Conversion -------------------------------------------------------------

// transforms.json frames for the registered images of model (matched to
// cubes by file stem), in cube order. cube_paths: as written in the file
// (relative to the scene folder). core::Error for a distorting camera.
TransformsFile transforms_from_colmap(const ColmapModel& model, const CubeSet& cubes,
                                      const std::vector<std::string>& cube_paths);
// The inverse: one PINHOLE camera per distinct intrinsics, images named by
// the frames' file_path, no points.
ColmapModel colmap_from_transforms(const TransformsFile& file);

// Mean spectrum [P, N] of each point of model over the pixels where it was
// observed, from the cubes (float, [0, 1]); each cube is read once. Points
// with no observation in a known cube get the mean of all observed points.
torch::Tensor sample_point_spectra(const ColmapModel& model, const CubeSet& cubes);

// --- The whole command --------------------------------------------------------

struct ProcessOptions {
  std::filesystem::path cubes_dir, out;
  core::PseudoRgbOptions pseudo_rgb;
  std::string pseudo_rgb_spec = "cie";
  std::optional<WavelengthRange> wavelengths;  // for cubes that name none
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

}  // namespace ddhgs::io
