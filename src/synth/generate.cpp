#include "synth/generate.h"

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/transforms/transforms.h"
#include "synth/render.h"
#include "synth/rig_scene.h"
#include "synth/variant.h"

namespace ddhgs::synth {

namespace fs = std::filesystem;

std::vector<double> SynthConfig::wavelengths_nm() const {
  std::vector<double> out;
  for (int i = 0; i < bands; ++i)
    out.push_back(bands == 1 ? wl_min_nm : wl_min_nm + (wl_max_nm - wl_min_nm) * i / (bands - 1));
  return out;
}

std::vector<std::string> preset_names() {
  return {"demo", "bayspec", "surface-optics", "noisy-edges", "rig", "rig-nadir"};
}

SynthConfig preset_config(const std::string& name) {
  SynthConfig c;
  c.preset = name;
  if (name == "demo") return c;
  if (name == "rig-nadir") {  // the rig flown over the plant: 8 nadir captures, 70 % overlap
    c = preset_config("rig");
    c.preset = name;
    c.nadir = true;
    c.views = 8;
    c.overlap = 0.7;
    return c;
  }
  if (name == "rig") {  // a RedEdge-MX's five band cameras, 1/8 of its 1280 x 960 pixels
    c.rig = true;
    c.width = 160;
    c.height = 120;
    c.bands = 5;
    c.wl_min_nm = 475;
    c.wl_max_nm = 842;
    c.views = 24;
    c.rings = 1;
    c.min_elevation_deg = c.max_elevation_deg = 30;
    c.fov_deg =
        2 * std::atan(2.4 / 5.4) * 180 / 3.14159265358979323846;  // 4.8 mm sensor, 5.4 mm lens
    c.supersample = 2;
    c.points = 2000;
    return c;
  }
  if (name == "noisy-edges") {
    c.noisy_edges = true;
    return c;
  }
  if (name == "bayspec") {  // BaySpec turntable: 640 x 512, 141 bands, 433 views
    c.width = 640;
    c.height = 512;
    c.bands = 141;
    c.wl_min_nm = 400;
    c.wl_max_nm = 1100;
    c.views = 433;
    c.rings = 5;
    c.min_elevation_deg = 5;
    c.max_elevation_deg = 65;
    c.fov_deg = 35;
    c.supersample = 2;
    c.points = 5000;
    return c;
  }
  if (name == "surface-optics") {  // tripod 2 m away, narrow field of view
    c.width = 696;
    c.height = 520;
    c.bands = 128;
    c.wl_min_nm = 370;
    c.wl_max_nm = 1100;
    c.views = 48;
    c.rings = 2;
    c.min_elevation_deg = 8;
    c.max_elevation_deg = 25;
    c.fov_deg = 9;
    c.supersample = 2;
    c.points = 4000;
    return c;
  }
  std::string names;
  for (const auto& n : preset_names()) names += (names.empty() ? "" : ", ") + n;
  throw core::Error("--preset " + name + ": expected one of " + names);
}

void validate(const SynthConfig& c) {
  core::require(c.width >= 8 && c.height >= 8, "synth: expected --width and --height >= 8");
  core::require(c.bands >= 1 && c.bands <= 10000, "synth: expected 1 <= --bands <= 10000");
  core::require(c.views >= 1 && c.views <= 100000, "synth: expected 1 <= --views <= 100000");
  core::require(c.bands == 1 || c.wl_max_nm > c.wl_min_nm, "synth: expected --wl-max > --wl-min");
  core::require(c.wl_min_nm > 0, "synth: expected --wl-min > 0 nm");
  core::require(c.fov_deg > 0 && c.fov_deg < 170, "synth: expected 0 < --fov-deg < 170");
  core::require(std::abs(c.k1) < 1, "synth: expected -1 < --k1 < 1");
  core::require(c.noise_scale >= 0, "synth: expected --noise-scale >= 0");
  core::require(c.supersample >= 1 && c.supersample <= 8,
                "synth: expected 1 <= --supersample <= 8");
  core::require(c.points >= 0 && c.points <= 10000000, "synth: expected 0 <= --points <= 10000000");
  // A fill of 0 places the cameras infinitely far away: null camera matrices.
  core::require(c.fill > 0 && c.fill <= 1, "synth: expected 0 < --fill <= 1");
  core::require(c.rings >= 1 && c.rings <= 1000, "synth: expected 1 <= --rings <= 1000");
  core::require(c.min_elevation_deg > -90 && c.max_elevation_deg < 90 &&
                    c.min_elevation_deg <= c.max_elevation_deg,
                "synth: expected -90 < --elevation-min <= --elevation-max < 90 degrees");
  core::require(c.point_jitter >= 0, "synth: expected --point-jitter >= 0");
  // UTM's range, which world_placement (synth/geo_truth.h) needs.
  core::require(
      c.gps_latitude_deg >= -80 && c.gps_latitude_deg <= 84 && std::abs(c.gps_longitude_deg) <= 180,
      "synth: expected --gps-origin within latitude -80 to 84 and longitude -180 to "
      "180 degrees (UTM's range)");
  core::require(c.light_change >= 0 && c.light_change < 1,
                "synth: expected 0 <= --light-change < 1");
  core::require(c.light_change == 0 || c.light_factors.empty(),
                "synth: give --light-change or --light-factors, not both");
  core::require(c.rig || (c.light_change == 0 && c.light_factors.empty()),
                "synth: --light-change and --light-factors are for the rig presets (rig, "
                "rig-nadir)");
  core::require(c.light_factors.empty() || int(c.light_factors.size()) == c.views,
                "synth: --light-factors has " + std::to_string(c.light_factors.size()) +
                    " values; expected one per capture (--views " + std::to_string(c.views) + ")");
  for (double f : c.light_factors)
    core::require(std::isfinite(f) && f > 0 && f <= 10,
                  "synth: expected every --light-factors value > 0 and <= 10");
  core::require(c.rig_perturb_deg >= 0 && c.rig_perturb_deg <= 10,
                "synth: expected 0 <= --rig-perturb-deg <= 10 degrees");
  core::require(c.rig_offset_cm >= 0 && c.rig_offset_cm <= 100,
                "synth: expected 0 <= --rig-offset-cm <= 100");
  core::require(c.lines >= 1 && c.lines <= c.views && c.views % c.lines == 0,
                "synth: --lines " + std::to_string(c.lines) + ": expected a divisor of --views " +
                    std::to_string(c.views));
  core::require(c.overlap > 0 && c.overlap < 1, "synth: expected 0 < --overlap < 1");
  core::require(c.side_overlap >= 0 && c.side_overlap < 1,
                "synth: expected 0 <= --side-overlap < 1");
  core::require(c.altitude_m == 0 || (c.altitude_m >= 1.5 && c.altitude_m <= 1000),
                "synth: expected --altitude 0 (automatic) or 1.5 to 1000 m");
  core::require(c.field_spacing_m == 0 || (c.field_spacing_m >= 1.5 && c.field_spacing_m <= 100),
                "synth: expected --field-spacing 0 (one plant) or 1.5 to 100 m");
  core::require(c.nadir || (c.lines == 1 && c.altitude_m == 0 && c.field_spacing_m == 0 &&
                            !c.gcp_targets && !c.novel_views),
                "synth: --lines, --altitude, --field-spacing, --gcp-targets and --novel-views need "
                "--preset rig-nadir");
  core::require(!c.novel_views || c.views / c.lines >= 2,
                "synth: --novel-views needs at least two captures a line to lie between");
  core::require(c.gps_noise_m >= 0 && c.gps_noise_m <= 100,
                "synth: expected 0 <= --gps-noise <= 100 (metres)");
  core::require(!c.rig || !c.vary,
                "synth: --vary is for the ring presets (demo, bayspec, surface-optics, "
                "noisy-edges)");
  core::require(c.rig || c.gps_noise_m == 0, "synth: --gps-noise needs --preset rig or rig-nadir");
  core::require(c.rig || (c.rig_perturb_deg == 0 && c.rig_offset_cm == 0),
                "synth: --rig-perturb-deg and --rig-offset-cm need --preset rig or rig-nadir");
  // One view is rendered as float32 [H, W, B] at a time; more than this is a typo.
  const double view_gib = double(c.width) * double(c.height) * double(c.bands) * 4.0 / (1 << 30);
  core::require(c.width <= 16384 && c.height <= 16384 && view_gib <= 4.0,
                "synth: --width x --height x --bands is " + std::to_string(view_gib) +
                    " GiB per view as float32 (at most 16384 pixels a side and 4 GiB)");
}

namespace {

// float [H, W, N] in [0, 1] -> uint16 samples held in int16 (see io::SampleType).
torch::Tensor to_u16(const torch::Tensor& unit) {
  auto v = (unit.clamp(0, 1) * 65535.0f).round().to(torch::kInt32);
  return torch::where(v > 32767, v - 65536, v).to(torch::kInt16);
}

std::string view_name(int view, int views) {
  size_t digits = std::max<size_t>(3, std::to_string(views - 1).size());
  std::string number = std::to_string(view);
  return "r_" + std::string(digits - std::min(digits, number.size()), '0') + number;
}

nlohmann::json describe(const SynthConfig& c, const SpectralSetup& setup, const PlantScene& scene,
                        const SceneVariant& variant) {
  nlohmann::json j;
  j["generator"] = "ddhgs synth";
  j["preset"] = c.preset;
  j["seed"] = c.seed;
  j["width"] = c.width;
  j["height"] = c.height;
  j["bands"] = c.bands;
  j["wavelengths_nm"] = setup.wavelengths_nm;
  j["views"] = c.views;
  j["rings"] = c.rings;
  j["elevation_deg"] = {c.min_elevation_deg, c.max_elevation_deg};
  j["fov_deg"] = c.fov_deg;
  j["fill"] = c.fill;
  j["k1"] = c.k1;
  j["supersample"] = c.supersample;
  j["ground"] = c.ground;
  j["leaves"] = scene.leaves.size();
  j["points"] = c.points;
  j["point_jitter"] = c.point_jitter;
  j["cube_dtype"] = "uint16 (value / 65535)";
  j["clean_folder"] = "clean";
  j["images"] = "pseudo-RGB (CIE 1931, D65) of the clean cube divided by band_gain";
  j["noise"] = {
      {"model", "std = scale * sqrt(shot * s / q + (read / q)^2), q = response^edge_power"},
      {"shot", setup.noise.shot},
      {"read", setup.noise.read},
      {"scale", setup.noise.scale},
      {"edge_power", setup.noise.edge_power}};
  j["sensor_response"] = setup.response;
  j["band_gain"] = setup.band_gain;
  j["lighting"] = {
      {"to_light",
       {setup.lighting.to_light.x, setup.lighting.to_light.y, setup.lighting.to_light.z}},
      {"sun", setup.lighting.sun},
      {"ambient", setup.lighting.ambient},
      {"backdrop", setup.lighting.backdrop}};
  if (c.vary) j["variant"] = describe_variant(variant);
  return j;
}

}  // namespace

SynthResult write_synthetic_scene(const SynthConfig& config, const fs::path& out, bool force) {
  if (config.rig) return write_synthetic_rig(config, out, force);
  validate(config);
  auto start = std::chrono::steady_clock::now();
  SynthResult result;
  io::write_folder_atomically({out, io::OutputKind::Scene, force, {}}, [&](const fs::path& tmp) {
    for (const char* sub : {"hyperspectral", "clean", "images"}) fs::create_directories(tmp / sub);
    // The default variant is the presets' plant and light.
    const SceneVariant variant = config.vary ? draw_variant(config.seed) : SceneVariant{};
    PlantScene scene = PlantScene::build(config.seed, config.ground, variant.plant);
    NoiseModel noise;
    noise.scale = config.noise_scale;
    noise.edge_power = config.noisy_edges ? 2.0 : 1.0;
    SpectralSetup setup =
        make_spectral_setup(scene, config.wavelengths_nm(), noise, variant.lighting);
    auto cameras = turntable_rig(scene, rig_options(config));

    io::TransformsFile transforms;
    transforms.wavelengths_nm = setup.wavelengths_nm;
    transforms.ply_file_path = "points.ply";
    std::vector<float> xyz, spectra;
    std::vector<uint8_t> rgb;
    const int per_view = (config.points + config.views - 1) / config.views;
    core::ProgressBar bar("synth", int64_t(cameras.size()));
    for (int v = 0; v < int(cameras.size()); ++v) {
      const std::string name = view_name(v, config.views);
      torch::Tensor clean = render_clean(scene, setup, cameras[v], config.supersample);
      // One generator per view, seeded from (seed, view): results do not
      // depend on the thread count or on which views are rendered.
      std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), uint32_t(v), 0x5eedu};
      std::mt19937_64 rng(seq);
      torch::Tensor noisy = add_noise(clean, setup, rng);
      torch::Tensor image =
          core::pseudo_rgb_u8(radiance_factor(clean, setup), setup.wavelengths_nm);
      io::write_npy(tmp / "hyperspectral" / (name + ".npy"), to_u16(noisy), io::SampleType::U16);
      io::write_npy(tmp / "clean" / (name + ".npy"), to_u16(clean), io::SampleType::U16);
      io::write_png(tmp / "images" / (name + ".png"), image);

      ViewPoints points =
          sample_points(scene, cameras[v], clean, per_view, config.point_jitter, rng);
      xyz.insert(xyz.end(), points.xyz.begin(), points.xyz.end());
      spectra.insert(spectra.end(), points.spectra.begin(), points.spectra.end());
      auto flat = image.reshape({-1, 3});
      for (int64_t pixel : points.pixels)
        for (int ch = 0; ch < 3; ++ch) rgb.push_back(flat[pixel][ch].item<uint8_t>());

      io::TransformsFrame frame;
      frame.file_path = "images/" + name + ".png";
      frame.hyperspectral_file_path = "hyperspectral/" + name + ".npy";
      frame.intrinsics = cameras[v].intrinsics;
      frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(cameras[v].world_to_camera);
      transforms.frames.push_back(frame);
      bar.update(v + 1);
    }
    bar.finish();

    io::PointCloud cloud;
    const int64_t count = int64_t(xyz.size() / 3);
    cloud.xyz = torch::from_blob(xyz.data(), {count, 3}, torch::kFloat32).clone();
    cloud.rgb = torch::from_blob(rgb.data(), {count, 3}, torch::kUInt8).clone();
    cloud.spectra =
        torch::from_blob(spectra.data(), {count, int64_t(setup.bands())}, torch::kFloat32).clone();
    io::write_point_ply(tmp / "points.ply", cloud);
    io::write_transforms(tmp / "transforms.json", transforms);
    io::write_file_atomically(tmp / "synth.json",
                              describe(config, setup, scene, variant).dump(2) + "\n");

    result.views = int(cameras.size());
    result.points = int(count);
  });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace ddhgs::synth
