#include "io/splat/splat.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "core/error.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace {

constexpr double kShC0 = 0.28209479177387814;  // Y_0^0 of 3DGS

uint8_t unit_to_byte(double value) {
  return uint8_t(std::lround(std::clamp(value, 0.0, 1.0) * 255.0));
}

uint8_t quat_to_byte(double component) {
  return uint8_t(std::clamp<long>(std::lround(component * 128.0 + 128.0), 0, 255));
}

}  // namespace

void write_splat(const std::filesystem::path& path, const GaussianPly& ply) {
  core::require(
      ply.means.defined() && ply.sh_dc.defined() && ply.sh_dc.dim() == 2 && ply.sh_dc.size(1) == 3,
      path, "cannot write .splat: the model must have three colour channels");
  const int64_t G = ply.means.size(0);
  auto means = ply.means.to(torch::kFloat32).contiguous();
  auto log_scales = ply.log_scales.to(torch::kFloat64).contiguous();
  auto quats = ply.quats.to(torch::kFloat64).contiguous();
  auto opacity = torch::sigmoid(ply.logit_opacities.reshape({G}).to(torch::kFloat64)).contiguous();
  auto colour = (ply.sh_dc.to(torch::kFloat64) * kShC0 + 0.5).contiguous();
  auto importance = -(log_scales.sum(1).exp() * opacity);
  auto order = std::get<1>(importance.sort(/*stable=*/true, /*dim=*/0, /*descending=*/false));

  std::string bytes(size_t(G * kSplatRecordBytes), '\0');
  auto m = means.accessor<float, 2>();
  auto s = log_scales.accessor<double, 2>();
  auto q = quats.accessor<double, 2>();
  auto a = opacity.accessor<double, 1>();
  auto c = colour.accessor<double, 2>();
  auto o = order.accessor<int64_t, 1>();
  for (int64_t r = 0; r < G; ++r) {
    const int64_t g = o[r];
    char* record = bytes.data() + r * kSplatRecordBytes;
    float floats[6] = {m[g][0],
                       m[g][1],
                       m[g][2],
                       float(std::exp(s[g][0])),
                       float(std::exp(s[g][1])),
                       float(std::exp(s[g][2]))};
    std::memcpy(record, floats, sizeof floats);
    uint8_t* tail = reinterpret_cast<uint8_t*>(record + sizeof floats);
    for (int j = 0; j < 3; ++j) tail[j] = unit_to_byte(c[g][j]);
    tail[3] = unit_to_byte(a[g]);
    const double norm =
        std::sqrt(q[g][0] * q[g][0] + q[g][1] * q[g][1] + q[g][2] * q[g][2] + q[g][3] * q[g][3]);
    core::require(norm > 0 && std::isfinite(norm), path,
                  "cannot write .splat: Gaussian " + std::to_string(g) + " has a zero rotation");
    for (int j = 0; j < 4; ++j) tail[4 + j] = quat_to_byte(q[g][j] / norm);
  }
  write_file_atomically(path, bytes);
}

}  // namespace ddhgs::io
