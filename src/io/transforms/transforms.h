// transforms.json in the nerfstudio / Hyper-NeRF layout.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "io/rig/rig_layout.h"

namespace ddhgs::io {

struct TransformsFrame {
  std::string file_path;                // pseudo-RGB image, relative to the file's folder
  std::string hyperspectral_file_path;  // cube; empty for an RGB dataset
  core::Intrinsics intrinsics;          // per-frame, or copied from the global keys
  core::Mat4 camera_to_world_gl;        // as stored: OpenGL axes, maybe scaled rotation
  // ddhgs extension for band-per-view scenes (one camera per band, as on a
  // multispectral rig): the frame's file holds these bands of the top-level
  // "wavelengths" list (0-based indices, in the file's band order). Empty:
  // the file holds every band.
  std::vector<int> bands;
  // ddhgs extension for rig scenes: the RigCameraIndex of the band camera
  // that took the frame (one of TransformsFile::rig's cameras; MicaSense
  // numbers them from 0 or 1); -1: none.
  int rig_camera = -1;
};

struct TransformsFile {
  std::vector<TransformsFrame> frames;
  std::vector<double> wavelengths_nm;  // optional top-level "wavelengths"
  std::string ply_file_path;           // optional initial points
  // nerfstudio's "applied_transform" (3x4): the map from the COLMAP model's
  // world frame to this file's, when the file was made from one.
  std::optional<core::Mat4> applied_transform;
  std::optional<double> scale;  // optional divisor for integer cubes
  // Optional explicit split: file_path values of the train / test frames.
  std::vector<std::string> train_files, test_files;
  // ddhgs extension (`ddhgs process --rig`): the rig's band cameras as their
  // metadata describes them.
  std::optional<TransformsRig> rig;
};

// Throws core::Error naming the file for missing keys or wrong types.
TransformsFile read_transforms(const std::filesystem::path& path);
// Writes global intrinsics when all frames share them, per-frame otherwise.
void write_transforms(const std::filesystem::path& path, const TransformsFile& file);

}  // namespace ddhgs::io
