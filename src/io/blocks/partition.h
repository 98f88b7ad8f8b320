// `ddhgs partition`: a scene cut into overlapping blocks over its ground
// footprint, each block an ordinary scene folder (BLOCKS/block_NN/) that
// `ddhgs train` takes, and BLOCKS/blocks.json describing the cut.
#pragma once
#include <filesystem>

#include "io/blocks/block_grid.h"
#include "io/scene/scene.h"

namespace ddhgs::io {

struct PartitionOptions {
  std::filesystem::path scene;  // a transforms.json scene
  std::filesystem::path out;    // BLOCKS
  // rows x cols cells; rows 0: `blocks` cells arranged as close to square
  // cells as the footprint allows.
  int rows = 0, cols = 0, blocks = 4;
  double overlap = 0.2;  // margin on every side, of a cell's size
  bool force = false;    // replace an earlier BLOCKS folder
};

// A view belongs to a block when at least this share of its footprint
// lies in the block's cell and margin.
constexpr double kViewShare = 0.25;

// The flight's backdrop, the colour every block of it draws over
// (BlockContext::background): io::sampled_colour of the training views,
// kBackdropViews views (band by band in a band-per-view scene) and
// kBackdropPixels pixels of each. float32 [bands]. A nadir flight's median
// is its commonest ground (bare soil between rows, or the canopy), the
// colour a learned background settles at. core::Error naming the scene
// when no view holds a band.
constexpr int kBackdropViews = 16;
constexpr int64_t kBackdropPixels = 8192;
torch::Tensor flight_backdrop(const Scene& scene, const std::vector<int>& views);

// The rows and columns for `blocks` cells over a footprint of this size:
// the factorisation whose cells are closest to square.
std::pair<int, int> grid_shape(int blocks, double length_u, double length_v);

// Writes BLOCKS (io::write_folder_atomically: all or nothing). Each block
// holds the views that see its cell with the margin (kViewShare), split as
// in the scene (train_filenames / test_filenames), the points inside its
// cell and margin, its views' cubes, clean ground truth and images (hard
// links where the file system allows, else copies) and the scene's other
// top-level files (wavelengths, georeferencing, synth.json). core::Error
// naming the file or the block: not a transforms.json scene, a frame's
// file missing or outside the scene folder, a block without a training
// view.
BlocksFile partition_scene(const PartitionOptions& options);

}  // namespace ddhgs::io
