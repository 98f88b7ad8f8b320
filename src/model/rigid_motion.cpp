#include "model/rigid_motion.h"

#include "model/densify.h"

namespace ddhgs::model {

torch::Tensor rotation_vector_quat(const torch::Tensor& r) {
  // sqrt(|r|^2 + tiny) keeps the gradient finite at r = 0, where
  // sin(theta / 2) / theta tends to 1/2.
  const torch::Tensor theta = (r.pow(2).sum() + 1e-20).sqrt();
  return torch::cat({(0.5 * theta).cos().view({1}), r * ((0.5 * theta).sin() / theta)});
}

torch::Tensor quat_multiply(const torch::Tensor& a, const torch::Tensor& b) {
  const auto aw = a[0], ax = a[1], ay = a[2], az = a[3];
  const auto bw = b.select(1, 0), bx = b.select(1, 1), by = b.select(1, 2), bz = b.select(1, 3);
  return torch::stack(
      {aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
       aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw},
      1);
}

std::pair<torch::Tensor, torch::Tensor> move_rigidly(const torch::Tensor& means,
                                                     const torch::Tensor& quats,
                                                     const torch::Tensor& rotation,
                                                     const torch::Tensor& shift,
                                                     const core::Vec3& centre) {
  const torch::Tensor q = rotation_vector_quat(rotation);
  const torch::Tensor rot = quat_to_matrix(q.unsqueeze(0))[0];  // [3, 3]
  const torch::Tensor c =
      torch::tensor({double(centre.x), double(centre.y), double(centre.z)}, means.options());
  const torch::Tensor moved = torch::matmul(means - c, rot.t()) + (c + shift);
  return {moved, quat_multiply(q, quats)};
}

}  // namespace ddhgs::model
