// Renders a list of frames (dataset views or orbit cameras) to cubes and
// pictures: the work behind `ddhgs render`.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "eval/figures.h"
#include "eval/vegetation_index.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

enum class OutputFormat {
  Png,   // pictures only
  Npy,   // float32 [H, W, N] .npy cube per frame, plus pictures
  Envi,  // ENVI .hdr + .img cube (BSQ, float32, wavelengths) per frame, plus pictures
};
OutputFormat parse_output_format(const std::string& name);  // "png", "npy", "envi"

struct Frame {
  std::string name;     // file stem
  core::Camera camera;  // at the output resolution
  int view = -1;        // scene view with ground truth, -1 for none (orbit)
};

struct RenderOptions {
  OutputFormat format = OutputFormat::Png;
  BandSelection bands;  // default: pseudo-RGB
  Colormap colormap = Colormap::Viridis;
  // For frames with ground truth: an error heatmap and a side-by-side
  // comparison (truth | render | error, with a colour bar under the error).
  bool diff = false;
  double diff_max = 0.1;  // reflectance error shown at the top of the colour map
  // Applied to every render before it is written (e.g. the diffusion
  // denoiser); [H, W, N] -> [H, W, N]. Empty: the raw render.
  std::function<torch::Tensor(const torch::Tensor& image)> transform;
  // Output channels other than the bands (core/band_map.h): [M, N], applied
  // after the colour model's decode and to the ground truth of --diff, with
  // the channels' wavelengths (for pictures and ENVI headers). Undefined:
  // the N bands.
  torch::Tensor band_map;
  std::vector<double> wavelengths_nm;
  // A vegetation index (eval/vegetation_index.h) in place of band pictures:
  // its map per frame, and with diff its error (diff_max at the top).
  std::optional<VegetationIndex> index;
};

// Frames for the views of a split, named by their file stems.
std::vector<Frame> view_frames(const io::Scene& scene, const std::vector<int>& views);
// Frames orbit_000, orbit_001, ... along eval::orbit_cameras of the training views.
std::vector<Frame> orbit_frames(const io::Scene& scene, int count);

// What a render folder's files show: its channels' wavelengths (the scene's
// bands, or those of options.band_map) and the index, if any, as the JSON
// text render_frames writes into channels.json. A render whose record
// differs from the folder's replaces the folder: its frames would otherwise
// sit beside earlier ones of another band count.
std::string channels_record(const io::Scene& scene, const RenderOptions& options);

// The files of an earlier render of the same channels that rendering frames
// with options makes stale: each frame's cube in the other format (NAME.npy
// beside a new NAME.hdr + NAME.img, or the reverse). For
// io::OutputRequest::superseded.
std::vector<std::string> superseded_files(const std::vector<Frame>& frames,
                                          const RenderOptions& options);

// Writes, per frame, into out_dir (an existing folder):
//   NAME.npy | NAME.hdr + NAME.img      the cube (npy / envi formats)
//   NAME_LABEL.png                      picture (LABEL: rgb, band42, 750-768nm)
//   NAME_LABEL_diff_max0.1.png          error heatmap (diff, frames with truth)
//   NAME_LABEL_compare.png              truth | render | error (diff, frames with truth)
// With an index, instead (LABEL: ndvi):
//   NAME_LABEL.png                      the index, -1 to 1 through RdYlGn, colour bar below
//   NAME_LABEL.npy                      float32 [H, W], NaN without signal (npy format)
//   NAME_LABEL_compare.png              truth | render | |error| (diff, frames with truth)
//   LABEL.json                          per frame: mean index, and the mean absolute
//                                       error against the truth's index (diff)
// and channels.json (channels_record).
// Ground truth is the clean view when the scene has one, else the stored view.
// A view that holds some of the bands (a band-per-view scene) is compared on
// them: its compare and diff pictures show the mean of its own bands, or of
// those of --band/--bands it holds, through the colour map (LABEL: its bands,
// band3 or band1-3, or the selection's label); a view holding none of the
// selected bands gets none. Its index truth comes from the views at its pose (a capture's
// band images through one lens); core::Error when they lack a band the
// index weighs (a rig's band cameras each look from their own pose).
// Returns the number of files written. The caller makes them appear together
// (io::write_into_folder_atomically).
int render_frames(const io::Scene& scene, const model::Gaussians& gaussians,
                  const torch::Tensor& background,  // [N]
                  const std::vector<Frame>& frames, const RenderOptions& options,
                  const std::filesystem::path& out_dir);

}  // namespace ddhgs::eval
