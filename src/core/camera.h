// Pinhole camera model and the axis conventions of the whole project.
//
// Conventions: OpenCV camera axes (x right, y down, z forward), world-to-camera
// 4x4 rigid transforms, pixel centres at (x + 0.5, y + 0.5), distances in the
// scene's own units. Readers convert nerfstudio/OpenGL camera-to-world poses.
#pragma once
#include <string>

#include "core/mat.h"

namespace ddhgs::core {

struct Intrinsics {
  double fx = 0, fy = 0;  // focal lengths, pixels
  double cx = 0, cy = 0;  // principal point, pixels (top-left corner is 0, 0)
  int width = 0, height = 0;
  // Lens distortion of normalised image coordinates (x/z, y/z), applied
  // between the pinhole projection and the focal lengths (core/distortion.h):
  // radial k1..k4 (terms in r^2..r^8) and tangential p1 p2 (OpenCV's and
  // nerfstudio's OPENCV; COLMAP SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV
  // without its rational terms); with fisheye set, the equidistant fisheye
  // model's k1..k4 instead (OPENCV_FISHEYE, COLMAP SIMPLE_RADIAL_FISHEYE and
  // RADIAL_FISHEYE). All zero and not fisheye: a pinhole camera.
  bool fisheye = false;
  double k1 = 0, k2 = 0, k3 = 0, k4 = 0, p1 = 0, p2 = 0;
  // A camera that sees part of a larger view (a training crop,
  // train/view_crop.h): the part's corner in the view (pixels) and the
  // view's size; frame_width 0: the image is the whole view. The
  // rasterizer's Jacobian clamp follows the whole view's field of view, so
  // the part renders what the whole view renders there.
  int frame_x = 0, frame_y = 0, frame_width = 0, frame_height = 0;

  bool has_distortion() const {
    return fisheye || k1 != 0 || k2 != 0 || k3 != 0 || k4 != 0 || p1 != 0 || p2 != 0;
  }
  // Same focal lengths, principal point, size, lens and frame.
  bool operator==(const Intrinsics& o) const;
  // Intrinsics of the same camera at 1/factor resolution (area-averaged images).
  Intrinsics downscaled(int factor) const;
};

struct Camera {
  Intrinsics intrinsics;
  Mat4 world_to_camera;  // OpenCV axes

  Mat4 camera_to_world() const { return world_to_camera.rigid_inverse(); }
  Vec3 center() const { return camera_to_world().translation(); }
  // Unit viewing direction (camera +z) in world coordinates.
  Vec3 forward() const;
};

// Why a camera cannot be rendered in float32, or "" when it can: a value that
// is not finite, a focal length that is not positive or beyond 1e6 x the
// image size, a principal point more than 100 image sizes off the image, a
// camera centre more than kMaxSceneExtent from the origin. (Scenes are in
// their own units, normalised by the readers; 1e7 is far past any capture.)
constexpr double kMaxSceneExtent = 1e7;
std::string camera_problem(const Camera& camera);

// nerfstudio/NeRF camera-to-world (OpenGL axes: x right, y up, z backward) to
// an OpenCV world-to-camera. A uniform scale in the rotation block is removed.
Mat4 opengl_c2w_to_opencv_w2c(const Mat4& c2w_gl);
// The inverse conversion, used by the transforms.json writer.
Mat4 opencv_w2c_to_opengl_c2w(const Mat4& w2c_cv);

// World-to-camera (OpenCV) for a camera at eye looking at target, with
// world_up giving the image's upward direction.
Mat4 look_at(const Vec3& eye, const Vec3& target, const Vec3& world_up);

// Field of view (radians) -> focal length (pixels) for an image extent (pixels).
double focal_from_fov(double fov_rad, int extent_px);

}  // namespace ddhgs::core
