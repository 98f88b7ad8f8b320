#include "eval/orbit.h"

#include "core/tensor.h"

#include <torch/linalg.h>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace ddhgs::eval {
namespace {

using core::Vec3;

torch::Tensor to_tensor(const Vec3& v) {
  return torch::tensor({v.x, v.y, v.z}, torch::kDouble);
}
Vec3 to_vec(const torch::Tensor& t) {
  torch::Tensor c = t.contiguous();
  auto a = c.accessor<double, 1>();
  return {a[0], a[1], a[2]};
}

// Image "up" of a camera in world coordinates: minus its y axis (OpenCV y down).
Vec3 camera_up(const core::Camera& camera) {
  const core::Mat4& w2c = camera.world_to_camera;
  return Vec3{-w2c(1, 0), -w2c(1, 1), -w2c(1, 2)};
}

// Least-squares point nearest to every optical axis; when the axes are
// (nearly) parallel there is none, and the point one mean camera distance
// ahead of the centroid is used instead.
Vec3 nearest_to_axes(const std::vector<core::Camera>& cameras, const Vec3& centroid) {
  torch::Tensor a = torch::zeros({3, 3}, torch::kDouble), b = torch::zeros({3}, torch::kDouble);
  Vec3 mean_forward;
  for (const core::Camera& cam : cameras) {
    torch::Tensor d = to_tensor(cam.forward());
    torch::Tensor p = torch::eye(3, torch::kDouble) - torch::outer(d, d);
    a += p;
    b += p.matmul(to_tensor(cam.center()));
    mean_forward = mean_forward + cam.forward();
  }
  torch::Tensor eig = torch::linalg_eigvalsh(a);
  if (eig[0].item<double>() > 1e-3 * double(cameras.size()))
    return to_vec(torch::linalg_solve(a, b));
  double spread = 0;
  for (const core::Camera& cam : cameras) spread += (cam.center() - centroid).norm();
  spread = spread > 0 ? spread / double(cameras.size()) : 1.0;
  return centroid + mean_forward.normalized() * spread;
}

// Least-squares Fourier series of `values` over `angles` (order <= 2, lowered
// when there are too few samples to fit it).
std::vector<double> fit_series(const std::vector<double>& angles,
                               const std::vector<double>& values) {
  int order = angles.size() >= 9 ? 2 : angles.size() >= 5 ? 1 : 0;
  int terms = 1 + 2 * order;
  int64_t n = int64_t(angles.size());
  torch::Tensor design = torch::ones({n, terms}, torch::kDouble);
  for (int64_t i = 0; i < n; ++i)
    for (int k = 1; k <= order; ++k) {
      design[i][2 * k - 1] = std::cos(k * angles[size_t(i)]);
      design[i][2 * k] = std::sin(k * angles[size_t(i)]);
    }
  torch::Tensor y = torch::tensor(values, torch::kDouble).unsqueeze(1);
  // Ridge-regularised normal equations: stable for clustered angles too.
  torch::Tensor gram = design.t().matmul(design) + 1e-6 * torch::eye(terms, torch::kDouble);
  torch::Tensor coeffs = torch::linalg_solve(gram, design.t().matmul(y)).squeeze(1);
  return std::vector<double>(coeffs.data_ptr<double>(), coeffs.data_ptr<double>() + terms);
}

double eval_series(const std::vector<double>& c, double theta) {
  double v = c[0];
  for (size_t k = 1; 2 * k < c.size() + 1; ++k)
    v += c[2 * k - 1] * std::cos(double(k) * theta) + c[2 * k] * std::sin(double(k) * theta);
  return v;
}

}  // namespace

double OrbitFit::radius_at(double theta) const {
  double inv_sq = eval_series(inv_sq_radius_coeffs, theta);
  return inv_sq > 0 ? std::clamp(1.0 / std::sqrt(inv_sq), radius_min, radius_max) : radius_max;
}
double OrbitFit::height_at(double theta) const {
  return std::clamp(eval_series(height_coeffs, theta), height_min, height_max);
}

OrbitFit fit_orbit(const std::vector<core::Camera>& cameras) {
  core::require(!cameras.empty(), "orbit: the scene has no training cameras to fit an orbit to");
  OrbitFit fit;
  Vec3 centroid, mean_up;
  for (const core::Camera& cam : cameras) {
    centroid = centroid + cam.center();
    mean_up = mean_up + camera_up(cam);
  }
  centroid = centroid * (1.0 / double(cameras.size()));
  mean_up = mean_up.normalized();

  // Plane normal: the direction in which the centres vary least, when they
  // spread in a plane (a ring); otherwise the cameras' mean image up.
  torch::Tensor cov = torch::zeros({3, 3}, torch::kDouble);
  for (const core::Camera& cam : cameras) {
    torch::Tensor d = to_tensor(cam.center() - centroid);
    cov += torch::outer(d, d);
  }
  auto [eigvals, eigvecs] = torch::linalg_eigh(cov);
  Vec3 normal = to_vec(eigvecs.select(1, 0));
  bool planar =
      eigvals[1].item<double>() > 1e-6 && eigvals[1].item<double>() > 4 * eigvals[0].item<double>();
  if (normal.dot(mean_up) < 0) normal = normal * -1.0;
  fit.up = planar && normal.dot(mean_up) > 0.5 ? normal : mean_up;

  fit.target = nearest_to_axes(cameras, centroid);
  fit.centre = fit.target + fit.up * (centroid - fit.target).dot(fit.up);
  Vec3 first = cameras.front().center() - fit.centre;
  Vec3 in_plane = first - fit.up * first.dot(fit.up);
  if (in_plane.norm() < 1e-9) in_plane = fit.up.cross(Vec3{1, 0, 0}).cross(fit.up);
  if (in_plane.norm() < 1e-9) in_plane = fit.up.cross(Vec3{0, 1, 0}).cross(fit.up);
  fit.axis_u = in_plane.normalized();
  fit.axis_v = fit.up.cross(fit.axis_u);

  std::vector<double> angles, radii, inv_sq_radii, heights;
  for (const core::Camera& cam : cameras) {
    Vec3 d = cam.center() - fit.centre;
    double u = d.dot(fit.axis_u), v = d.dot(fit.axis_v);
    angles.push_back(std::atan2(v, u));
    radii.push_back(std::hypot(u, v));
    inv_sq_radii.push_back(1.0 / std::max(u * u + v * v, 1e-12));
    heights.push_back(d.dot(fit.up));
  }
  fit.inv_sq_radius_coeffs = fit_series(angles, inv_sq_radii);
  fit.height_coeffs = fit_series(angles, heights);
  fit.radius_min = *std::min_element(radii.begin(), radii.end());
  fit.radius_max = *std::max_element(radii.begin(), radii.end());
  fit.height_min = *std::min_element(heights.begin(), heights.end());
  fit.height_max = *std::max_element(heights.begin(), heights.end());
  return fit;
}

std::vector<core::Camera> orbit_cameras(const std::vector<core::Camera>& cameras, int frames) {
  core::require(frames > 0, "--orbit: expected a positive number of frames");
  OrbitFit fit = fit_orbit(cameras);
  std::vector<core::Camera> path;
  for (int i = 0; i < frames; ++i) {
    double theta = 2 * M_PI * double(i) / double(frames);
    Vec3 eye = fit.centre + fit.axis_u * (fit.radius_at(theta) * std::cos(theta)) +
               fit.axis_v * (fit.radius_at(theta) * std::sin(theta)) +
               fit.up * fit.height_at(theta);
    core::Camera cam;
    cam.intrinsics = cameras.front().intrinsics;
    cam.world_to_camera = core::look_at(eye, fit.target, fit.up);
    path.push_back(cam);
  }
  return path;
}

}  // namespace ddhgs::eval
