#include "eval/render_frames.h"

#include <cstdio>

#include "core/error.h"
#include "core/log.h"
#include "eval/orbit.h"
#include "io/cube/cube.h"
#include "io/image/image.h"

namespace ddhgs::eval {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kColourBarPx = 12;  // height of the error colour bar

std::string number_label(double value) {
  return core::format_g(value);
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
  const bool mapped = options.band_map.defined();
  const std::vector<double>& wavelengths = mapped ? options.wavelengths_nm : scene.wavelengths_nm;
  model::Gaussians model = gaussians;  // handles to the same tensors
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
