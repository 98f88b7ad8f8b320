#include "io/undistort/undistort.h"

#include <c10/util/Half.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "core/distortion.h"
#include "core/error.h"
#include "core/parallel.h"
#include "io/cube/cube_formats.h"

namespace ddhgs::io {
namespace {

template <typename T, typename Acc>
T from_acc(Acc v) {
  if constexpr (std::is_integral_v<T>) {
    v = std::round(v);
    v = std::min<Acc>(std::max<Acc>(v, Acc(std::numeric_limits<T>::lowest())),
                      Acc(std::numeric_limits<T>::max()));
  }
  return static_cast<T>(v);
}

// out[p, :] = bilinear blend of the four source rows around p; the band loop
// is innermost and contiguous. Acc: float, or double for int32 and float64
// samples, which float32 would round.
template <typename T, typename Acc>
void remap(const T* src, T* dst, int64_t pixels, int64_t bands, int64_t width,
           const std::vector<int64_t>& top_left, const std::vector<double>& wx,
           const std::vector<double>& wy) {
  core::parallel_for(0, pixels, 256, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      const Acc ax = wx[size_t(p)], ay = wy[size_t(p)];
      const Acc w00 = (1 - ax) * (1 - ay), w01 = ax * (1 - ay), w10 = (1 - ax) * ay, w11 = ax * ay;
      const T* r00 = src + top_left[size_t(p)] * bands;
      const T* r01 = r00 + bands;
      const T* r10 = r00 + width * bands;
      const T* r11 = r10 + bands;
      T* out = dst + p * bands;
      for (int64_t b = 0; b < bands; ++b)
        out[b] = from_acc<T>(w00 * Acc(r00[b]) + w01 * Acc(r01[b]) + w10 * Acc(r10[b]) +
                             w11 * Acc(r11[b]));
    }
  });
}

template <typename T, typename Acc>
void remap_tensor(const torch::Tensor& src, torch::Tensor& dst, int64_t width,
                  const std::vector<int64_t>& top_left, const std::vector<double>& wx,
                  const std::vector<double>& wy) {
  // U16 samples live bit-for-bit in int16 tensors (see cube.h).
  const T* in = reinterpret_cast<const T*>(src.data_ptr());
  T* out = reinterpret_cast<T*>(dst.data_ptr());
  remap<T, Acc>(in, out, src.size(0) * src.size(1), src.size(2), width, top_left, wx, wy);
}

}  // namespace

Undistortion::Undistortion(const core::Intrinsics& lens)
    : lens_(lens), pinhole_(core::undistorted_pinhole(lens)) {}

void Undistortion::build_table() const {
  const int64_t w = lens_.width, h = lens_.height;
  top_left_.resize(size_t(w * h));
  weight_x_.resize(size_t(w * h));
  weight_y_.resize(size_t(w * h));
  core::parallel_for(0, h, 8, [&](int64_t row_begin, int64_t row_end) {
    for (int64_t j = row_begin; j < row_end; ++j)
      for (int64_t i = 0; i < w; ++i) {
        core::Point2 n{(i + 0.5 - pinhole_.cx) / pinhole_.fx,
                       (j + 0.5 - pinhole_.cy) / pinhole_.fy};
        core::Point2 d = core::distort(lens_, n);
        // Source sample position: pixel centres sit at integer + 0.5.
        double sx = std::clamp(lens_.fx * d.x + lens_.cx - 0.5, 0.0, double(w - 1));
        double sy = std::clamp(lens_.fy * d.y + lens_.cy - 0.5, 0.0, double(h - 1));
        int64_t x0 = std::min<int64_t>(int64_t(sx), w - 2);
        int64_t y0 = std::min<int64_t>(int64_t(sy), h - 2);
        size_t p = size_t(j * w + i);
        top_left_[p] = y0 * w + x0;
        weight_x_[p] = sx - double(x0);
        weight_y_[p] = sy - double(y0);
      }
  });
}

torch::Tensor Undistortion::apply(const torch::Tensor& data, SampleType type,
                                  const std::string& origin) const {
  core::require(data.dim() == 3 && data.size(0) == lens_.height && data.size(1) == lens_.width,
                origin + ": undistortion expects a " + std::to_string(lens_.width) + "x" +
                    std::to_string(lens_.height) + " view");
  core::require(data.scalar_type() == detail::tensor_dtype(type),
                origin + ": undistortion: samples do not hold their stored type");
  std::call_once(built_, [this] { build_table(); });
  torch::Tensor src = data.contiguous();
  torch::Tensor dst = torch::empty_like(src);
  const int64_t w = lens_.width;
  switch (type) {
    case SampleType::U8:
      remap_tensor<uint8_t, float>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::U16:
      remap_tensor<uint16_t, float>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::I16:
      remap_tensor<int16_t, float>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::I32:
      remap_tensor<int32_t, double>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::F16:
      remap_tensor<c10::Half, float>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::F32:
      remap_tensor<float, float>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
    case SampleType::F64:
      remap_tensor<double, double>(src, dst, w, top_left_, weight_x_, weight_y_);
      break;
  }
  return dst;
}

}  // namespace ddhgs::io
