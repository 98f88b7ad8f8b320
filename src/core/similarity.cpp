#include "core/similarity.h"

#include "core/tensor.h"

#include <torch/linalg.h>
#include <cmath>

#include "core/error.h"

namespace ddhgs::core {
namespace {

Vec3 centroid(const std::vector<Vec3>& points) {
  Vec3 sum;
  for (const Vec3& p : points) sum = sum + p;
  return sum * (1.0 / double(points.size()));
}

Mat3 to_mat3(const torch::Tensor& m) {  // double [3, 3]
  auto a = m.accessor<double, 2>();
  Mat3 out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out(i, j) = a[i][j];
  return out;
}

}  // namespace

Similarity fit_similarity(const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
  require(from.size() == to.size() && from.size() >= 3,
          "similarity fit: expected at least 3 matched point pairs, got " +
              std::to_string(std::min(from.size(), to.size())));
  const Vec3 mean_from = centroid(from), mean_to = centroid(to);
  // Cross-covariance sum (to - mean_to)(from - mean_from)^T / n and the
  // variance of `from`.
  torch::Tensor cov = torch::zeros({3, 3}, torch::kFloat64);
  auto c = cov.accessor<double, 2>();
  double var_from = 0;
  for (size_t i = 0; i < from.size(); ++i) {
    const Vec3 a = from[i] - mean_from, b = to[i] - mean_to;
    const double av[3] = {a.x, a.y, a.z}, bv[3] = {b.x, b.y, b.z};
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) c[r][k] += bv[r] * av[k] / double(from.size());
    var_from += a.dot(a) / double(from.size());
  }
  auto [u, singular, vh] = torch::linalg_svd(cov, /*full_matrices=*/true);
  auto s = singular.accessor<double, 1>();
  require(var_from > 0 && s[1] > 1e-12 * s[0],
          "similarity fit: the points lie on one line (or one point); the rotation is undefined");
  // Exclude reflections: flip the weakest direction when det(U V^T) < 0.
  const double sign = (torch::det(u) * torch::det(vh)).item<double>() < 0 ? -1.0 : 1.0;
  torch::Tensor d = torch::diag(torch::tensor({1.0, 1.0, sign}, torch::kFloat64));
  Similarity out;
  out.rotation = to_mat3(u.matmul(d).matmul(vh));
  out.scale = (s[0] + s[1] + sign * s[2]) / var_from;
  out.translation = mean_to - (out.rotation * mean_from) * out.scale;
  return out;
}

double rms_residual(const Similarity& s, const std::vector<Vec3>& from,
                    const std::vector<Vec3>& to) {
  double sum = 0;
  for (size_t i = 0; i < from.size(); ++i) {
    const Vec3 e = to[i] - s.apply(from[i]);
    sum += e.dot(e);
  }
  return from.empty() ? 0 : std::sqrt(sum / double(from.size()));
}

double rms_spread(const std::vector<Vec3>& points) {
  if (points.empty()) return 0;
  const Vec3 mean = centroid(points);
  double sum = 0;
  for (const Vec3& p : points) sum += (p - mean).dot(p - mean);
  return std::sqrt(sum / double(points.size()));
}

}  // namespace ddhgs::core
