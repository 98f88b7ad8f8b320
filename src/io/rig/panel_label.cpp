#include "io/rig/panel_label.h"

#include <zbar.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <regex>
#include <vector>

#include "core/distortion.h"

namespace ddhgs::io {

namespace {

using Corners = std::array<std::array<double, 2>, 4>;

// The region measured, in the code's frame (see panel_label.h), by version.
const Corners kLayoutBefore3 = {
    std::array<double, 2>{1.529, -0.131}, {2.840, -0.118}, {2.821, 1.214}, {1.505, 1.201}};
const Corners kLayoutFrom3 = {
    std::array<double, 2>{0.167, -1.490}, {0.882, -1.521}, {0.869, -0.702}, {0.154, -0.682}};

// The affine map (x, y) -> (a0 x + a1 y + a2, a3 x + a4 y + a5) that takes
// three corners of the unit square (0,0), (1,0), (1,1), (0,1), those
// numbered first, first + 1 and first + 2 (mod 4), to to[0], to[1], to[2].
std::array<double, 6> unit_corners_to(const Corners& to, size_t first) {
  static const double kUnit[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  double m[3][3];
  for (size_t i = 0; i < 3; ++i) {
    const double* u = kUnit[(first + i) % 4];
    m[i][0] = u[0], m[i][1] = u[1], m[i][2] = 1;
  }
  auto det3 = [](const double a[3][3]) {
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
           a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  };
  const double det = det3(m);  // +-1: three corners of the unit square
  std::array<double, 6> a{};
  for (size_t c = 0; c < 2; ++c)
    for (size_t k = 0; k < 3; ++k) {  // Cramer's rule: column k replaced by the targets
      double r[3][3];
      for (size_t i = 0; i < 3; ++i)
        for (size_t j = 0; j < 3; ++j) r[i][j] = j == k ? to[i][c] : m[i][j];
      a[3 * c + k] = det3(r) / det;
    }
  return a;
}

// Pixel (centres at integers) <-> the pinhole frame's normalised coordinates.
core::Point2 to_pinhole(const core::Intrinsics& lens, double x, double y) {
  const core::Point2 d{(x - lens.cx) / lens.fx, (y - lens.cy) / lens.fy};
  return lens.has_distortion() ? core::undistort(lens, d) : d;
}
std::array<double, 2> to_pixel(const core::Intrinsics& lens, core::Point2 p) {
  const core::Point2 d = lens.has_distortion() ? core::distort(lens, p) : p;
  return {lens.fx * d.x + lens.cx, lens.fy * d.y + lens.cy};
}

// Pixels whose centres lie inside the convex quadrilateral (either winding),
// edges included.
torch::Tensor quad_mask(const Corners& q, int64_t height, int64_t width) {
  torch::Tensor mask = torch::zeros({height, width}, torch::kBool);
  bool* m = mask.data_ptr<bool>();
  double area2 = 0;
  for (size_t i = 0; i < 4; ++i) area2 += q[i][0] * q[(i + 1) % 4][1] - q[(i + 1) % 4][0] * q[i][1];
  const double sign = area2 >= 0 ? 1 : -1;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& c : q) {
    x0 = std::min(x0, c[0]), x1 = std::max(x1, c[0]);
    y0 = std::min(y0, c[1]), y1 = std::max(y1, c[1]);
  }
  for (int64_t y = std::max<int64_t>(0, int64_t(std::ceil(y0)));
       y <= std::min<int64_t>(height - 1, int64_t(std::floor(y1))); ++y)
    for (int64_t x = std::max<int64_t>(0, int64_t(std::ceil(x0)));
         x <= std::min<int64_t>(width - 1, int64_t(std::floor(x1))); ++x) {
      bool in = true;
      for (size_t i = 0; i < 4 && in; ++i) {
        const auto& a = q[i];
        const auto& b = q[(i + 1) % 4];
        const double cross =
            (b[0] - a[0]) * (double(y) - a[1]) - (b[1] - a[1]) * (double(x) - a[0]);
        in = sign * cross >= -1e-9;
      }
      m[y * width + x] = in;
    }
  return mask;
}

}  // namespace

core::Intrinsics maker_pinhole(const core::Intrinsics& lens) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) {
      const core::Point2 p =
          to_pinhole(lens, j * double(lens.width - 1) / 8, i * double(lens.height - 1) / 8);
      x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
      y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
  core::Intrinsics pinhole;
  pinhole.width = lens.width, pinhole.height = lens.height;
  pinhole.fx = double(lens.width - 1) / (x1 - x0);
  pinhole.fy = double(lens.height - 1) / (y1 - y0);
  pinhole.cx = -pinhole.fx * x0, pinhole.cy = -pinhole.fy * y0;
  return pinhole;
}

namespace {

// signal seen through `pinhole` (bilinear; 0 outside the source).
torch::Tensor resample(const torch::Tensor& signal_in, const core::Intrinsics& lens,
                       const core::Intrinsics& pinhole) {
  const torch::Tensor signal = signal_in.to(torch::kFloat).contiguous();
  const int64_t height = signal.size(0), width = signal.size(1);
  const float* s = signal.data_ptr<float>();
  torch::Tensor out = torch::zeros({height, width}, torch::kFloat);
  float* o = out.data_ptr<float>();
  for (int64_t y = 0; y < height; ++y)
    for (int64_t x = 0; x < width; ++x) {
      const core::Point2 p{(double(x) - pinhole.cx) / pinhole.fx,
                           (double(y) - pinhole.cy) / pinhole.fy};
      const std::array<double, 2> at = to_pixel(lens, p);
      const int64_t x0 = int64_t(std::floor(at[0])), y0 = int64_t(std::floor(at[1]));
      if (x0 < 0 || y0 < 0 || x0 + 1 >= width || y0 + 1 >= height) continue;
      const double wx = at[0] - double(x0), wy = at[1] - double(y0);
      const float* r = s + y0 * width + x0;
      o[y * width + x] = float((1 - wy) * ((1 - wx) * r[0] + wx * r[1]) +
                               wy * ((1 - wx) * r[width] + wx * r[width + 1]));
    }
  return out;
}

}  // namespace

std::optional<PanelLabel> read_panel_label(const torch::Tensor& signal_in) {
  const torch::Tensor signal = signal_in.to(torch::kFloat).contiguous();
  const int64_t height = signal.size(0), width = signal.size(1);
  const double low = signal.min().item<double>(), high = signal.max().item<double>();
  if (!(high > low)) return std::nullopt;
  std::vector<uint8_t> gray(size_t(height * width));
  const float* s = signal.data_ptr<float>();
  for (size_t i = 0; i < gray.size(); ++i)
    gray[i] =
        uint8_t(std::clamp(std::lround(255.0 * (double(s[i]) - low) / (high - low)), 0L, 255L));

  std::unique_ptr<zbar::zbar_image_scanner_t, void (*)(zbar::zbar_image_scanner_t*)> scanner(
      zbar::zbar_image_scanner_create(), zbar::zbar_image_scanner_destroy);
  zbar::zbar_image_scanner_set_config(scanner.get(), zbar::ZBAR_NONE, zbar::ZBAR_CFG_ENABLE, 0);
  zbar::zbar_image_scanner_set_config(scanner.get(), zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_ENABLE, 1);
  std::unique_ptr<zbar::zbar_image_t, void (*)(zbar::zbar_image_t*)> image(
      zbar::zbar_image_create(), zbar::zbar_image_destroy);
  zbar::zbar_image_set_format(image.get(), zbar_fourcc('Y', '8', '0', '0'));
  zbar::zbar_image_set_size(image.get(), unsigned(width), unsigned(height));
  zbar::zbar_image_set_data(image.get(), gray.data(), gray.size(), nullptr);
  if (zbar::zbar_scan_image(scanner.get(), image.get()) <= 0) return std::nullopt;

  static const std::regex kSerial(R"(RP(\d{2})-\d{7}-[A-Za-z]{2}.*)");
  for (const zbar::zbar_symbol_t* symbol = zbar::zbar_image_first_symbol(image.get()); symbol;
       symbol = zbar::zbar_symbol_next(symbol)) {
    const char* data = zbar::zbar_symbol_get_data(symbol);
    std::smatch match;
    const std::string text = data ? data : "";
    if (!std::regex_match(text, match, kSerial) || zbar::zbar_symbol_get_loc_size(symbol) != 4)
      continue;
    PanelLabel label;
    label.serial = text;
    label.version = std::stoi(match[1].str());
    for (unsigned i = 0; i < 4; ++i)
      label.corners[i] = {double(zbar::zbar_symbol_get_loc_x(symbol, i)),
                          double(zbar::zbar_symbol_get_loc_y(symbol, i))};
    return label;
  }
  return std::nullopt;
}

std::optional<PanelRegion> find_labelled_panel(const torch::Tensor& signal,
                                               const core::Intrinsics& lens) {
  const core::Intrinsics pinhole = lens.has_distortion() ? maker_pinhole(lens) : lens;
  std::optional<PanelLabel> label =
      read_panel_label(lens.has_distortion() ? resample(signal, lens, pinhole) : signal);
  if (!label || label->version < 1) return std::nullopt;
  const Corners& layout = label->version < 3 ? kLayoutBefore3 : kLayoutFrom3;
  const int64_t height = signal.size(0), width = signal.size(1);
  Corners code;  // the code's corners in the pinhole frame, and in the image
  for (size_t i = 0; i < 4; ++i) {
    const core::Point2 p{(label->corners[i][0] - pinhole.cx) / pinhole.fx,
                         (label->corners[i][1] - pinhole.cy) / pinhole.fy};
    code[i] = {p.x, p.y};
    label->corners[i] = to_pixel(lens, p);
  }
  std::optional<PanelRegion> best;
  double best_spread = 1e300;
  for (size_t rotation = 0; rotation < 4; ++rotation) {
    // As the maker's library: the affine map through the code's first three
    // corners, the unit square's corners numbered from (4 - rotation) % 4.
    const std::array<double, 6> a = unit_corners_to(code, (4 - rotation) % 4);
    Corners region;
    bool inside = true;
    for (size_t i = 0; i < 4; ++i) {
      const double u = layout[i][0], v = layout[i][1];
      region[i] = to_pixel(lens, {a[0] * u + a[1] * v + a[2], a[3] * u + a[4] * v + a[5]});
      inside = inside && region[i][0] >= 0 && region[i][1] >= 0 &&
               region[i][0] <= double(width - 1) && region[i][1] <= double(height - 1);
    }
    if (!inside) continue;
    const torch::Tensor mask = quad_mask(region, height, width);
    const int64_t pixels = mask.sum().item<int64_t>();
    if (pixels < 50) continue;
    const torch::Tensor values = signal.masked_select(mask).to(torch::kDouble);
    const double mean = values.mean().item<double>();
    if (!(mean > 0)) continue;
    const double spread = values.std().item<double>() / mean;
    if (spread >= best_spread) continue;
    best_spread = spread;
    PanelRegion r;
    r.mask = mask;
    r.pixels = pixels;
    // Top-left, top-right, bottom-right, bottom-left: extremes along the diagonals.
    auto pick = [&](auto score) {
      return *std::max_element(region.begin(), region.end(),
                               [&](const auto& p, const auto& q) { return score(p) < score(q); });
    };
    r.corners = {pick([](const auto& p) { return -(p[0] + p[1]); }),
                 pick([](const auto& p) { return p[0] - p[1]; }),
                 pick([](const auto& p) { return p[0] + p[1]; }),
                 pick([](const auto& p) { return p[1] - p[0]; })};
    r.label = label->serial;
    r.label_corners = label->corners;
    r.spread = spread;
    best = std::move(r);
  }
  return best;
}

}  // namespace ddhgs::io
