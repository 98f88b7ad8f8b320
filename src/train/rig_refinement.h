// One correction per band camera of a multispectral rig, learned beside the
// Gaussians and shared by every capture (camera_refinement.rig).
//
// `ddhgs process --rig` places each band camera by its factory rotation
// (XMP RigRelatives) and at the reference camera's centre; real rigs have
// their cameras a few centimetres apart and rotations that drift by a
// fraction of a degree, and Gaussians fitted to such views blur. Each band
// camera other than the reference gets a rotation r (radians) about its
// centre and an offset o of its centre (in scene extents while training),
// both in the reference camera's axes (io/rig/rig_layout.h has the
// geometry). The renderer has no gradient for cameras, so, as in
// train/camera_refinement.h, the Gaussians move instead: with M the
// reference camera's axes in the world (R_W^T T for the view's rotation
// R_W and the band camera's factory turn T) and D the rotation r,
//   x' = c + R(M r) (x - c) - M D o,   q' = q(M r) * q,
// which the view's recorded camera sees as the corrected camera sees x.
// With a pivot depth d > 0 the learned offset o' is measured from the
// band camera turned about the pivot p = (0, 0, d) in the reference
// camera's axes, the point it looks at, rather than about its centre:
//   o = o' + (I - D^T) p,
// so a turn r alone leaves the scene at depth d where it was in the image.
// A turn about the centre and a sideways move of d times it shift the image
// alike at depth d (only the scene's depth spread tells them apart); in
// these coordinates the image's shift is o' and the part the images barely
// see is r alone, which Adam's per-parameter steps then move at full rate.
// pull() is the L2 pull towards the factory values (zero turn and offset);
// held-out views are measured through io::corrected_band_camera.
#pragma once
#include <torch/nn/module.h>
#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <map>
#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/tensor.h"
#include "io/rig/rig_layout.h"
#include "io/scene/scene.h"

namespace ddhgs::train {

class RigRefinementImpl : public torch::nn::Module {
 public:
  // scene: a rig scene (Scene::rig, views with rig cameras); core::Error
  // naming its folder otherwise. pivot_depth (scene units): the pivot's
  // distance in front of the camera; 0 turns about the camera's centre.
  explicit RigRefinementImpl(const io::Scene& scene, double pivot_depth = 0);

  // means: [G, 3], quats: [G, 4] (w, x, y, z) moved for view v seen by
  // camera (its recorded camera, or a crop of it); unchanged for the
  // reference camera's views. Differentiable in the corrections.
  std::pair<torch::Tensor, torch::Tensor> move(int view, const core::Camera& camera,
                                               const torch::Tensor& means,
                                               const torch::Tensor& quats, double extent) const;
  // view v's recorded camera as its corrected band camera.
  core::Camera corrected(int view, const core::Camera& camera, double extent) const;
  // The offset o of each camera (scene extents, [C, 3]).
  torch::Tensor offsets(double extent) const;
  // weight x (|r|^2 + |o|^2) summed over the cameras (r in radians, o in
  // scene extents): [].
  torch::Tensor pull(double weight, double extent) const;
  // The corrections by rig camera index, offsets in scene units.
  std::map<int, io::RigCorrection> corrections(double extent) const;
  // Starts from `start` (corrections() of an earlier run, as its
  // rig_corrections.json holds them): corrections() then gives them back.
  // Cameras `start` leaves out keep theirs; core::Error naming `source` for
  // a camera that is not one of this rig's band cameras.
  void start_from(const std::map<int, io::RigCorrection>& start, double extent,
                  const std::filesystem::path& source);
  // Writes them to `file` (io::write_rig_corrections, which eval, render
  // and report apply to the views), logs one line per camera and returns
  // them as io::rig_corrections_json does.
  nlohmann::json report(const io::Scene& scene, double extent,
                        const std::filesystem::path& file) const;

  torch::Tensor rotation;  // [C, 3] radians, reference camera's axes
  torch::Tensor offset;    // [C, 3] o', scene extents, reference camera's axes
  double pivot_depth() const { return pivot_depth_; }

 private:
  std::vector<int> cameras_;      // rig index of each row
  std::vector<core::Mat3> turn_;  // factory turn of each row
  std::vector<int> row_;          // by view; -1: not corrected
  double pivot_depth_ = 0;        // scene units

  // Row `row`'s offset o given its turn D ([3, 3]): [3], scene extents.
  torch::Tensor offset_of(int64_t row, const torch::Tensor& d, double extent) const;
};
TORCH_MODULE(RigRefinement);

// The depth the reference camera looks at (scene units): over `views` (the
// reference camera's), the median of each view's median depth of the
// scene's points inside its image; scene_extent of the views where no
// point is seen.
double rig_pivot_depth(const io::Scene& scene, const std::vector<int>& views);

}  // namespace ddhgs::train
