#include "train/rig_refinement.h"

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "model/densify.h"
#include "model/rigid_motion.h"

namespace ddhgs::train {

namespace {

torch::Tensor mat_tensor(const core::Mat3& m, const torch::TensorOptions& options) {
  return torch::tensor(std::vector<double>(m.m.begin(), m.m.end()), torch::kFloat64)
      .view({3, 3})
      .to(options);
}

core::Vec3 vec_of(const torch::Tensor& t) {  // [3]
  const torch::Tensor d = t.detach().to(torch::kFloat64).contiguous();
  const double* p = d.data_ptr<double>();
  return {p[0], p[1], p[2]};
}

}  // namespace

RigRefinementImpl::RigRefinementImpl(const io::Scene& scene) {
  core::require(scene.rig.has_value(), scene.root,
                "is not a rig scene (transforms.json has no \"rig\"); camera_refinement.rig "
                "needs one, as `ddhgs process --rig` writes it");
  const io::TransformsRig& rig = *scene.rig;
  for (const io::RigCameraInfo& c : rig.cameras)
    if (c.index != rig.reference_camera) {
      cameras_.push_back(c.index);
      turn_.push_back(rig.turn(c.index));
    }
  core::require(!cameras_.empty(), scene.root, "the rig has no band camera besides the reference");
  row_.assign(scene.views.size(), -1);
  for (size_t v = 0; v < scene.views.size(); ++v)
    for (size_t r = 0; r < cameras_.size(); ++r)
      if (scene.views[v].rig_camera == cameras_[r]) row_[v] = int(r);
  const int64_t rows = int64_t(cameras_.size());
  rotation = register_parameter("rotation", torch::zeros({rows, 3}));
  offset = register_parameter("offset", torch::zeros({rows, 3}));
}

std::pair<torch::Tensor, torch::Tensor> RigRefinementImpl::move(int view,
                                                                const core::Camera& camera,
                                                                const torch::Tensor& means,
                                                                const torch::Tensor& quats,
                                                                double extent) const {
  const int row = row_[size_t(view)];
  if (row < 0) return {means, quats};
  // M: the reference camera's axes in the world.
  const torch::Tensor m = mat_tensor(
      camera.world_to_camera.rotation().transposed() * turn_[size_t(row)], rotation.options());
  const torch::Tensor r = rotation[row];
  const torch::Tensor d = model::quat_to_matrix(model::rotation_vector_quat(r).unsqueeze(0))[0];
  const torch::Tensor shift = -torch::matmul(m, torch::matmul(d, offset[row])) * extent;
  return model::move_rigidly(means, quats, torch::matmul(m, r), shift, camera.center());
}

core::Camera RigRefinementImpl::corrected(int view, const core::Camera& camera,
                                          double extent) const {
  const int row = row_[size_t(view)];
  if (row < 0) return camera;
  return io::corrected_band_camera(camera, turn_[size_t(row)],
                                   {vec_of(rotation[row]), vec_of(offset[row]) * extent});
}

torch::Tensor RigRefinementImpl::pull(double weight) const {
  return weight * (rotation.pow(2).sum() + offset.pow(2).sum());
}

std::map<int, io::RigCorrection> RigRefinementImpl::corrections(double extent) const {
  std::map<int, io::RigCorrection> out;
  for (size_t r = 0; r < cameras_.size(); ++r)
    out[cameras_[r]] = {vec_of(rotation[int64_t(r)]), vec_of(offset[int64_t(r)]) * extent};
  return out;
}

nlohmann::json RigRefinementImpl::report(const io::Scene& scene, double extent,
                                         const std::filesystem::path& file) const {
  const std::map<int, io::RigCorrection> found = corrections(extent);
  io::write_rig_corrections(file, *scene.rig, found);
  for (const auto& [index, c] : found)
    core::log_info("rig " + io::describe_rig_correction(*scene.rig, index, c));
  return io::rig_corrections_json(*scene.rig, found);
}

}  // namespace ddhgs::train
