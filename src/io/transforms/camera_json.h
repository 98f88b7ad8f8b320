// One pinhole camera as a small JSON file, the exchange format of
// `ddhgs render-ply` with other tools:
//   {"width": W, "height": H, "fx": .., "fy": .., "cx": .., "cy": ..,
//    "world_to_camera": [[4 x 4, row-major, OpenCV axes]]}
// Sizes and focal lengths in pixels; a 3 x 4 matrix is accepted as well.
#pragma once
#include <filesystem>

#include "core/camera.h"

namespace ddhgs::io {

// Throws core::Error naming the file for invalid JSON, missing keys, wrong
// types, non-positive sizes or focal lengths, non-finite numbers, and a matrix
// that is not a rigid transform (singular, scaled, reflecting, or a last row
// other than 0 0 0 1).
core::Camera read_camera_json(const std::filesystem::path& path);

// Atomic write; numbers round-trip exactly.
void write_camera_json(const std::filesystem::path& path, const core::Camera& camera);

}  // namespace ddhgs::io
