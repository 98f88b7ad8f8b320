#include "train/view_crop.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "train/seed.h"

namespace ddhgs::train {
namespace {

struct Side {
  int begin, end;      // the drawn span, clipped to the side
  double mean_length;  // over every offset
};

// One side of the crop: a window of `window` pixels at an offset drawn from
// [m - window, side - m], clipped to [0, side).
Side draw_side(int side, int window, uint64_t seed) {
  const int m = kMinCropSide, lo = m - window, hi = side - m;
  auto clipped = [&](int start) {
    return std::pair<int, int>(std::max(0, start), std::min(side, start + window));
  };
  double total = 0;
  for (int start = lo; start <= hi; ++start) {
    const auto [b, e] = clipped(start);
    total += e - b;
  }
  const int start = lo + int(seed % uint64_t(hi - lo + 1));
  const auto [b, e] = clipped(start);
  return {b, e, total / double(hi - lo + 1)};
}

// The window giving a pixel coverage of q along a side (q = L / (side + L -
// 2 m + 1) for the pixels away from the border), at least m.
int window_for(int side, double q) {
  const double m = kMinCropSide;
  return std::max(kMinCropSide, int(std::lround(q * (side - 2 * m + 1) / (1 - q))));
}

}  // namespace

double crop_fraction(double view_fraction, int64_t from_pixels, int width, int height) {
  return int64_t(width) * int64_t(height) >= from_pixels ? view_fraction : 1;
}

ViewCrop draw_view_crop(int width, int height, double fraction, uint64_t seed) {
  core::require(fraction > 0 && fraction <= 1, "view crop: fraction must be in (0, 1]");
  ViewCrop crop{0, 0, width, height, 1, 1};
  if (fraction >= 1 || width < 2 * kMinCropSide || height < 2 * kMinCropSide) return crop;
  const double q = std::sqrt(fraction);
  const Side x = draw_side(width, window_for(width, q), mix_seed(seed, 0));
  const Side y = draw_side(height, window_for(height, q), mix_seed(seed, 1));
  crop.x0 = x.begin, crop.x1 = x.end, crop.y0 = y.begin, crop.y1 = y.end;
  const double mean_area = x.mean_length * y.mean_length;
  crop.loss_scale = double(crop.width()) * crop.height() / mean_area;
  crop.coverage = mean_area / (double(width) * height);
  return crop;
}

core::Camera crop_camera(const core::Camera& camera, const ViewCrop& crop) {
  core::Camera out = camera;
  core::Intrinsics& in = out.intrinsics;
  in.frame_x = crop.x0, in.frame_y = crop.y0;
  in.frame_width = in.width, in.frame_height = in.height;
  in.cx -= crop.x0, in.cy -= crop.y0;
  in.width = crop.width(), in.height = crop.height();
  return out;
}

}  // namespace ddhgs::train
