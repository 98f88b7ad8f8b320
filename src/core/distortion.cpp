#include "core/distortion.h"

#include <cmath>

#include "core/error.h"

namespace ddhgs::core {
namespace {

// 2x2 Jacobian of distort, row-major: d(x_d, y_d) / d(x, y).
struct Jacobian {
  double xx = 1, xy = 0, yx = 0, yy = 1;
  double determinant() const { return xx * yy - xy * yx; }
};

// Fisheye: theta_d(theta) and its derivative.
double fisheye_theta_d(const Intrinsics& k, double theta) {
  double t2 = theta * theta;
  return theta * (1 + t2 * (k.k1 + t2 * (k.k2 + t2 * (k.k3 + t2 * k.k4))));
}
double fisheye_theta_d_slope(const Intrinsics& k, double theta) {
  double t2 = theta * theta;
  return 1 + t2 * (3 * k.k1 + t2 * (5 * k.k2 + t2 * (7 * k.k3 + t2 * 9 * k.k4)));
}

// OpenCV: the radial factor R(r^2).
double opencv_radial(const Intrinsics& k, double r2) {
  return 1 + r2 * (k.k1 + r2 * (k.k2 + r2 * (k.k3 + r2 * k.k4)));
}

Jacobian opencv_jacobian(const Intrinsics& k, Point2 p) {
  const double x = p.x, y = p.y, r2 = x * x + y * y;
  const double radial = opencv_radial(k, r2);
  const double slope = k.k1 + r2 * (2 * k.k2 + r2 * (3 * k.k3 + r2 * 4 * k.k4));  // d R / d r^2
  Jacobian j;
  j.xx = radial + 2 * x * x * slope + 2 * k.p1 * y + 6 * k.p2 * x;
  j.xy = 2 * x * y * slope + 2 * k.p1 * x + 2 * k.p2 * y;
  j.yx = 2 * x * y * slope + 2 * k.p1 * x + 2 * k.p2 * y;
  j.yy = radial + 2 * y * y * slope + 6 * k.p1 * y + 2 * k.p2 * x;
  return j;
}

Jacobian fisheye_jacobian(const Intrinsics& k, Point2 p) {
  const double r = std::hypot(p.x, p.y);
  if (r < 1e-12) return {};
  const double theta = std::atan(r);
  const double s = fisheye_theta_d(k, theta) / r;  // x_d = x s(r)
  // d s / d r, with d theta / d r = 1 / (1 + r^2).
  const double ds = (fisheye_theta_d_slope(k, theta) / (1 + r * r) - s) / r;
  Jacobian j;
  j.xx = s + ds * p.x * p.x / r;
  j.xy = ds * p.x * p.y / r;
  j.yx = j.xy;
  j.yy = s + ds * p.y * p.y / r;
  return j;
}

Jacobian jacobian(const Intrinsics& k, Point2 p) {
  return k.fisheye ? fisheye_jacobian(k, p) : opencv_jacobian(k, p);
}

// Where the model is locally invertible and keeps the image upright:
// positive determinant and trace (a radial model's eigenvalues are R and
// d(r R)/dr; beyond the fold both can turn negative, the determinant not).
bool keeps_orientation(const Jacobian& j) {
  return j.determinant() > 0 && j.xx + j.yy > 0;
}
bool keeps_orientation(const std::array<double, 4>& j) {
  return keeps_orientation(Jacobian{j[0], j[1], j[2], j[3]});
}

[[noreturn]] void no_inverse(Point2 distorted) {
  throw Error("lens model: the distorted point (" + std::to_string(distorted.x) + ", " +
              std::to_string(distorted.y) +
              ") has no undistorted ray (beyond the model's fold or 90 degrees off axis)");
}

Point2 undistort_fisheye(const Intrinsics& k, Point2 distorted) {
  const double theta_d = std::hypot(distorted.x, distorted.y);
  if (theta_d < 1e-15) return distorted;
  const double half_pi = 1.57079632679489661923;
  double theta = theta_d;
  for (int i = 0; i < 100; ++i) {
    double slope = fisheye_theta_d_slope(k, theta);
    if (!(slope > 0)) no_inverse(distorted);
    double step = (fisheye_theta_d(k, theta) - theta_d) / slope;
    theta -= step;
    if (std::abs(step) < 1e-15) break;
  }
  if (!(theta > 0 && theta < half_pi) ||
      std::abs(fisheye_theta_d(k, theta) - theta_d) > 1e-12 * (1 + theta_d))
    no_inverse(distorted);
  const double scale = std::tan(theta) / theta_d;
  return {distorted.x * scale, distorted.y * scale};
}

Point2 undistort_opencv(const Intrinsics& k, Point2 distorted) {
  Point2 p = distorted;
  for (int i = 0; i < 100; ++i) {
    Point2 d = distort(k, p);
    double ex = d.x - distorted.x, ey = d.y - distorted.y;
    Jacobian j = opencv_jacobian(k, p);
    double det = j.determinant();
    if (!(std::abs(det) > 1e-300)) no_inverse(distorted);
    double step_x = (j.yy * ex - j.xy * ey) / det;
    double step_y = (-j.yx * ex + j.xx * ey) / det;
    p.x -= step_x;
    p.y -= step_y;
    if (std::abs(step_x) + std::abs(step_y) < 1e-15) break;
  }
  Point2 d = distort(k, p);
  double tolerance = 1e-12 * (1 + std::abs(distorted.x) + std::abs(distorted.y));
  if (!(std::abs(d.x - distorted.x) <= tolerance && std::abs(d.y - distorted.y) <= tolerance) ||
      !keeps_orientation(opencv_jacobian(k, p)))
    no_inverse(distorted);
  return p;
}

// Whether every output pixel centre on the border of a pinhole frame with
// focal lengths scaled by `scale` maps inside the source frame's outermost
// pixel centres, where the model keeps its orientation. The border suffices:
// radial models are monotonic up to their fold, which starts at the largest
// radius, and the frame's interior maps inside its border's image.
bool covers_source(const Intrinsics& lens, double scale) {
  const double eps = 1e-9;
  auto maps_inside = [&](double u, double v) {
    Point2 n{(u - lens.cx) / (scale * lens.fx), (v - lens.cy) / (scale * lens.fy)};
    if (!keeps_orientation(distortion_jacobian(lens, n))) return false;
    Point2 d = distort(lens, n);
    double x = lens.fx * d.x + lens.cx, y = lens.fy * d.y + lens.cy;
    return x >= 0.5 - eps && x <= lens.width - 0.5 + eps && y >= 0.5 - eps &&
           y <= lens.height - 0.5 + eps;
  };
  for (int i = 0; i < lens.width; ++i)
    if (!maps_inside(i + 0.5, 0.5) || !maps_inside(i + 0.5, lens.height - 0.5)) return false;
  for (int j = 0; j < lens.height; ++j)
    if (!maps_inside(0.5, j + 0.5) || !maps_inside(lens.width - 0.5, j + 0.5)) return false;
  return true;
}

}  // namespace

Point2 distort(const Intrinsics& k, Point2 p) {
  if (k.fisheye) {
    const double r = std::hypot(p.x, p.y);
    if (r < 1e-15) return p;
    const double s = fisheye_theta_d(k, std::atan(r)) / r;
    return {p.x * s, p.y * s};
  }
  const double x = p.x, y = p.y, r2 = x * x + y * y;
  const double radial = opencv_radial(k, r2);
  return {x * radial + 2 * k.p1 * x * y + k.p2 * (r2 + 2 * x * x),
          y * radial + k.p1 * (r2 + 2 * y * y) + 2 * k.p2 * x * y};
}

std::array<double, 4> distortion_jacobian(const Intrinsics& lens, Point2 undistorted) {
  Jacobian j = jacobian(lens, undistorted);
  return {j.xx, j.xy, j.yx, j.yy};
}

Point2 undistort(const Intrinsics& lens, Point2 distorted) {
  if (!lens.has_distortion()) return distorted;
  return lens.fisheye ? undistort_fisheye(lens, distorted) : undistort_opencv(lens, distorted);
}

Intrinsics undistorted_pinhole(const Intrinsics& lens) {
  if (!lens.has_distortion()) return lens;
  require(lens.width >= 2 && lens.height >= 2 && lens.fx > 0 && lens.fy > 0,
          "lens model: expected at least 2x2 pixels and positive focal lengths");
  require(
      lens.cx > 0.5 && lens.cx < lens.width - 0.5 && lens.cy > 0.5 && lens.cy < lens.height - 0.5,
      "lens model: the principal point (" + std::to_string(lens.cx) + ", " +
          std::to_string(lens.cy) + ") lies outside the image");
  double lo = std::log(1.0 / 16), hi = std::log(16.0);  // log of the focal scale
  if (!covers_source(lens, std::exp(hi)))
    throw Error("lens model: the distortion (k1 " + std::to_string(lens.k1) + ", k2 " +
                std::to_string(lens.k2) + ", ...) folds even the centre of the " +
                std::to_string(lens.width) + "x" + std::to_string(lens.height) +
                " image over; no pinhole view of it can be made");
  if (covers_source(lens, std::exp(lo))) {
    hi = lo;
  } else {
    // Bisection on the boundary between scales that leave blank pixels (lo)
    // and scales that do not (hi); 40 halvings of log(256) reach 5e-12.
    for (int i = 0; i < 40; ++i) {
      double mid = 0.5 * (lo + hi);
      (covers_source(lens, std::exp(mid)) ? hi : lo) = mid;
    }
  }
  Intrinsics out;
  out.width = lens.width;
  out.height = lens.height;
  out.cx = lens.cx;
  out.cy = lens.cy;
  out.fx = lens.fx * std::exp(hi);
  out.fy = lens.fy * std::exp(hi);
  return out;
}

}  // namespace ddhgs::core
