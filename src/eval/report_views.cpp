#include "eval/report_views.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/log.h"
#include "eval/colormap.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"

namespace ddhgs::eval {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kReportColourBarPx = 8;

// The paper's figure ranges, nm.
constexpr double kPaperRangesNm[][2] = {{400, 418}, {750, 768}, {1082, 1100}};

std::string nm(double value) {
  return core::format_g(std::round(value * 10) / 10);
}

}  // namespace

std::vector<BandSelection> report_band_selections(const std::vector<double>& wavelengths_nm) {
  std::vector<BandSelection> out{BandSelection{}};
  if (wavelengths_nm.empty()) return out;
  if (!std::is_sorted(wavelengths_nm.begin(), wavelengths_nm.end())) {
    // An RGB run (610, 550, 465 nm): each channel on its own.
    for (int64_t b = 0; b < int64_t(wavelengths_nm.size()); ++b) {
      BandSelection s;
      s.pseudo_rgb = false;
      s.first = s.last = b;
      s.label = nm(wavelengths_nm[size_t(b)]) + "nm";
      out.push_back(s);
    }
    return out;
  }
  const double first = wavelengths_nm.front(), last = wavelengths_nm.back();
  for (const auto& range : kPaperRangesNm) {
    double width = range[1] - range[0];
    double lo = std::clamp(range[0], first, std::max(first, last - width));
    double hi = std::min(lo + width, last);
    BandSelection s;
    s.pseudo_rgb = false;
    s.first = int64_t(wavelengths_nm.size());
    s.last = -1;
    for (int64_t b = 0; b < int64_t(wavelengths_nm.size()); ++b) {
      if (wavelengths_nm[size_t(b)] < lo || wavelengths_nm[size_t(b)] > hi) continue;
      s.first = std::min(s.first, b);
      s.last = std::max(s.last, b);
    }
    if (s.last < 0) {
      const double mid = 0.5 * (lo + hi);
      auto nearest = std::min_element(
          wavelengths_nm.begin(), wavelengths_nm.end(),
          [mid](double a, double b) { return std::abs(a - mid) < std::abs(b - mid); });
      s.first = s.last = nearest - wavelengths_nm.begin();
    }
    s.label = nm(lo) + "-" + nm(hi) + "nm";
    bool seen = std::any_of(out.begin(), out.end(), [&](const BandSelection& o) {
      return !o.pseudo_rgb && o.first == s.first && o.last == s.last;
    });
    if (!seen) out.push_back(s);
  }
  return out;
}

std::string selection_title(const BandSelection& bands, const std::vector<double>& wavelengths_nm) {
  if (bands.pseudo_rgb) return "pseudo-RGB (all bands, CIE D65)";
  std::string title = bands.label.substr(0, bands.label.size() - 2) + " nm (";
  if (bands.first == bands.last) return title + "band " + std::to_string(bands.first) + ")";
  return title + "bands " + std::to_string(bands.first) + "-" + std::to_string(bands.last) +
         ", mean)";
}

torch::Tensor comparison_figure(const torch::Tensor& render, const torch::Tensor& truth,
                                const std::vector<double>& wavelengths_nm,
                                const BandSelection& bands, double diff_max) {
  const Colormap map = Colormap::Viridis;
  torch::Tensor error = error_heatmap(render, truth, bands, diff_max, map);
  return comparison_panels(picture(truth, wavelengths_nm, bands, Colormap::Gray),
                           picture(render, wavelengths_nm, bands, Colormap::Gray), error, map,
                           kReportColourBarPx);
}

BandAtlas band_atlas(const torch::Tensor& cube, int max_px) {
  const int64_t h = cube.size(0), w = cube.size(1), n = cube.size(2);
  const int64_t factor = std::max<int64_t>(1, (std::max(h, w) + max_px - 1) / max_px);
  torch::Tensor bands = cube.permute({2, 0, 1}).unsqueeze(0).to(torch::kFloat);  // [1, N, H, W]
  if (factor > 1) bands = torch::avg_pool2d(bands, {factor, factor});
  bands = bands.squeeze(0);  // [N, h, w]
  BandAtlas atlas;
  atlas.height = int(bands.size(1));
  atlas.width = int(bands.size(2));
  atlas.cols = int(std::ceil(std::sqrt(double(n))));
  atlas.rows = int((n + atlas.cols - 1) / atlas.cols);
  torch::Tensor padded =
      torch::zeros({int64_t(atlas.rows) * atlas.cols, bands.size(1), bands.size(2)});
  padded.narrow(0, 0, n).copy_(bands);
  atlas.pixels =
      (padded.clamp(0, 1) * 255)
          .round()
          .to(torch::kUInt8)
          .reshape({atlas.rows, atlas.cols, atlas.height, atlas.width})
          .permute({0, 2, 1, 3})
          .reshape({int64_t(atlas.rows) * atlas.height, int64_t(atlas.cols) * atlas.width})
          .contiguous();
  return atlas;
}

std::string base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t chunk = uint32_t(uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) chunk |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    if (i + 2 < bytes.size()) chunk |= uint32_t(uint8_t(bytes[i + 2]));
    out += kAlphabet[(chunk >> 18) & 63];
    out += kAlphabet[(chunk >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(chunk >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[chunk & 63] : '=';
  }
  return out;
}

std::string png_data_uri(const torch::Tensor& image, const fs::path& scratch) {
  io::write_png(scratch, image);
  std::string bytes = io::read_file(scratch);
  fs::remove(scratch);
  return "data:image/png;base64," + base64(bytes);
}

nlohmann::json viridis_lut() {
  return colormap_lut(Colormap::Viridis);
}

nlohmann::json colormap_lut(Colormap map) {
  nlohmann::json lut = nlohmann::json::array();
  for (int i = 0; i < 256; ++i) {
    auto rgb = colormap_rgb(map, i / 255.0);
    lut.push_back({int(std::lround(255 * rgb[0])), int(std::lround(255 * rgb[1])),
                   int(std::lround(255 * rgb[2]))});
  }
  return lut;
}

}  // namespace ddhgs::eval
