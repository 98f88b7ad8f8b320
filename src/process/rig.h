// `ddhgs process CAPTURES --rig`: a folder of multispectral rig captures (one
// raw TIFF per band camera per trigger, io/rig) -> a band-per-view scene.
//  - Each band image becomes reflectance (io/rig/rig_radiometry.h): through a
//    calibration-panel capture (--panel, --panel-albedo) when one is given,
//    else through each capture's DLS irradiance. Written as bands/<stem>.npy,
//    float32 [H, W, 1], at the camera's own resolution and lens (the scene
//    undistorts it as it loads).
//  - COLMAP poses the reference camera's images (one per capture; or the
//    poses come from --poses): by default the brightest camera (NIR over
//    vegetation; on the synthetic rig the blue camera's dark images posed
//    to 1.1 degrees median, NIR's to 0.15). Every other band camera of a capture takes the
//    reference pose turned by the two cameras' RigRelatives rotations; the
//    cameras' few-centimetre offsets are not placed (no translation):
//    training refines both per camera (camera_refinement.rig), from each
//    frame's "rig_camera" and the top-level "rig" (reference camera, factory
//    rotations, and metres per unit when given poses in a transforms.json
//    say it).
//  - transforms.json names each frame's band ("bands"), with a split by
//    capture (the Hyper-NeRF rule over captures: all bands of a capture are
//    on the same side); process.json says which calibration each camera used
//    and, with a panel, where the panel was found in each band and what its
//    region holds; panel/ shows each panel band image with the region drawn.
//  - Everything that can be checked before the work is: the metadata (as
//    the files are read), the reference camera, the number of captures.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "io/rig/rig_radiometry.h"
#include "process/colmap_runner.h"
#include "process/process.h"

namespace ddhgs::process {

struct RigProcessOptions {
  std::filesystem::path captures_dir, out;
  std::filesystem::path panel_dir;   // empty: reflectance from the DLS
  std::vector<double> panel_albedo;  // per band camera, in rig order
  // Where the panel lies, where the finder should not look for it
  // (io/rig/rig_radiometry.h: by rig index, -1 for every camera).
  io::PanelRegions panel_regions;
  // The rig's own number (RigCameraIndex) of the camera whose images COLMAP
  // poses; none: the camera with the brightest reflectance (the most
  // texture to match).
  std::optional<int> reference_camera;
  ColmapOptions colmap;
  std::filesystem::path poses;  // given poses instead of COLMAP
  bool force = false;
};

// Views are band images; registered counts posed band images. Built in a
// temporary sibling of out (nothing is left on failure).
ProcessResult process_rig(const RigProcessOptions& options);

}  // namespace ddhgs::process
