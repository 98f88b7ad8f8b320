// Rigid motions of a set of Gaussians, differentiable in the motion.
//
// The rasterizer has no gradient for the camera, so a pose correction is
// applied to the Gaussians instead: turning them by R about the camera
// centre c and shifting them by d,
//   x' = R (x - c) + c + d,   q' = q(R) * q,
// is what the camera would see after the inverse motion (view-dependent
// colour is evaluated in the moved frame; a fraction of a degree does not
// change it). Training's camera refinement (train/camera_refinement.h) and
// eval's pose alignment (eval/pose_alignment.h) both use it.
#pragma once
#include "core/tensor.h"

#include <utility>

#include "core/mat.h"

namespace ddhgs::model {

// Unit quaternion (w, x, y, z) of a rotation vector r: [3] -> [4];
// differentiable at r = 0.
torch::Tensor rotation_vector_quat(const torch::Tensor& r);

// Hamilton product a * b of (w, x, y, z) quaternions: [4] x [G, 4] -> [G, 4].
torch::Tensor quat_multiply(const torch::Tensor& a, const torch::Tensor& b);

// means [G, 3] and quats [G, 4] turned by the rotation vector `rotation` [3]
// (radians, world axes) about `centre` and shifted by `shift` [3] (world
// units), as above. Differentiable in rotation, shift, means and quats.
std::pair<torch::Tensor, torch::Tensor> move_rigidly(const torch::Tensor& means,
                                                     const torch::Tensor& quats,
                                                     const torch::Tensor& rotation,
                                                     const torch::Tensor& shift,
                                                     const core::Vec3& centre);

}  // namespace ddhgs::model
