#include "io/scene/backdrop.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/log.h"

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

// Pixels of the middle third of one image (rows and columns), on a grid of
// at most about kCentrePixels: [Q, n] float32.
constexpr int64_t kCentrePixels = 2048;
torch::Tensor image_centre(const torch::Tensor& image) {
  const int64_t h = image.size(0), w = image.size(1), n = image.size(2);
  const torch::Tensor middle = image.slice(0, h / 3, std::max(h / 3 + 1, 2 * h / 3))
                                   .slice(1, w / 3, std::max(w / 3 + 1, 2 * w / 3));
  const auto step = int64_t(
      std::ceil(std::sqrt(double(middle.size(0) * middle.size(1)) / double(kCentrePixels))));
  return middle.slice(0, 0, middle.size(0), step)
      .slice(1, 0, middle.size(1), step)
      .reshape({-1, n})
      .to(torch::kFloat32)
      .clone();
}

// Border pixels of up to max_views of `views` ([P_i, n_i] each), a sample
// of their middles ([Q_i, n_i]) and the scene bands each holds. In a
// band-per-view scene the views are sampled band by band, so that every
// band the views hold is represented.
struct Borders {
  std::vector<torch::Tensor> pixels;
  std::vector<torch::Tensor> centres;
  std::vector<torch::Tensor> bands;  // int64 scene band indices per entry
};

// Up to max_views of `views` spread along the list; in a band-per-view
// scene band by band, so that every band the views hold is represented.
std::vector<int> spread_views(const Scene& scene, const std::vector<int>& views, int max_views) {
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
  return chosen;
}

// The scene bands view v holds, as an int64 index tensor (every band: all).
torch::Tensor held_bands(const Scene& scene, int v) {
  const torch::Tensor b = scene.view_bands(v);
  return b.defined() ? b : torch::arange(scene.bands(), torch::kInt64);
}

Borders border_pixels(const Scene& scene, const std::vector<int>& views, int max_views,
                      int border_px) {
  core::require(!views.empty(), scene.root, "no views to take the border colour from");
  core::require(max_views > 0 && border_px > 0, "border_colour: expected positive counts");
  Borders out;
  for (int v : spread_views(scene, views, max_views)) {
    const torch::Tensor image = scene.image(v);
    out.pixels.push_back(image_border(image, border_px));
    out.centres.push_back(image_centre(image));
    out.bands.push_back(held_bands(scene, v));
  }
  return out;
}

// The per-band median over every sampled pixel ([P_i, n_i] each, holding
// the scene bands `bands[i]`) that holds the band: [N].
torch::Tensor median_colour(const Scene& scene, const std::vector<torch::Tensor>& pixels,
                            const std::vector<torch::Tensor>& bands) {
  if (!scene.band_per_view()) return std::get<0>(torch::cat(pixels, 0).median(0)).contiguous();
  torch::Tensor colour = torch::zeros({scene.bands()}, torch::kFloat32);
  for (int64_t band = 0; band < scene.bands(); ++band) {
    std::vector<torch::Tensor> columns;
    for (size_t i = 0; i < pixels.size(); ++i) {
      const torch::Tensor at = (bands[i] == band).nonzero();
      if (at.numel() > 0) columns.push_back(pixels[i].select(1, at[0][0].item<int64_t>()));
    }
    if (!columns.empty()) colour[band] = std::get<0>(torch::cat(columns).median(0));
  }
  return colour;
}

// 1.4826 x the median absolute deviation from the colour per band (a
// standard deviation for Gaussian noise), and the median of it over the
// bands, so that a few noisy bands at a sensor's edges do not decide.
// deviations: |pixel - colour| of the border pixels on the colour, per view.
double border_spread(const Scene& scene, const Borders& borders,
                     const std::vector<torch::Tensor>& deviations) {
  // No border pixel near the colour (a textured field to every edge): no
  // spread to measure, and the share test has already said why.
  int64_t rows = 0;
  for (const torch::Tensor& d : deviations) rows += d.size(0);
  if (rows == 0) return 0;
  if (!scene.band_per_view())
    return 1.4826 * std::get<0>(torch::cat(deviations, 0).median(0)).median().item<double>();
  std::vector<torch::Tensor> per_band;
  for (int64_t band = 0; band < scene.bands(); ++band) {
    std::vector<torch::Tensor> columns;
    for (size_t i = 0; i < deviations.size(); ++i) {
      const torch::Tensor at = (borders.bands[i] == band).nonzero();
      if (at.numel() > 0) columns.push_back(deviations[i].select(1, at[0][0].item<int64_t>()));
    }
    const torch::Tensor band_rows = columns.empty() ? torch::Tensor() : torch::cat(columns);
    if (band_rows.defined() && band_rows.numel() > 0)
      per_band.push_back(std::get<0>(band_rows.median(0)));
  }
  if (per_band.empty()) return 0;
  return 1.4826 * torch::stack(per_band).median().item<double>();
}

std::string whole_percent(double share) {
  return std::to_string(int(std::lround(100 * share))) + " %";
}

double round3(double value) {
  return std::round(value * 1000) / 1000;
}

}  // namespace

torch::Tensor border_colour(const Scene& scene, const std::vector<int>& views, int max_views,
                            int border_px) {
  const Borders borders = border_pixels(scene, views, max_views, border_px);
  return median_colour(scene, borders.pixels, borders.bands);
}

torch::Tensor sampled_colour(const Scene& scene, const std::vector<int>& views, int max_views,
                             int64_t pixels_per_view) {
  core::require(!views.empty(), scene.root, "no views to take the colour from");
  core::require(max_views > 0 && pixels_per_view > 0, "sampled_colour: expected positive counts");
  std::vector<torch::Tensor> pixels, bands;
  for (int v : spread_views(scene, views, max_views)) {
    const torch::Tensor image = scene.image(v);
    const torch::Tensor flat = image.reshape({-1, image.size(2)}).to(torch::kFloat32);
    torch::Tensor picked = flat;
    if (flat.size(0) > pixels_per_view) {
      auto generator = at::make_generator<at::CPUGeneratorImpl>(uint64_t(v) + 1);
      picked = flat.index_select(
          0, torch::randperm(flat.size(0), generator, torch::kInt64).slice(0, 0, pixels_per_view));
    }
    pixels.push_back(picked);
    bands.push_back(held_bands(scene, v));
  }
  return median_colour(scene, pixels, bands);
}

BorderScan scan_border(const Scene& scene, const std::vector<int>& views, double tolerance,
                       double min_share) {
  const Borders borders = border_pixels(scene, views, kBorderViews, kBorderPx);
  BorderScan scan;
  scan.colour = median_colour(scene, borders.pixels, borders.bands);
  double near = 0, total = 0;
  int views_on = 0, views_filled = 0;
  std::vector<torch::Tensor>
      on_deviations;  // per view: [P_i', n_i], its border pixels on the colour
  for (size_t i = 0; i < borders.pixels.size(); ++i) {
    const torch::Tensor own = scan.colour.index_select(0, borders.bands[i]);
    const torch::Tensor deviation = (borders.pixels[i] - own).abs();
    const torch::Tensor on = deviation.amax(1) <= tolerance;
    on_deviations.push_back(deviation.index({on}));
    const double count = on.sum().item<double>(), pixels = double(on.size(0));
    views_on += pixels > 0 && count >= min_share * pixels;
    near += count;
    total += pixels;
    const torch::Tensor centre = borders.centres[i];
    const double filled = ((centre - own).abs().amax(1) <= tolerance).sum().item<double>();
    views_filled += filled >= kBackdropFilledCentre * double(centre.size(0));
  }
  const double sampled = double(borders.pixels.size());
  scan.share = total > 0 ? near / total : 0;
  scan.view_share = sampled > 0 ? views_on / sampled : 0;
  scan.filled_share = sampled > 0 ? views_filled / sampled : 0;
  scan.spread = border_spread(scene, borders, on_deviations);
  const std::string within = " within " + core::format_g(tolerance) + " of their median";
  if (scan.share < min_share)
    scan.why_not = whole_percent(scan.share) + " of the view borders" + within;
  else if (scan.view_share < kBackdropMinViewShare)
    scan.why_not =
        "the borders of " + whole_percent(scan.view_share) + " of the views lie" + within;
  else if (scan.spread > kBackdropMaxSpread)
    scan.why_not = "the border varies by " + core::format_g(round3(scan.spread)) +
                   " around its median, a texture; a backdrop varies by at most " +
                   core::format_g(kBackdropMaxSpread);
  else if (scan.filled_share > kBackdropMaxFilledShare)
    scan.why_not = "the border's colour fills the middle of " + whole_percent(scan.filled_share) +
                   " of the views too: a surface across the frame (a field, a floor), not a "
                   "backdrop behind an object";
  scan.masked = scan.why_not.empty();
  return scan;
}

std::optional<torch::Tensor> masked_backdrop(const Scene& scene, const std::vector<int>& views,
                                             double tolerance, double min_share) {
  BorderScan scan = scan_border(scene, views, tolerance, min_share);
  if (!scan.masked) return std::nullopt;
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
