#include "io/scene/backdrop.h"

#include <algorithm>
#include <cstdio>

#include "core/error.h"

namespace ddhgs::io {

namespace {

// The pixels within border_px of the edge of one image: [P, n] float32.
torch::Tensor image_border(const torch::Tensor& image, int border_px) {
  const int64_t h = image.size(0), w = image.size(1), n = image.size(2);
  const int64_t b = std::min<int64_t>(border_px, std::min(h, w) / 2);
  if (b == 0) return image.reshape({-1, n}).to(torch::kFloat32);
  // Copies: a view of the top or bottom rows would keep the whole float
  // image alive (185 MB for a 640x512x141 view) until the median.
  return torch::cat({image.slice(0, 0, b).reshape({-1, n}).clone(),
                     image.slice(0, h - b, h).reshape({-1, n}).clone(),
                     image.slice(0, b, h - b).slice(1, 0, b).reshape({-1, n}),
                     image.slice(0, b, h - b).slice(1, w - b, w).reshape({-1, n})},
                    0)
      .to(torch::kFloat32);
}

// Border pixels of up to max_views of `views` ([P_i, n_i] each) and the
// scene bands each holds. In a band-per-view scene the views are sampled
// band by band, so that every band the views hold is represented.
struct Borders {
  std::vector<torch::Tensor> pixels;
  std::vector<torch::Tensor> bands;  // int64 scene band indices per entry
};

Borders border_pixels(const Scene& scene, const std::vector<int>& views, int max_views,
                      int border_px) {
  core::require(!views.empty(), scene.root, "no views to take the border colour from");
  core::require(max_views > 0 && border_px > 0, "border_colour: expected positive counts");
  std::vector<int> chosen;
  auto sample = [&](const std::vector<int>& from) {
    const size_t count = std::min(from.size(), size_t(max_views));
    for (size_t i = 0; i < count; ++i) chosen.push_back(from[i * from.size() / count]);
  };
  if (!scene.band_per_view()) {
    sample(views);
  } else {
    for (int64_t band = 0; band < scene.bands(); ++band) {
      std::vector<int> holding;
      for (int v : views) {
        const std::vector<int>& b = scene.views[size_t(v)].bands;
        if (b.empty() || std::find(b.begin(), b.end(), int(band)) != b.end()) holding.push_back(v);
      }
      sample(holding);
    }
    std::sort(chosen.begin(), chosen.end());
    chosen.erase(std::unique(chosen.begin(), chosen.end()), chosen.end());
  }
  Borders out;
  for (int v : chosen) {
    out.pixels.push_back(image_border(scene.image(v), border_px));
    const torch::Tensor b = scene.view_bands(v);
    out.bands.push_back(b.defined() ? b : torch::arange(scene.bands(), torch::kInt64));
  }
  return out;
}

// The per-band median over every border pixel that holds the band: [N].
torch::Tensor median_colour(const Scene& scene, const Borders& borders) {
  if (!scene.band_per_view())
    return std::get<0>(torch::cat(borders.pixels, 0).median(0)).contiguous();
  torch::Tensor colour = torch::zeros({scene.bands()}, torch::kFloat32);
  for (int64_t band = 0; band < scene.bands(); ++band) {
    std::vector<torch::Tensor> columns;
    for (size_t i = 0; i < borders.pixels.size(); ++i) {
      const torch::Tensor at = (borders.bands[i] == band).nonzero();
      if (at.numel() > 0) columns.push_back(borders.pixels[i].select(1, at[0][0].item<int64_t>()));
    }
    if (!columns.empty()) colour[band] = std::get<0>(torch::cat(columns).median(0));
  }
  return colour;
}

}  // namespace

torch::Tensor border_colour(const Scene& scene, const std::vector<int>& views, int max_views,
                            int border_px) {
  return median_colour(scene, border_pixels(scene, views, max_views, border_px));
}

BorderScan scan_border(const Scene& scene, const std::vector<int>& views, double tolerance) {
  const Borders borders = border_pixels(scene, views, kBorderViews, kBorderPx);
  BorderScan scan;
  scan.colour = median_colour(scene, borders);
  double near = 0, total = 0;
  for (size_t i = 0; i < borders.pixels.size(); ++i) {
    const torch::Tensor own = scan.colour.index_select(0, borders.bands[i]);
    near += ((borders.pixels[i] - own).abs().amax(1) <= tolerance).sum().item<double>();
    total += double(borders.pixels[i].size(0));
  }
  scan.share = total > 0 ? near / total : 0;
  return scan;
}

std::optional<torch::Tensor> masked_backdrop(const Scene& scene, const std::vector<int>& views,
                                             double tolerance, double min_share) {
  BorderScan scan = scan_border(scene, views, tolerance);
  if (scan.share < min_share) return std::nullopt;
  return scan.colour;
}

std::string describe_colour(const torch::Tensor& values) {
  char text[96];
  if (values.numel() <= 4) {
    std::string out;
    for (int64_t i = 0; i < values.numel(); ++i) {
      std::snprintf(text, sizeof text, "%s%.3f", i ? ", " : "", values[i].item<double>());
      out += text;
    }
    return out;
  }
  std::snprintf(text, sizeof text, "%.3f to %.3f over %lld bands", values.min().item<double>(),
                values.max().item<double>(), (long long)values.numel());
  return text;
}

torch::Tensor object_mask(const torch::Tensor& image, const torch::Tensor& backdrop,
                          double tolerance) {
  core::require(image.dim() == 3 && backdrop.dim() == 1 && backdrop.size(0) == image.size(2),
                "object_mask: expected an [H, W, N] image and an [N] backdrop");
  const torch::Tensor b = backdrop.to(image.scalar_type()).view({1, 1, -1});
  return (image - b).abs().amax(2) > tolerance;
}

torch::Tensor interior(const torch::Tensor& mask) {
  core::require(mask.dim() == 2, "interior: expected an [H, W] mask");
  // A pixel is interior when no backdrop pixel is among its 8 neighbours:
  // max-pool the backdrop; the pooling's padding counts as object.
  const torch::Tensor backdrop = (~mask).to(torch::kFloat32).unsqueeze(0).unsqueeze(0);
  const torch::Tensor near = torch::max_pool2d(backdrop, {3, 3}, {1, 1}, {1, 1});
  return near.squeeze(0).squeeze(0) == 0;
}

}  // namespace ddhgs::io
