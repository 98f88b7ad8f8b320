// The ground a flight was flown over, for cutting it into blocks: its plane
// and axes, and what each camera sees of it.
#pragma once
#include <array>
#include <vector>

#include "core/camera.h"
#include "core/tensor.h"
#include "io/blocks/block_grid.h"

namespace ddhgs::io {

// Principal axes of points: eigenvalues ascending and their unit
// eigenvectors (the covariance's), by Jacobi rotations. Fewer than two
// points: zero eigenvalues and the world axes.
struct PrincipalAxes {
  std::array<double, 3> values{};
  std::array<core::Vec3, 3> vectors{core::Vec3{1, 0, 0}, core::Vec3{0, 1, 0}, core::Vec3{0, 0, 1}};
  core::Vec3 mean;
};
PrincipalAxes principal_axes(const std::vector<core::Vec3>& points);

// The ground frame of a flight. The normal is the points' dominant plane's
// (their least principal axis, when the points are flat: least variance
// under a quarter of the middle one), else the camera centres' best-fit
// plane's (when they span a plane), else the cameras' mean viewing
// direction reversed; it points towards the cameras. The origin lies on
// the ground at the points' median height (the cameras' centroid without
// points); u follows the camera centres' main direction (the flight), v
// = n x u.
GroundFrame ground_frame(const std::vector<core::Vec3>& points,
                         const std::vector<core::Camera>& cameras);

// What a camera sees of the ground plane: the box around its image
// corners' rays where they meet the plane (those that meet it in front of
// the camera; with none, the camera centre's foot). with_ground false (a
// scene without points, whose ground height is unknown): the centre's foot.
GroundBox view_footprint(const GroundFrame& frame, const core::Camera& camera, bool with_ground);

// Which pixels of a window of a camera's image see the ground plane inside
// box: [height, width] bool, the window's top-left pixel at (x0, y0) of the
// image. A pixel's ray leaves through its centre (the lens's distortion
// undone) and must meet the plane in front of the camera; a camera at or
// below the plane sees none of it.
torch::Tensor ground_box_mask(const GroundFrame& frame, const GroundBox& box,
                              const core::Camera& camera, int x0, int y0, int width, int height);

}  // namespace ddhgs::io
