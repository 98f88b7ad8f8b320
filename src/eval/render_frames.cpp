#include "eval/render_frames.h"

#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "eval/orbit.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/image/image.h"

namespace ddhgs::eval {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kColourBarPx = 12;  // height of the error colour bar

std::string number_label(double value) {
  return core::format_g(value);
}

// Mean of the finite values; NaN when there is none.
double finite_mean(const torch::Tensor& values) {
  const torch::Tensor finite = values.isfinite();
  const int64_t count = finite.sum().item<int64_t>();
  if (count == 0) return NAN;
  return torch::where(finite, values, torch::zeros_like(values)).sum().item<double>() /
         double(count);
}

nlohmann::json number_or_null(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
}

// The --index branch of render_frames.
int render_index_frames(const io::Scene& scene, const model::Gaussians& model,
                        const torch::Tensor& background, const std::vector<Frame>& frames,
                        const RenderOptions& options, const fs::path& out_dir) {
  if (options.diff && scene.band_per_view())
    throw core::Error("--diff",
                      "compares every band of a view; the views of this band-per-view "
                      "scene hold one or a few (ddhgs eval measures them per band)");
  const VegetationIndex& index = *options.index;
  const torch::Tensor map = index_band_map(index, scene.wavelengths_nm);  // [2, N]
  const std::string& label = index.name;
  nlohmann::json summary = {{"index", label},
                            {"a", index.a.name},
                            {"b", index.b.name},
                            {"frames", nlohmann::json::array()}};
  int written = 0;
  double error_sum = 0;
  int64_t compared = 0;
  core::ProgressBar bar("render", int64_t(frames.size()));
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    const fs::path stem = out_dir / frame.name;
    torch::Tensor image = model::render_gaussians(model, frame.camera, background).image;
    if (options.transform) image = options.transform(image);
    const torch::Tensor values = index_values(image, map);  // [H, W]
    const torch::Tensor shown = index_picture(values);
    io::write_png(stem.string() + "_" + label + ".png",
                  stacked(shown, colour_bar(kColourBarPx, values.size(1), Colormap::RdYlGn)));
    ++written;
    if (options.format != OutputFormat::Png) {
      io::write_npy(stem.string() + "_" + label + ".npy", values);
      ++written;
    }
    nlohmann::json record = {{"name", frame.name}, {"mean", number_or_null(finite_mean(values))}};
    if (options.diff && frame.view >= 0) {
      const torch::Tensor truth = index_values(
          scene.has_clean() ? scene.clean_image(frame.view) : scene.image(frame.view), map);
      const torch::Tensor error = (values - truth).abs();  // NaN where either has no signal
      const double mae = finite_mean(error);
      record["truth_mean"] = number_or_null(finite_mean(truth));
      record["mean_absolute_error"] = number_or_null(mae);
      if (std::isfinite(mae)) {
        error_sum += mae;
        ++compared;
      }
      const torch::Tensor heat = apply_colormap(
          torch::where(error.isfinite(), error / options.diff_max, torch::zeros_like(error)),
          options.colormap);
      io::write_png(
          stem.string() + "_" + label + "_compare.png",
          comparison_panels(index_picture(truth), shown, heat, options.colormap, kColourBarPx));
      ++written;
    }
    summary["frames"].push_back(record);
    bar.update(int64_t(i + 1));
  }
  if (compared > 0) {
    summary["mean_absolute_error"] = error_sum / double(compared);
    summary["truth"] = scene.has_clean() ? "clean" : "captured";
    core::log_info(label + ": mean absolute error against the " +
                   summary["truth"].get<std::string>() + " views' own " + label + " " +
                   core::format_g(error_sum / double(compared)) + " over " +
                   std::to_string(compared) + " frame(s)");
  }
  io::write_file_atomically(out_dir / (label + ".json"), summary.dump(2) + "\n");
  ++written;
  bar.finish(std::to_string(written) + " files");
  return written;
}

}  // namespace

OutputFormat parse_output_format(const std::string& name) {
  if (name == "png") return OutputFormat::Png;
  if (name == "npy") return OutputFormat::Npy;
  if (name == "envi") return OutputFormat::Envi;
  throw core::Error("--format: expected npy, envi or png, got '" + name + "'");
}

std::vector<Frame> view_frames(const io::Scene& scene, const std::vector<int>& views) {
  std::vector<Frame> frames;
  for (int v : views)
    frames.push_back({scene.views[size_t(v)].name, scene.views[size_t(v)].camera, v});
  return frames;
}

std::vector<Frame> orbit_frames(const io::Scene& scene, int count) {
  std::vector<core::Camera> train;
  for (int v : scene.train) train.push_back(scene.views[size_t(v)].camera);
  if (train.empty())
    for (const io::View& view : scene.views) train.push_back(view.camera);
  std::vector<Frame> frames;
  std::vector<core::Camera> path = orbit_cameras(train, count);
  for (size_t i = 0; i < path.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "orbit_%03zu", i);
    frames.push_back({name, path[i], -1});
  }
  return frames;
}

int render_frames(const io::Scene& scene, const model::Gaussians& gaussians,
                  const torch::Tensor& background, const std::vector<Frame>& frames,
                  const RenderOptions& options, const fs::path& out_dir) {
  torch::NoGradGuard no_grad;
  if (options.diff && scene.band_per_view())
    throw core::Error("--diff",
                      "compares every band of a view; the views of this band-per-view "
                      "scene hold one or a few (ddhgs eval measures them per band)");
  const bool mapped = options.band_map.defined();
  const std::vector<double>& wavelengths = mapped ? options.wavelengths_nm : scene.wavelengths_nm;
  model::Gaussians model = gaussians;  // handles to the same tensors
  if (options.index) return render_index_frames(scene, model, background, frames, options, out_dir);
  if (mapped) model.colour = gaussians.colour.mapped(options.band_map);
  const std::string label = options.bands.label;
  int written = 0;
  core::ProgressBar bar("render", int64_t(frames.size()));
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    fs::path stem = out_dir / frame.name;
    torch::Tensor image =
        model::render_gaussians(model, frame.camera, background).image;  // [H, W, N or M]
    if (options.transform) image = options.transform(image);
    if (options.format == OutputFormat::Npy) {
      io::write_npy(stem.string() + ".npy", image);
      ++written;
    } else if (options.format == OutputFormat::Envi) {
      io::write_envi(stem.string() + ".hdr", image, wavelengths);
      written += 2;
    }
    torch::Tensor shown = picture(image, wavelengths, options.bands, options.colormap);
    io::write_png(stem.string() + "_" + label + ".png", shown);
    ++written;

    if (options.diff && frame.view >= 0) {
      torch::Tensor truth =
          scene.has_clean() ? scene.clean_image(frame.view) : scene.image(frame.view);  // [H, W, N]
      if (mapped) truth = torch::matmul(truth, options.band_map.to(truth.scalar_type()).t());
      torch::Tensor error =
          error_heatmap(image, truth, options.bands, options.diff_max, options.colormap);
      io::write_png(
          stem.string() + "_" + label + "_diff_max" + number_label(options.diff_max) + ".png",
          error);
      torch::Tensor compare =
          comparison_panels(picture(truth, wavelengths, options.bands, options.colormap), shown,
                            error, options.colormap, kColourBarPx);
      io::write_png(stem.string() + "_" + label + "_compare.png", compare);
      written += 2;
    }
    bar.update(int64_t(i + 1));
  }
  bar.finish(std::to_string(written) + " files");
  return written;
}

}  // namespace ddhgs::eval
