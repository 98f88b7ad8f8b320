#include "train/rig_refinement.h"

#include <nlohmann/json.hpp>

#include <algorithm>

#include "core/error.h"
#include "core/log.h"
#include "model/densify.h"
#include "model/rigid_motion.h"
#include "train/init.h"

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

RigRefinementImpl::RigRefinementImpl(const io::Scene& scene, double pivot_depth)
    : pivot_depth_(pivot_depth) {
  core::require(pivot_depth >= 0, scene.root, "rig refinement: the pivot depth must be >= 0");
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
  const torch::Tensor o = offset_of(row, d, extent);
  const torch::Tensor shift = -torch::matmul(m, torch::matmul(d, o)) * extent;
  return model::move_rigidly(means, quats, torch::matmul(m, r), shift, camera.center());
}

torch::Tensor RigRefinementImpl::offset_of(int64_t row, const torch::Tensor& d,
                                           double extent) const {
  if (pivot_depth_ <= 0) return offset[row];
  // (I - D^T) p with p = (0, 0, depth): depth (e_z - D's third row).
  const torch::Tensor e_z = torch::tensor({0.0, 0.0, 1.0}, rotation.options());
  return offset[row] + (e_z - d[2]) * (pivot_depth_ / extent);
}

torch::Tensor RigRefinementImpl::offsets(double extent) const {
  if (pivot_depth_ <= 0) return offset;
  std::vector<torch::Tensor> rows;
  for (int64_t r = 0; r < rotation.size(0); ++r)
    rows.push_back(offset_of(
        r, model::quat_to_matrix(model::rotation_vector_quat(rotation[r]).unsqueeze(0))[0],
        extent));
  return torch::stack(rows);
}

core::Camera RigRefinementImpl::corrected(int view, const core::Camera& camera,
                                          double extent) const {
  const int row = row_[size_t(view)];
  if (row < 0) return camera;
  return io::corrected_band_camera(camera, turn_[size_t(row)],
                                   {vec_of(rotation[row]), vec_of(offsets(extent)[row]) * extent});
}

torch::Tensor RigRefinementImpl::pull(double weight, double extent) const {
  return weight * (rotation.pow(2).sum() + offsets(extent).pow(2).sum());
}

std::map<int, io::RigCorrection> RigRefinementImpl::corrections(double extent) const {
  std::map<int, io::RigCorrection> out;
  const torch::Tensor o = offsets(extent);
  for (size_t r = 0; r < cameras_.size(); ++r)
    out[cameras_[r]] = {vec_of(rotation[int64_t(r)]), vec_of(o[int64_t(r)]) * extent};
  return out;
}

void RigRefinementImpl::start_from(const std::map<int, io::RigCorrection>& start, double extent,
                                   const std::filesystem::path& source) {
  torch::NoGradGuard no_grad;
  for (const auto& [index, c] : start) {
    const auto at = std::find(cameras_.begin(), cameras_.end(), index);
    core::require(at != cameras_.end(), source,
                  "has a correction for rig camera " + std::to_string(index) +
                      ", which is not one of this rig's band cameras");
    const int64_t row = int64_t(at - cameras_.begin());
    const core::Vec3 r = c.rotation_rad, o = c.offset;
    rotation[row].copy_(torch::tensor({r.x, r.y, r.z}, torch::kFloat64));
    // offset_of() adds the pivot's part to the learned o': take it away.
    offset[row].zero_();
    const torch::Tensor d =
        model::quat_to_matrix(model::rotation_vector_quat(rotation[row]).unsqueeze(0))[0];
    const torch::Tensor pivot_part = offset_of(row, d, extent);
    offset[row].copy_(torch::tensor({o.x, o.y, o.z}, torch::kFloat64) / extent - pivot_part);
  }
}

nlohmann::json RigRefinementImpl::report(const io::Scene& scene, double extent,
                                         const std::filesystem::path& file) const {
  const std::map<int, io::RigCorrection> found = corrections(extent);
  io::write_rig_corrections(file, *scene.rig, found);
  for (const auto& [index, c] : found)
    core::log_info("rig " + io::describe_rig_correction(*scene.rig, index, c));
  return io::rig_corrections_json(*scene.rig, found);
}

double rig_pivot_depth(const io::Scene& scene, const std::vector<int>& views) {
  std::vector<double> medians;
  const torch::Tensor xyz = scene.points.xyz.defined()
                                ? scene.points.xyz.to(torch::kFloat64).contiguous()
                                : torch::zeros({0, 3}, torch::kFloat64);
  const double* p = xyz.data_ptr<double>();
  for (int v : views) {
    const core::Camera& camera = scene.views[size_t(v)].camera;
    const core::Intrinsics& k = camera.intrinsics;
    std::vector<double> depths;
    for (int64_t i = 0; i < xyz.size(0); ++i) {
      const core::Vec3 x =
          camera.world_to_camera.transform_point({p[3 * i], p[3 * i + 1], p[3 * i + 2]});
      if (x.z <= 0) continue;
      const double u = k.fx * x.x / x.z + k.cx, w = k.fy * x.y / x.z + k.cy;
      if (u >= 0 && u < k.width && w >= 0 && w < k.height) depths.push_back(x.z);
    }
    if (depths.empty()) continue;
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    medians.push_back(depths[depths.size() / 2]);
  }
  if (medians.empty()) return scene_extent(scene, views);
  std::nth_element(medians.begin(), medians.begin() + medians.size() / 2, medians.end());
  return medians[medians.size() / 2];
}

}  // namespace ddhgs::train
