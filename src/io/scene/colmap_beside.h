// Initial points for a transforms.json from a COLMAP model beside it (as
// Hyper-NeRF and nerfstudio datasets keep colmap/sparse/0 or sparse/0 next to
// their transforms.json), brought into the transforms.json's world frame.
//
// The two frames may differ (nerfstudio swaps axes and writes the map as
// "applied_transform"; Hyper-NeRF's basil scales and moves the scene). The
// model's images are matched to frames by file stem, and the map is the
// file's applied_transform when it fits the matched camera centres, else
// the least-squares similarity between the centres. The points are used
// when, after the map, the camera centres agree within 1 % (RMS) of their
// spread and the camera orientations within 1 degree (median).
#pragma once
#include <filesystem>
#include <string>

#include "io/ply/ply.h"
#include "io/transforms/transforms.h"

namespace ddhgs::io {

struct PointsBeside {
  PointCloud points;    // xyz undefined when the model's points are not used
  std::string message;  // why they are used (a note), or why not (a warning)
};

// file: the transforms.json (named in messages), tf: its contents.
PointsBeside points_beside(const std::filesystem::path& model_dir, const TransformsFile& tf,
                           const std::filesystem::path& file);

}  // namespace ddhgs::io
