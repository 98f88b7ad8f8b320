// Rigid motions of Gaussians (model/rigid_motion.h): the rotation-vector
// quaternion, quaternion products against matrix products, and a motion
// that must leave the centre fixed and turn every offset from it.
#include <gtest/gtest.h>

#include <cmath>

#include "model/densify.h"
#include "model/rigid_motion.h"

namespace ddhgs::model {
namespace {

torch::Tensor matrix_of(const torch::Tensor& r) {  // [3] rotation vector -> [3, 3]
  return quat_to_matrix(rotation_vector_quat(r).unsqueeze(0))[0];
}

TEST(RigidMotion, RotationVectorQuaternion) {
  EXPECT_TRUE(torch::allclose(rotation_vector_quat(torch::zeros({3})),
                              torch::tensor({1.0f, 0.0f, 0.0f, 0.0f})));
  // 90 degrees about z.
  const auto q = rotation_vector_quat(torch::tensor({0.0f, 0.0f, float(M_PI / 2)}));
  EXPECT_TRUE(
      torch::allclose(q, torch::tensor({float(M_SQRT1_2), 0.0f, 0.0f, float(M_SQRT1_2)}), 0, 1e-6));
  // Finite gradient at zero, where d q_xyz / d r = 1/2.
  auto r = torch::zeros({3}, torch::requires_grad());
  rotation_vector_quat(r)[1].backward();
  EXPECT_TRUE(torch::allclose(r.grad(), torch::tensor({0.5f, 0.0f, 0.0f}), 0, 1e-6)) << r.grad();
}

TEST(RigidMotion, QuaternionProductIsTheMatrixProduct) {
  const torch::Tensor a = torch::tensor({0.3, -0.2, 0.5}, torch::kFloat64);
  const torch::Tensor b = torch::tensor({-0.1, 0.4, 0.2}, torch::kFloat64);
  const torch::Tensor product =
      quat_multiply(rotation_vector_quat(a), rotation_vector_quat(b).unsqueeze(0));
  EXPECT_TRUE(torch::allclose(quat_to_matrix(product)[0], torch::matmul(matrix_of(a), matrix_of(b)),
                              0, 1e-12));
}

TEST(RigidMotion, TurnsAboutTheCentreThenShifts) {
  const core::Vec3 centre{1.0, -2.0, 0.5};
  const torch::Tensor r =
      torch::tensor({0.0, 0.0, M_PI / 2}, torch::kFloat64);  // 90 degrees about z
  const torch::Tensor shift = torch::tensor({0.1, 0.2, 0.3}, torch::kFloat64);
  // The centre itself, and a point one unit along x from it.
  const torch::Tensor means = torch::tensor({{1.0, -2.0, 0.5}, {2.0, -2.0, 0.5}}, torch::kFloat64);
  const torch::Tensor quats =
      torch::tensor({{1.0, 0.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}}, torch::kFloat64);
  const auto [moved, turned] = move_rigidly(means, quats, r, shift, centre);
  EXPECT_TRUE(torch::allclose(
      moved, torch::tensor({{1.1, -1.8, 0.8}, {1.1, -0.8, 0.8}}, torch::kFloat64), 0, 1e-12))
      << moved;
  EXPECT_TRUE(torch::allclose(quat_to_matrix(turned)[1], matrix_of(r), 0, 1e-12));
}

}  // namespace
}  // namespace ddhgs::model
