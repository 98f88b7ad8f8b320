// `ddhgs synth`: writes a built-in synthetic scene (a potted plant) with
// clean ground truth. Every size is a flag overriding the preset.
#include <memory>

#include "app/number_list.h"
#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "io/files/output_folder.h"
#include "synth/generate.h"
#include "synth/variant.h"

namespace ddhgs::app {
namespace cmd_synth {

struct SynthArgs {
  std::string preset = "demo";
  std::string out;
  bool force = false;
  synth::SynthConfig flags;  // values of the flags given; others unused
  bool no_ground = false;
  bool noisy_edges = false;
  bool gcp_targets = false;
  bool novel_views = false;
  bool vary = false;
  std::string light_factors;  // comma-separated, one per capture
  std::string gps_origin;     // LAT,LON
};

// Copies each given flag onto the preset's configuration (with --vary, onto
// its variant's framing).
synth::SynthConfig resolve(const SynthArgs& a, CLI::App* cmd) {
  synth::SynthConfig c = synth::preset_config(a.preset);
  auto set = [&](const char* name, auto& field, const auto& value) {
    if (cmd->get_option(name)->count() > 0) field = value;
  };
  const auto& f = a.flags;
  set("--seed", c.seed, f.seed);
  if (a.vary) {
    c.vary = true;
    // A rig preset is refused by validate; its framing is not a ring's.
    if (!c.rig) synth::vary_framing(c);
  }
  set("--width", c.width, f.width);
  set("--height", c.height, f.height);
  set("--bands", c.bands, f.bands);
  set("--wl-min", c.wl_min_nm, f.wl_min_nm);
  set("--wl-max", c.wl_max_nm, f.wl_max_nm);
  set("--views", c.views, f.views);
  set("--rings", c.rings, f.rings);
  set("--elevation-min", c.min_elevation_deg, f.min_elevation_deg);
  set("--elevation-max", c.max_elevation_deg, f.max_elevation_deg);
  set("--fov-deg", c.fov_deg, f.fov_deg);
  set("--fill", c.fill, f.fill);
  set("--k1", c.k1, f.k1);
  set("--supersample", c.supersample, f.supersample);
  set("--noise-scale", c.noise_scale, f.noise_scale);
  set("--points", c.points, f.points);
  set("--point-jitter", c.point_jitter, f.point_jitter);
  set("--light-change", c.light_change, f.light_change);
  if (!a.light_factors.empty())
    c.light_factors = parse_number_list(a.light_factors, "--light-factors");
  set("--overlap", c.overlap, f.overlap);
  set("--lines", c.lines, f.lines);
  set("--side-overlap", c.side_overlap, f.side_overlap);
  set("--altitude", c.altitude_m, f.altitude_m);
  set("--field-spacing", c.field_spacing_m, f.field_spacing_m);
  set("--rig-perturb-deg", c.rig_perturb_deg, f.rig_perturb_deg);
  set("--rig-offset-cm", c.rig_offset_cm, f.rig_offset_cm);
  set("--gps-noise", c.gps_noise_m, f.gps_noise_m);
  if (!a.gps_origin.empty()) {
    const std::vector<double> origin = parse_number_list(a.gps_origin, "--gps-origin");
    core::require(origin.size() == 2, "--gps-origin",
                  "expected LAT,LON in degrees, e.g. 51.8091,-0.3727");
    c.gps_latitude_deg = origin[0];
    c.gps_longitude_deg = origin[1];
  }
  if (a.no_ground) c.ground = false;
  if (a.noisy_edges) c.noisy_edges = true;
  if (a.gcp_targets) c.gcp_targets = true;
  if (a.novel_views) c.novel_views = true;
  return c;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "synth", "Write a built-in synthetic hyperspectral scene (potted plant, clean ground truth)");
  auto& f = args->flags;
  cmd->add_option("--preset", args->preset,
                  "demo, bayspec, surface-optics, noisy-edges, rig (raw TIFF captures of a "
                  "5-camera multispectral rig on a ring) or rig-nadir (the rig flown over the "
                  "plant: 8 nadir captures, 70 % overlap)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "Output scene folder")->required();
  cmd->add_flag("--force", args->force, "Replace an existing non-empty output folder");
  cmd->add_option("--seed", f.seed, "Random seed (plant shape and noise)");
  cmd->add_option("--width", f.width, "Image width, pixels");
  cmd->add_option("--height", f.height, "Image height, pixels");
  cmd->add_option("--bands", f.bands, "Number of spectral bands");
  cmd->add_option("--wl-min", f.wl_min_nm, "First band centre, nm");
  cmd->add_option("--wl-max", f.wl_max_nm, "Last band centre, nm");
  cmd->add_option("--views", f.views, "Number of camera views");
  cmd->add_option("--rings", f.rings, "Camera rings (elevations) of the turntable");
  cmd->add_option("--elevation-min", f.min_elevation_deg, "Lowest ring elevation, degrees");
  cmd->add_option("--elevation-max", f.max_elevation_deg, "Highest ring elevation, degrees");
  cmd->add_option("--fov-deg", f.fov_deg, "Horizontal field of view, degrees");
  cmd->add_option("--fill", f.fill, "Fraction of the frame (each axis) the plant fills");
  cmd->add_option("--k1", f.k1,
                  "Radial lens distortion of every camera (OPENCV k1, negative: barrel); the "
                  "views are undistorted when the scene loads");
  cmd->add_option("--supersample", f.supersample, "Rays per pixel along each axis");
  cmd->add_option("--noise-scale", f.noise_scale, "Multiplies the noise standard deviation");
  cmd->add_option("--points", f.points, "Sparse points in points.ply (about)");
  cmd->add_option("--point-jitter", f.point_jitter, "Point position noise, scene units");
  cmd->add_option("--light-change", f.light_change,
                  "Rig presets: each capture's true light is its DLS reading times a factor "
                  "drawn from the seed within 1 +- this (0.2: up to 20 %), which the DLS and "
                  "the panel do not see; the factors go to synth.json");
  cmd->add_option("--light-factors", args->light_factors,
                  "Rig presets: each capture's light factor, one per capture "
                  "(\"1,0.8,1.1,...\"), instead of drawn ones");
  cmd->add_option("--overlap", f.overlap,
                  "rig-nadir: forward overlap of neighbouring captures on a line (0.7: 70 % of "
                  "a frame's length)");
  cmd->add_option("--lines", f.lines,
                  "rig-nadir: fly the --views captures as this many parallel lines (a grid; "
                  "--views a multiple of it), back and forth");
  cmd->add_option("--side-overlap", f.side_overlap,
                  "rig-nadir: overlap of neighbouring lines, of a frame's width across them "
                  "(default 0.6)");
  cmd->add_option("--altitude", f.altitude_m,
                  "rig-nadir: flying height above the ground, metres (default: three plant "
                  "heights, about 3.5 m)");
  cmd->add_option("--field-spacing", f.field_spacing_m,
                  "rig-nadir: a field of plants this many metres apart (jittered) on ground "
                  "covering every capture, instead of one plant on its disc");
  cmd->add_option("--rig-perturb-deg", f.rig_perturb_deg,
                  "rig presets: each band camera but camera 1 truly sits turned by this many "
                  "degrees (random axis) from its factory RigRelatives, which its metadata keeps");
  cmd->add_option("--rig-offset-cm", f.rig_offset_cm,
                  "rig presets: each band camera but camera 1 truly sits this many cm (metres "
                  "are scene units) from camera 1, across the rig's face");
  cmd->add_option("--gps-origin", args->gps_origin,
                  "rig presets: the world origin's WGS84 latitude and longitude (LAT,LON "
                  "degrees; default 51.8091,-0.3727, a field in England, ground 120 m above the "
                  "ellipsoid); every capture's EXIF GPS is its true position from there (world "
                  "x east, y north, metres)");
  cmd->add_option("--gps-noise", f.gps_noise_m,
                  "rig presets: each capture's EXIF GPS is off its true position by a normal "
                  "error of this standard deviation (metres) along east, north and up, drawn "
                  "from --seed; synth.json records each error (default 0: exact)");
  cmd->add_flag("--gcp-targets", args->gcp_targets,
                "rig-nadir: print the ground control points on the ground as survey targets "
                "(black and white 2 x 2 checkers, 10 ground pixels a side, centred on each "
                "point); other pixels stay as they are");
  cmd->add_flag("--novel-views", args->novel_views,
                "rig-nadir: cubes/ also gets held-out captures the flight did not take, "
                "midway between its neighbouring captures and lines (NOVEL_NNNN, in the test "
                "split beside the flight's own held-out captures), to measure a model over the "
                "whole survey");
  cmd->add_flag("--vary", args->vary,
                "A randomised variant of the preset drawn from --seed (plant shape, size and "
                "leaf count, leaf, pot, soil, ground and backdrop spectra, light direction, level "
                "and colour, backdrop or none, camera fill, field of view and rings; ranges in "
                "docs/commands.md), recorded in synth.json's variant; other flags override it");
  cmd->add_flag("--no-ground", args->no_ground, "Leave out the ground disc");
  cmd->add_flag("--noisy-edges", args->noisy_edges, "Much noisier edge bands (ablations)");
  return [args, cmd] {
    synth::SynthConfig config = resolve(*args, cmd);
    // Refused before the announcement: a refusal is the only line printed.
    synth::validate(config);
    io::check_output_folder({args->out, io::OutputKind::Scene, args->force, {}});
    core::log_info("synth: preset " + config.preset + ", " + std::to_string(config.views) +
                   " views of " + std::to_string(config.width) + "x" +
                   std::to_string(config.height) + " px, " + std::to_string(config.bands) +
                   " bands -> " + args->out);
    auto result = synth::write_synthetic_scene(config, args->out, args->force);
    core::log_info("synth: wrote " + std::to_string(result.views) + " views and " +
                   std::to_string(result.points) + " points in " +
                   core::format_duration(result.seconds));
    return 0;
  };
}

Registrar registrar("synth", 10, setup);

}  // namespace cmd_synth
}  // namespace ddhgs::app
