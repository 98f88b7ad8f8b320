// `ddhgs export RUN`: the trained model as a standard three-channel 3DGS file
// (PLY with SH, or .splat) for the viewers and editors people already use,
// coloured by pseudo-RGB, three chosen bands or one band, optionally cropped.
#include <cctype>
#include <cstdio>
#include <filesystem>

#include "app/number_list.h"
#include "app/registry.h"
#include "app/trained_run.h"
#include "core/error.h"
#include "core/text.h"
#include "eval/rgb_export.h"
#include "io/files/output_file.h"
#include "io/ply/ply.h"
#include "io/splat/splat.h"

namespace ddhgs::app {
namespace cmd_export {
namespace fs = std::filesystem;

struct ExportArgs {
  std::string run, out;
  std::string format = "ply";
  std::string bands, crop;
  double band_nm = 0;
  std::string colormap = "gray";
  bool linear = false;
  double min_opacity = 0;
};

// "a,b,c" -> exactly `expected` numbers; core::Error naming the option otherwise.
std::vector<double> parse_numbers(const std::string& text, const std::string& option,
                                  size_t expected) {
  std::vector<double> values = parse_number_list(text, option);
  core::require(values.size() == expected, option + ": expected " + std::to_string(expected) +
                                               " comma-separated numbers, got " +
                                               core::quoted_value(text));
  return values;
}

eval::ColourMapping choose_mapping(const ExportArgs& args, const CLI::App& cmd,
                                   const io::GaussianPly& ply) {
  if (!args.bands.empty())
    return eval::band_mapping(ply.wavelengths_nm, parse_numbers(args.bands, "--bands", 3));
  if (cmd.count("--band") > 0)
    return eval::single_band_mapping(ply.wavelengths_nm, args.band_nm,
                                     eval::parse_colormap(args.colormap));
  return eval::cie_mapping(ply.wavelengths_nm, ply.bands(), !args.linear);
}

eval::Crop choose_crop(const ExportArgs& args) {
  eval::Crop crop;
  crop.min_opacity = args.min_opacity;
  if (args.crop.empty()) return crop;
  std::vector<double> v = parse_numbers(args.crop, "--crop", 6);
  for (int axis = 0; axis < 3; ++axis)
    core::require(v[size_t(axis)] <= v[size_t(axis) + 3],
                  "--crop: the box's minimum exceeds its maximum on axis " +
                      std::string(1, "xyz"[axis]) + " (give min x,y,z then max x,y,z)");
  crop.box = std::array<double, 6>{v[0], v[1], v[2], v[3], v[4], v[5]};
  return crop;
}

// The format: --format, else the extension of --out (.splat), else ply.
std::string choose_format(const ExportArgs& args, const CLI::App& cmd) {
  if (cmd.count("--format") > 0 || args.out.empty()) return args.format;
  std::string ext = fs::path(args.out).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".splat" ? "splat" : "ply";
}

// Before any work: a file of the format's kind that is none of the run's own
// files (its gaussians.ply above all).
void check_out(const fs::path& out, const std::string& format, const fs::path& run) {
  io::require_extension(out, "--out", {format == "splat" ? ".splat" : ".ply"});
  std::vector<std::pair<std::string, fs::path>> run_files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(run, ec))
    if (entry.is_regular_file(ec))
      run_files.push_back({"a file of the run " + run.string(), entry});
  io::require_distinct(out, "--out", run_files);
}

int run(const ExportArgs& given, const CLI::App& cmd) {
  ExportArgs args = given;
  args.format = choose_format(given, cmd);
  if (!args.out.empty()) check_out(args.out, args.format, args.run);
  RunModel run = open_run_model(args.run);
  const eval::ColourMapping mapping = choose_mapping(args, cmd, run.ply);
  const int64_t total = run.ply.means.size(0);
  const torch::Tensor kept = eval::crop_indices(run.ply, choose_crop(args));
  core::require(kept.numel() > 0, "--crop/--min-opacity: no Gaussian of the " +
                                      std::to_string(total) + " is left; loosen the crop");
  torch::NoGradGuard no_grad;
  const io::GaussianPly rgb = eval::map_colours(eval::select_rows(run.ply, kept), mapping);
  const fs::path out = args.out.empty() ? run.root / "export" / ("gaussians_rgb." + args.format)
                                        : fs::path(args.out);
  if (args.format == "splat")
    io::write_splat(out, rgb);
  else
    io::write_gaussian_ply(out, rgb);

  const torch::Tensor background = eval::map_background(run.background, mapping);
  std::printf("exported %lld of %lld Gaussians, colour: %s, SH degree %d\n",
              static_cast<long long>(kept.numel()), static_cast<long long>(total),
              mapping.description.c_str(), args.format == "splat" ? 0 : rgb.sh_degree());
  std::printf("background (as rendered by the run, for render-ply --background): %.6g,%.6g,%.6g\n",
              background[0].item<double>(), background[1].item<double>(),
              background[2].item<double>());
  std::printf("wrote %s (%.1f MB)\n", out.string().c_str(), double(fs::file_size(out)) / 1e6);
  return 0;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<ExportArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "export",
      "Export a trained run as a standard 3-channel 3DGS file (PLY with SH, or .splat) for "
      "common viewers and editors, coloured by pseudo-RGB (CIE 1931 + D65, as `render`), three "
      "bands, or one band");
  cmd->add_option("run", args->run, "Run folder written by ddhgs train")->required();
  cmd->add_option("--out", args->out, "Output file (default RUN/export/gaussians_rgb.FORMAT)");
  cmd->add_option("--format", args->format,
                  "ply: 3DGS PLY with f_dc_0..2 and f_rest_* (view dependence kept); splat: "
                  "antimatter15 .splat, 32 bytes per Gaussian, no view dependence (default: "
                  "from the extension of --out, else ply)")
      ->check(CLI::IsMember({"ply", "splat"}))
      ->capture_default_str();
  auto* bands = cmd->add_option(
      "--bands", args->bands,
      "Three wavelengths (nm) shown as R,G,B, nearest band each: 650,550,450 true colour, "
      "800,660,550 a NIR false-colour composite (default: pseudo-RGB)");
  auto* band = cmd->add_option("--band", args->band_nm,
                               "One wavelength (nm), nearest band, as grey or --colormap")
                   ->excludes(bands);
  cmd->add_option("--colormap", args->colormap, "Colour map for --band")
      ->check(CLI::IsMember({"gray", "grey", "viridis"}))
      ->needs(band)
      ->capture_default_str();
  cmd->add_flag("--linear", args->linear,
                "Pseudo-RGB in linear light, without the sRGB curve (for tools that apply the "
                "curve to the rendered image)")
      ->excludes(bands)
      ->excludes(band);
  cmd->add_option("--crop", args->crop,
                  "Keep Gaussians whose centre lies in the box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX "
                  "(scene units)");
  cmd->add_option("--min-opacity", args->min_opacity, "Keep Gaussians at least this opaque (0-1)")
      ->check(within(0, 1))
      ->capture_default_str();
  return [args, cmd] { return run(*args, *cmd); };
}

const Registrar registrar("export", 58, setup);

}  // namespace cmd_export
}  // namespace ddhgs::app
