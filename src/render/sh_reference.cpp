#include "render/sh_reference.h"

#include "render/sh.h"

namespace ddhgs::render {

torch::Tensor sh_basis_reference(const torch::Tensor& dirs, int degree) {
  using namespace sh_constants;
  auto x = dirs.select(1, 0), y = dirs.select(1, 1), z = dirs.select(1, 2);
  std::vector<torch::Tensor> Y{torch::full_like(x, C0)};
  if (degree >= 1) {
    Y.insert(Y.end(), {-C1 * y, C1 * z, -C1 * x});
  }
  auto xx = x * x, yy = y * y, zz = z * z;
  if (degree >= 2) {
    Y.insert(Y.end(), {C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * zz - xx - yy), C2[3] * x * z,
                       C2[4] * (xx - yy)});
  }
  if (degree >= 3) {
    Y.insert(Y.end(), {C3[0] * y * (3 * xx - yy), C3[1] * x * y * z, C3[2] * y * (4 * zz - xx - yy),
                       C3[3] * z * (2 * zz - 3 * xx - 3 * yy), C3[4] * x * (4 * zz - xx - yy),
                       C3[5] * z * (xx - yy), C3[6] * x * (xx - 3 * yy)});
  }
  return torch::stack(Y, 1);
}

torch::Tensor eval_sh_reference(const torch::Tensor& sh_dc, const torch::Tensor& sh_rest,
                                const torch::Tensor& means, const torch::Tensor& camera_center,
                                int degree, const torch::Tensor& band_offsets, bool linear) {
  const int64_t K = sh_coeff_count(degree);
  auto offsets = means - camera_center.reshape({1, 3});
  auto dirs = offsets / offsets.norm(2, 1, true);
  auto basis = sh_basis_reference(dirs, degree);  // [G, K]
  auto coeffs = sh_dc.unsqueeze(2);               // [G, N, K]
  if (K > 1) coeffs = torch::cat({coeffs, sh_rest.slice(2, 0, K - 1)}, 2);
  if (band_offsets.defined()) coeffs = coeffs + band_offsets.slice(1, 0, K).unsqueeze(0);
  auto value = (coeffs * basis.unsqueeze(1)).sum(2);
  return linear ? value : (value + 0.5).clamp_min(0.0);
}

}  // namespace ddhgs::render
