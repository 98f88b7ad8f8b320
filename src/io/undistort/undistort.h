// Undistortion of views: one bilinear remap from a distorted camera to its
// pinhole twin (core::undistorted_pinhole), applied to all bands of a cube
// at once, in the cube's stored sample type.
//
// The remap table (four neighbours and two weights per output pixel) is
// built on first use and shared by every view of the same camera. Integer
// samples are interpolated in floating point and rounded back to their type:
// an error of at most half a quantisation step, as for area averaging.
#pragma once
#include "core/tensor.h"

#include <cstdint>
#include <mutex>
#include <vector>

#include "core/camera.h"
#include "io/cube/cube.h"

namespace ddhgs::io {

class Undistortion {
 public:
  // lens: the camera as captured, at the resolution of the views it will
  // remap (with distortion; core::Error when no pinhole view can be made).
  explicit Undistortion(const core::Intrinsics& lens);

  const core::Intrinsics& lens() const { return lens_; }
  // The undistorted camera: same size and principal point, scaled focal lengths.
  const core::Intrinsics& pinhole() const { return pinhole_; }

  // data: [H, W, N] of the lens's size, any stored type (U16 as int16 bits);
  // returns the undistorted view, same shape and dtype. core::Error naming
  // origin when the size differs. Thread-safe.
  torch::Tensor apply(const torch::Tensor& data, SampleType type, const std::string& origin) const;

 private:
  void build_table() const;

  core::Intrinsics lens_, pinhole_;
  mutable std::once_flag built_;
  // Per output pixel: the source pixel at the top-left of its 2x2
  // neighbourhood (y * W + x) and the weights of the right and lower ones.
  mutable std::vector<int64_t> top_left_;
  mutable std::vector<double> weight_x_, weight_y_;
};

}  // namespace ddhgs::io
