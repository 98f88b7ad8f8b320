// A smooth orbit of cameras around the scene, fitted to the training cameras,
// for fly-around renders of a trained model.
#pragma once
#include <vector>

#include "core/camera.h"

namespace ddhgs::eval {

struct OrbitFit {
  core::Vec3 target;          // point the orbit looks at: nearest to all optical axes
  core::Vec3 up;              // orbit plane normal, oriented like the cameras' image up
  core::Vec3 centre;          // target projected onto the plane of the camera centres
  core::Vec3 axis_u, axis_v;  // in-plane orthonormal axes, angle 0 along axis_u
  // 1 / radius^2 and the height above the plane (scene units) as smooth
  // functions of the angle: a0 + sum_k a_k cos(k theta) + b_k sin(k theta),
  // k <= 2. An ellipse centred on `centre` has exactly this 1 / r^2.
  std::vector<double> inv_sq_radius_coeffs, height_coeffs;
  double radius_min = 0, radius_max = 0;  // observed ranges; the fit is clamped to them
  double height_min = 0, height_max = 0;

  double radius_at(double theta_rad) const;
  double height_at(double theta_rad) const;
};

// Fits the orbit to cameras looking inward (turntable rings, hemispheres, or a
// tripod arc). Needs at least one camera; core::Error otherwise.
OrbitFit fit_orbit(const std::vector<core::Camera>& cameras);

// `frames` cameras at equal angle steps, starting at the first camera's
// angle, with its intrinsics, looking at the target with the image up along
// the orbit normal.
std::vector<core::Camera> orbit_cameras(const std::vector<core::Camera>& cameras, int frames);

}  // namespace ddhgs::eval
