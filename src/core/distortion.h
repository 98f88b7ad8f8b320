// Lens distortion of core::Intrinsics on normalised image coordinates
// (x/z, y/z of a camera-frame point), and the pinhole camera that a view is
// undistorted to. The definitions are OpenCV's and COLMAP's, so their
// coefficients apply as stored:
//
// OpenCV (Brown-Conrady), r^2 = x^2 + y^2,
// R = 1 + k1 r^2 + k2 r^4 + k3 r^6 + k4 r^8 (k4: nerfstudio's term, 0 in OpenCV):
//   x_d = x R + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y R + p1 (r^2 + 2 y^2) + 2 p2 x y
// Fisheye (equidistant), theta = atan(r):
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//   (x_d, y_d) = (x, y) theta_d / r
// A pixel is then (fx x_d + cx, fy y_d + cy), pixel centres at +0.5.
#pragma once
#include <array>

#include "core/camera.h"

namespace ddhgs::core {

struct Point2 {
  double x = 0, y = 0;
};

// Undistorted normalised coordinates -> distorted ones (the forward model).
Point2 distort(const Intrinsics& lens, Point2 undistorted);

// d(x_d, y_d) / d(x, y) of distort at a point, row-major {xx, xy, yx, yy}.
std::array<double, 4> distortion_jacobian(const Intrinsics& lens, Point2 undistorted);

// The inverse of distort, by Newton's method (the models have no closed-form
// inverse): within 1e-12 where the model is invertible. core::Error when it
// does not converge (a point beyond the fold of a strongly distorting model,
// or a fisheye point at 90 degrees or more from the axis).
Point2 undistort(const Intrinsics& lens, Point2 distorted);

// The pinhole camera a distorted view is resampled to: the same size and
// principal point, and the focal lengths scaled by one factor, the smallest
// (widest view) for which every output pixel centre maps inside the source
// frame's outermost pixel centres without the model folding over. So an
// undistorted view has no blank pixels; the frame is cropped instead: for
// barrel distortion (k1 < 0) the focal lengths shrink, and the source pixels
// beyond the tightest edge or corner are not used; for pincushion (k1 > 0)
// they grow. lens itself when it has no distortion; core::Error when no
// factor in [1/16, 16] works.
Intrinsics undistorted_pinhole(const Intrinsics& lens);

}  // namespace ddhgs::core
