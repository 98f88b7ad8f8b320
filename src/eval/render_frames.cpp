#include "eval/render_frames.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
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

// The views whose camera is view v's (the band images of one capture taken
// through one lens, or one cube's bands split apart), v among them. A rig's
// band cameras each look along their own rotation: their views differ.
std::vector<int> views_at_pose(const io::Scene& scene, int v) {
  const core::Camera& camera = scene.views[size_t(v)].camera;
  std::vector<int> out;
  for (size_t u = 0; u < scene.views.size(); ++u) {
    const core::Camera& other = scene.views[u].camera;
    bool same = other.intrinsics == camera.intrinsics;
    for (int k = 0; k < 16 && same; ++k)
      same = std::abs(other.world_to_camera.m[k] - camera.world_to_camera.m[k]) <= 1e-9;
    if (same) out.push_back(int(u));
  }
  return out;
}

// A truth of view v: the clean view when the scene has one, else the stored
// one.
torch::Tensor truth_of(const io::Scene& scene, int v) {
  return scene.has_clean() ? scene.clean_image(v) : scene.image(v);
}

// The scene bands a broad band of the index weighs (its row of the band map).
std::vector<int> weighed_bands(const torch::Tensor& row) {  // [N]
  std::vector<int> out;
  for (int64_t b = 0; b < row.size(0); ++b)
    if (row[b].item<double>() != 0) out.push_back(int(b));
  return out;
}

// The views an index truth of view v is computed from: v when it holds
// every band; in a band-per-view scene, the views at its pose. core::Error
// when those views lack a band the index weighs.
std::vector<int> index_views(const io::Scene& scene, int v, const VegetationIndex& index,
                             const torch::Tensor& map) {  // [2, N]
  if (scene.views[size_t(v)].bands.empty()) return {v};
  const std::vector<int> group = views_at_pose(scene, v);
  std::vector<bool> held(size_t(scene.bands()), false);
  for (int u : group) {
    const std::vector<int>& own = scene.views[size_t(u)].bands;
    for (int64_t b = 0; b < scene.bands(); ++b)
      held[size_t(b)] =
          held[size_t(b)] || own.empty() || std::find(own.begin(), own.end(), int(b)) != own.end();
  }
  for (int row = 0; row < 2; ++row) {
    const BroadBand& broad = row == 0 ? index.a : index.b;
    for (int b : weighed_bands(map[row]))
      if (!held[size_t(b)])
        throw core::Error("--index " + index.name + " --diff",
                          "no view at the pose of " + scene.views[size_t(v)].name + " holds the " +
                              broad.name + " band (" +
                              core::format_g(scene.wavelengths_nm[size_t(b)]) +
                              " nm), so no pixel has a true " + index.name +
                              ": this band-per-view scene's views hold one or a few bands, "
                              "and a rig's band "
                              "cameras each look from their own pose (render the index "
                              "without --diff; "
                              "render --diff and eval compare the bands one by one)");
  }
  return group;
}

// The truth an index of view v is computed from, [H, W, N]: the bands of the
// views index_views gives (zero where none holds a band, which the index
// does not weigh).
torch::Tensor index_truth(const io::Scene& scene, int v, const std::vector<int>& group) {
  if (scene.views[size_t(v)].bands.empty()) return truth_of(scene, v);
  const core::Intrinsics& k = scene.views[size_t(v)].camera.intrinsics;
  torch::Tensor truth = torch::zeros({k.height, k.width, scene.bands()}, torch::kFloat32);
  for (int u : group) {
    const torch::Tensor own = scene.view_bands(u);
    const torch::Tensor values = truth_of(scene, u);
    if (own.defined())
      truth.index_copy_(2, own, values);
    else
      truth.copy_(values);
  }
  return truth;
}

// The part of a band selection that view v of a band-per-view scene holds,
// as indices into its own bands (io::Scene::view_slice's order); none when
// it holds none of the selected bands. Pseudo-RGB (no selection) selects
// every band the view holds, named by them ("band3", "band1-3").
std::optional<BandSelection> own_bands(const io::Scene& scene, int v,
                                       const BandSelection& selection) {
  const std::vector<int>& bands = scene.views[size_t(v)].bands;
  BandSelection own;
  own.pseudo_rgb = false;
  own.first = int64_t(bands.size());
  own.last = -1;
  for (size_t j = 0; j < bands.size(); ++j)
    if (selection.pseudo_rgb || (bands[j] >= selection.first && bands[j] <= selection.last)) {
      own.first = std::min(own.first, int64_t(j));
      own.last = std::max(own.last, int64_t(j));
    }
  if (own.last < 0) return std::nullopt;
  const int lo = bands[size_t(own.first)], hi = bands[size_t(own.last)];
  own.label = !selection.pseudo_rgb ? selection.label
              : lo == hi            ? "band" + std::to_string(lo)
                                    : "band" + std::to_string(lo) + "-" + std::to_string(hi);
  return own;
}

// The error heatmap and truth | render | error of one frame: STEM_diff_maxD.png
// and STEM_compare.png. Returns the number of files written.
int write_comparison(const std::string& stem,
                     const torch::Tensor& image,  // [H, W, C]
                     const torch::Tensor& truth,  // [H, W, C]
                     const std::vector<double>& wavelengths_nm, const BandSelection& bands,
                     const torch::Tensor& shown,  // [H, W, 3] picture of image
                     const RenderOptions& options) {
  const torch::Tensor error =
      error_heatmap(image, truth, bands, options.diff_max, options.colormap);
  io::write_png(stem + "_diff_max" + number_label(options.diff_max) + ".png", error);
  io::write_png(stem + "_compare.png",
                comparison_panels(picture(truth, wavelengths_nm, bands, options.colormap), shown,
                                  error, options.colormap, kColourBarPx));
  return 2;
}

// Per frame of a band-per-view scene, the selection its comparison shows
// (own_bands; none without truth or without a selected band). core::Error
// when a comparison cannot be made: truth mapped to other channels, or no
// frame holding a selected band.
std::vector<std::optional<BandSelection>> own_comparisons(const io::Scene& scene,
                                                          const std::vector<Frame>& frames,
                                                          const RenderOptions& options) {
  std::vector<std::optional<BandSelection>> out(frames.size());
  if (!options.diff || !scene.band_per_view()) return out;
  core::require(!options.band_map.defined(),
                "--diff with --wavelengths or --response maps every band of "
                "the truth to other "
                "channels; the views of this band-per-view scene hold one or a "
                "few bands: drop "
                "them to compare each view's own bands");
  int with_truth = 0, without_band = 0;
  std::string example;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].view < 0 || scene.views[size_t(frames[i].view)].bands.empty()) continue;
    ++with_truth;
    out[i] = own_bands(scene, frames[i].view, options.bands);
    if (out[i]) continue;
    ++without_band;
    if (example.empty()) example = frames[i].name;
  }
  if (without_band == 0) return out;
  core::require(without_band < with_truth,
                "--diff: no view of this band-per-view scene holds the bands of " +
                    options.bands.label + " (each view holds its own band or few)");
  core::log_warn("--diff: " + std::to_string(without_band) + " of " + std::to_string(with_truth) +
                 " views hold none of the bands of " + options.bands.label +
                 " and get no comparison (e.g. " + example + ")");
  return out;
}

// The --index branch of render_frames.
int render_index_frames(const io::Scene& scene, const model::Gaussians& model,
                        const torch::Tensor& background, const std::vector<Frame>& frames,
                        const RenderOptions& options, const fs::path& out_dir) {
  const VegetationIndex& index = *options.index;
  const torch::Tensor map = index_band_map(index, scene.wavelengths_nm);  // [2, N]
  // Every frame's truth is checked before any is rendered.
  if (options.diff)
    for (const Frame& frame : frames)
      if (frame.view >= 0 && !scene.views[size_t(frame.view)].bands.empty())
        index_views(scene, frame.view, index, map);
  io::write_file_atomically(out_dir / "channels.json", channels_record(scene, options));
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
          index_truth(scene, frame.view, index_views(scene, frame.view, index, map)), map);
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

std::string channels_record(const io::Scene& scene, const RenderOptions& options) {
  const bool mapped = options.band_map.defined() && !options.index;
  nlohmann::json record = {
      {"wavelengths_nm", mapped ? options.wavelengths_nm : scene.wavelengths_nm}};
  if (options.index) record["index"] = options.index->name;
  return record.dump(2) + "\n";
}

std::vector<std::string> superseded_files(const std::vector<Frame>& frames,
                                          const RenderOptions& options) {
  std::vector<std::string> names;
  if (options.index) return names;  // index maps have no cubes
  for (const Frame& frame : frames) {
    if (options.format == OutputFormat::Npy) {
      names.push_back(frame.name + ".hdr");
      names.push_back(frame.name + ".img");
    } else if (options.format == OutputFormat::Envi) {
      names.push_back(frame.name + ".npy");
    }
  }
  return names;
}

OutputFormat parse_output_format(const std::string& name) {
  if (name == "png") return OutputFormat::Png;
  if (name == "npy") return OutputFormat::Npy;
  if (name == "envi") return OutputFormat::Envi;
  throw core::Error("--format: expected npy, envi or png, got " + core::quoted_value(name));
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
  if (options.index)
    return 1 + render_index_frames(scene, model, background, frames, options, out_dir);
  if (mapped) model.colour = gaussians.colour.mapped(options.band_map);
  const std::string label = options.bands.label;
  const std::vector<std::optional<BandSelection>> own = own_comparisons(scene, frames, options);
  // After every check that can refuse: a refused render writes nothing.
  io::write_file_atomically(out_dir / "channels.json", channels_record(scene, options));
  int written = 1;  // channels.json
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

    if (own[i]) {
      // A view that holds some of the bands is compared on them.
      const torch::Tensor rendered = scene.view_slice(frame.view, image);
      written += write_comparison(
          stem.string() + "_" + own[i]->label, rendered, truth_of(scene, frame.view), wavelengths,
          *own[i], picture(rendered, wavelengths, *own[i], options.colormap), options);
    } else if (options.diff && frame.view >= 0 && scene.views[size_t(frame.view)].bands.empty()) {
      torch::Tensor truth = truth_of(scene, frame.view);  // [H, W, N]
      if (mapped) truth = torch::matmul(truth, options.band_map.to(truth.scalar_type()).t());
      written += write_comparison(stem.string() + "_" + label, image, truth, wavelengths,
                                  options.bands, shown, options);
    }
    bar.update(int64_t(i + 1));
  }
  bar.finish(std::to_string(written) + " files");
  return written;
}

}  // namespace ddhgs::eval
