// `ddhgs render RUN`: a trained run's views, or an orbit around the scene, as
// cubes and pictures (pseudo-RGB, a band or band range, error heatmaps),
// optionally after the run's diffusion denoiser (--denoise K).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "app/ortho_render.h"
#include "app/registry.h"
#include "app/trained_run.h"
#include "core/band_map.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "eval/denoised_eval.h"
#include "eval/evaluate.h"
#include "eval/render_frames.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"
#include "io/response/response_csv.h"

namespace ddhgs::app {
namespace cmd_render {
namespace fs = std::filesystem;

struct RenderArgs {
  std::string run;
  std::string split = "test";
  int orbit = 0;
  std::string out;
  std::string format = "png";
  std::string band_range;
  std::string band;
  std::string colormap = "viridis";
  bool diff = false;
  double diff_max = 0.1;
  std::string data;
  std::string wavelengths;
  std::string response;
  std::string index;
  int64_t denoise = 0;
  bool ddpm = false;
  SamplerFlags sampler;
  bool ortho = false;
  double gsd_m = 0;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "render", "Render a trained run's views or an orbit to cubes and pictures");
  cmd->add_option("run", args->run, "Run folder written by ddhgs train")->required();
  auto* split = cmd->add_option("--split", args->split, "Dataset views to render")
                    ->check(CLI::IsMember({"test", "train", "all"}))
                    ->capture_default_str();
  cmd->add_option("--orbit", args->orbit,
                  "Render N frames on a smooth orbit fitted to the training cameras instead")
      ->check(within(1, 100000))
      ->excludes(split);
  cmd->add_option("--out", args->out,
                  "Output folder (default RUN/renders/<split> or RUN/renders/orbit)");
  cmd->add_option("--format", args->format,
                  "png: pictures only; npy or envi: float32 cubes as well")
      ->check(CLI::IsMember({"png", "npy", "envi"}))
      ->capture_default_str();
  auto* bands = cmd->add_option("--bands", args->band_range,
                                "Show the mean of the bands in MIN:MAX nm (default pseudo-RGB)");
  cmd->add_option("--band", args->band, "Show one band, by index")->excludes(bands);
  cmd->add_option("--colormap", args->colormap, "Colour map for bands and error heatmaps")
      ->check(CLI::IsMember({"viridis", "gray", "grey"}))
      ->capture_default_str();
  cmd->add_flag("--diff", args->diff,
                "For views with ground truth, also an error heatmap and a truth | render | error "
                "comparison");
  cmd->add_option(
         "--diff-max", args->diff_max,
         "Absolute error (reflectance; index units with --index) at the top of the heatmap "
         "scale")
      ->check(within(1e-12, 1e12))
      ->capture_default_str();
  cmd->add_option("--data", args->data, "Dataset folder, if it moved since training");
  auto* wavelengths = cmd->add_option(
      "--wavelengths", args->wavelengths,
      "Render these wavelengths instead of the captured bands (nm): START:STOP:STEP, e.g. "
      "450:950:5, or a list 550,670.5; interpolated between captured bands");
  cmd->add_option("--response", args->response,
                  "Render what another sensor sees: a CSV of spectral response functions "
                  "(wavelength_nm, one column per channel; examples/responses/)")
      ->excludes(wavelengths);
  cmd->add_option("--index", args->index,
                  "A vegetation index map instead of band pictures: ndvi, ndre or gndvi (bands "
                  "averaged over MicaSense RedEdge-MX's windows; -1 red to 1 green, colour bar "
                  "below; with --diff also against the views' own index)")
      ->excludes(wavelengths)
      ->excludes(bands)
      ->excludes("--band")
      ->excludes("--response");
  auto* denoise = cmd->add_option(
      "--denoise", args->denoise,
      "Denoise every render with the run's diffusion denoiser, DDIM with this many steps");
  denoise->check(within(1, 100000));
  cmd->add_flag("--ddpm", args->ddpm,
                "Denoise with full ancestral DDPM sampling instead (every step; slow)")
      ->excludes(denoise);
  add_sampler_flags(cmd, args->sampler);
  auto* ortho = cmd->add_flag(
      "--ortho", args->ortho,
      "An orthomosaic instead of views: the model straight down over the flight's footprint as "
      "Cloud-Optimised GeoTIFFs in the scene's CRS (needs georef.json: process --rig with GPS); "
      "reflectance bands, or with --index the index map; --bands MIN:MAX keeps those bands");
  for (const char* other : {"--orbit", "--split", "--format", "--band", "--colormap", "--diff",
                            "--diff-max", "--wavelengths", "--response", "--denoise", "--ddpm",
                            "--start-strength", "--eta", "--samples"})
    ortho->excludes(other);
  cmd->add_option("--gsd", args->gsd_m,
                  "With --ortho: ground sample distance, metres per pixel (default the flight's "
                  "own: the cameras' median height above the ground over their focal length)")
      ->check(within(1e-4, 1e4))
      ->needs(ortho);
  return [args] {
    TrainedRun run = open_trained_run(args->run, args->data);
    if (args->ortho) {
      write_orthomosaic(run, {args->gsd_m, args->index, args->band_range, args->out});
      return 0;
    }
    const io::Scene& scene = *run.scene;
    eval::RenderOptions options;
    options.format = eval::parse_output_format(args->format);
    std::string folder_suffix;
    if (!args->wavelengths.empty()) {
      options.wavelengths_nm = core::parse_wavelength_list(args->wavelengths, "--wavelengths");
      try {
        options.band_map = core::interpolation_map(scene.wavelengths_nm, options.wavelengths_nm);
      } catch (const core::Error& e) {
        throw core::Error(std::string("--wavelengths: ") + e.what());
      }
      folder_suffix = "_wavelengths";
    } else if (!args->response.empty()) {
      const core::ResponseFunctions response = io::read_response_csv(args->response);
      core::ResponseMap map;
      try {
        map = core::response_map(response, scene.wavelengths_nm);
      } catch (const core::Error& e) {
        throw core::Error(args->response, e.what());
      }
      for (size_t c = 0; c < response.channels.size(); ++c)
        if (map.captured[c] < 0.99)
          core::log_warn("response " + core::quoted_value(response.channels[c]) + ": " +
                         std::to_string(int(std::lround(100 * (1 - map.captured[c])))) +
                         " % of it lies outside the model's bands and is left out");
      // Cubes hold channels by increasing wavelength, as captured cubes do.
      std::vector<size_t> order(map.centres_nm.size());
      for (size_t c = 0; c < order.size(); ++c) order[c] = c;
      std::stable_sort(order.begin(), order.end(),
                       [&](size_t a, size_t b) { return map.centres_nm[a] < map.centres_nm[b]; });
      std::string listed;
      std::vector<int64_t> rows;
      for (size_t c : order) {
        rows.push_back(int64_t(c));
        options.wavelengths_nm.push_back(map.centres_nm[c]);
        listed += (listed.empty() ? "" : ", ") + response.channels[c] + " (" +
                  std::to_string(int(std::lround(map.centres_nm[c]))) + " nm)";
      }
      for (size_t i = 1; i < order.size(); ++i)
        core::require(options.wavelengths_nm[i] > options.wavelengths_nm[i - 1], args->response,
                      "channels " + core::quoted_value(response.channels[order[i - 1]]) + " and " +
                          core::quoted_value(response.channels[order[i]]) +
                          " have the same centre wavelength (" +
                          core::format_g(options.wavelengths_nm[i]) +
                          " nm); a rendered cube holds its channels by increasing wavelength");
      options.band_map = map.map.index_select(0, torch::tensor(rows));
      core::log_info("channels of the rendered cubes, by centre wavelength: " + listed);
      // Its own prefix: a file named ndvi.csv must not render into --index ndvi's folder.
      folder_suffix = "_response_" + fs::path(args->response).stem().string();
    }
    if (!args->index.empty()) {
      options.index = eval::find_vegetation_index(args->index, "--index");
      core::require(options.format != eval::OutputFormat::Envi,
                    "--index: an index map is written as PNG and, with --format npy, as .npy; "
                    "not as ENVI");
      try {
        eval::index_band_map(*options.index, scene.wavelengths_nm);  // its bands exist
      } catch (const core::Error& e) {
        throw core::Error(std::string("--index ") + e.what());
      }
      folder_suffix = "_" + args->index;
    }
    const std::vector<double>& shown =
        options.band_map.defined() ? options.wavelengths_nm : scene.wavelengths_nm;
    options.bands = eval::select_bands(args->band, args->band_range, shown);
    options.colormap = eval::parse_colormap(args->colormap);
    options.diff = args->diff;
    options.diff_max = args->diff_max;
    std::string what = args->orbit > 0 ? "orbit" : args->split;
    std::string folder = what + folder_suffix;
    if (args->denoise > 0 || args->ddpm) {
      core::require(!options.band_map.defined(),
                    "--denoise: the denoiser works on the captured bands; drop --wavelengths or "
                    "--response to denoise");
      core::require(run.denoiser.has_value(), run.root,
                    "this run has no denoiser.pt (trained without loss.diffusion): drop --denoise");
      model::SamplerOptions sampler = sampler_options(run, args->sampler);
      sampler.method = args->ddpm ? model::SamplerMethod::Ddpm : model::SamplerMethod::Ddim;
      if (args->denoise > 0) sampler.steps = args->denoise;
      sampler.validate(run.denoiser->schedule.steps, "--denoise");
      options.transform = [&run, sampler](const torch::Tensor& image) {
        return model::denoise_view(*run.denoiser, image, sampler);
      };
      // The setting's name, as eval reports it: "_ddim10", "_ddim10-mean4", "_ddpm".
      const auto setting = eval::denoise_settings(
          args->ddpm ? std::vector<int64_t>{} : std::vector<int64_t>{sampler.steps}, args->ddpm,
          sampler);
      folder += "_" + setting.front().name;
    }
    const fs::path out_dir =
        args->out.empty() ? run.root / "renders" / folder : fs::path(args->out);

    std::vector<eval::Frame> frames =
        args->orbit > 0 ? eval::orbit_frames(scene, args->orbit)
                        : eval::view_frames(scene, eval::split_views(scene, args->split));
    core::require(!frames.empty(), scene.root, "the " + what + " split has no views to render");
    io::FolderLock lock(run.root, "render");
    int files = 0;
    io::OutputRequest request{out_dir, io::OutputKind::Renders, true, {run.root, scene.root}, ""};
    request.superseded = eval::superseded_files(frames, options);
    const auto build = [&](const fs::path& tmp) {
      files = eval::render_frames(scene, run.gaussians, run.background, frames, options, tmp);
    };
    // Frames join an earlier render's only when they show the same channels.
    std::error_code ec;
    const fs::path record = out_dir / "channels.json";
    const bool same_channels = fs::is_regular_file(record, ec) &&
                               io::read_file(record) == eval::channels_record(scene, options);
    if (same_channels || !fs::exists(out_dir, ec))
      io::write_into_folder_atomically(request, build);
    else
      io::write_folder_atomically(request, build);
    std::cout << "rendered " << frames.size() << " frames (" << what << "): " << files
              << " files in " << out_dir.string() << "\n";
    return 0;
  };
}

Registrar registrar("render", 60, setup);

}  // namespace cmd_render
}  // namespace ddhgs::app
