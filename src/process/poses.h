// `ddhgs process`, last step: COLMAP poses and points to the scene's
// transforms.json and points with per-band spectra, and back.
#pragma once
#include "core/tensor.h"

#include <string>
#include <vector>

#include "io/colmap/colmap.h"
#include "io/transforms/transforms.h"
#include "process/cube_set.h"

namespace ddhgs::process {

// The cube index of every image of model whose name matches a cube; -1 otherwise.
std::vector<int64_t> cube_of_images(const io::ColmapModel& model, const CubeSet& cubes);

// transforms.json frames for the registered images of model (matched to
// cubes by file stem), in cube order. cube_paths: as written in the file
// (relative to the scene folder). Lens distortion is kept (the scene's
// views are undistorted as they load).
io::TransformsFile transforms_from_colmap(const io::ColmapModel& model, const CubeSet& cubes,
                                          const std::vector<std::string>& cube_paths);
// The inverse: one camera per distinct intrinsics (io::colmap_camera_of),
// images named by the frames' file_path, no points.
io::ColmapModel colmap_from_transforms(const io::TransformsFile& file);

// Mean spectrum [P, N] of each point of model over the pixels where it was
// observed, from the cubes (float, [0, 1]); each cube is read once. Points
// with no observation in a known cube get the mean of all observed points.
torch::Tensor sample_point_spectra(const io::ColmapModel& model, const CubeSet& cubes);

}  // namespace ddhgs::process
