// A rig scene's band cameras as their metadata describes them (the factory
// values), and the corrections training finds for them.
//
// A multispectral rig's band cameras sit a few centimetres apart and their
// factory rotations (XMP RigRelatives) drift. `ddhgs process --rig` places
// each band camera by its rotation alone; training may refine one correction
// per band camera, shared by every capture (train/rig_refinement.h):
//  - a rotation D (rotation vector r, radians) about the camera's centre and
//  - the offset o of its centre from the reference camera's,
// both in the reference camera's axes (the rig's frame), o in scene units.
// With T the factory rotation from the reference camera's axes to the band
// camera's (TransformsRig::turn), a point at x_ref in the reference camera's
// axes is at T D (x_ref - o) in the corrected band camera's.
#pragma once
#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/camera.h"

namespace ddhgs::io {

// The rotation by |r| radians about r's direction (a rotation vector), and
// the rotation vector of a rotation (angle in [0, pi]).
core::Mat3 rotation_from_vector(const core::Vec3& r);
core::Vec3 rotation_vector(const core::Mat3& rotation);

struct RigCameraInfo {
  int index = 0;                      // RigCameraIndex
  std::string band;                   // BandName
  std::vector<double> relatives_deg;  // RigRelatives (x, y, z), as in the metadata
};

// transforms.json's "rig" (ddhgs extension): which band cameras the frames
// came from (TransformsFrame::rig_camera) and their factory rotations.
struct TransformsRig {
  int reference_camera = 0;  // the camera whose poses the others follow
  double unit_m = 0;         // metres per scene unit; 0: unknown (e.g. COLMAP's scale)
  std::vector<RigCameraInfo> cameras;

  // Null when the rig has no such camera.
  const RigCameraInfo* camera(int index) const;
  // Factory rotation from the reference camera's axes to camera `index`'s.
  core::Mat3 turn(int index) const;
};

struct RigCorrection {
  core::Vec3 rotation_rad;  // rotation vector, reference camera's axes
  core::Vec3 offset;        // centre offset, scene units, reference camera's axes
};

// The band camera `camera` (placed by its factory rotation `turn`) corrected
// by `correction`: same intrinsics, the pose the header describes.
core::Camera corrected_band_camera(const core::Camera& camera, const core::Mat3& turn,
                                   const RigCorrection& correction);

// The corrections by rig camera index as JSON: each camera's rotation
// vector (rad) and offset (scene units), which read_rig_corrections reads,
// and for people its angle (degrees) and, when the unit is known, its
// offset in cm.
nlohmann::json rig_corrections_json(const TransformsRig& rig,
                                    const std::map<int, RigCorrection>& corrections);
// One line for people: "camera 2 (Green): turned 0.98 deg, centre moved by
// (5.1, -8.2, 0.3) cm (reference camera axes)" (scene units when the unit
// is unknown).
std::string describe_rig_correction(const TransformsRig& rig, int index,
                                    const RigCorrection& correction);
// RUN/rig_corrections.json: rig_corrections_json, written atomically.
void write_rig_corrections(const std::filesystem::path& path, const TransformsRig& rig,
                           const std::map<int, RigCorrection>& corrections);
// A rig_corrections.json, or a rig's known lever arms in the same form: each
// camera's "rig_camera", its "offset" in scene units or, where the scene's
// unit is known (unit_m metres per scene unit, > 0), its "offset_cm", and
// its "rotation_rad" (zero when absent). "offset" wins where both are given
// (a run's own file has both). core::Error naming the file when it is
// malformed, or gives offset_cm alone for a scene whose unit is unknown.
std::map<int, RigCorrection> read_rig_corrections(const std::filesystem::path& path,
                                                  double unit_m = 0);

}  // namespace ddhgs::io
