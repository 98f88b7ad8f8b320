#include "synth/rig_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <random>

#include "core/error.h"
#include "core/log.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/ply/ply.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_radiometry.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "synth/geo_truth.h"
#include "synth/render.h"
#include "synth/survey.h"

namespace ddhgs::synth {
namespace fs = std::filesystem;

namespace {

constexpr double kPi = 3.14159265358979323846;
// A ground control point's target: 10 of the flight's ground pixels a side.
constexpr double kGcpTargetHalfPixels = 5;
// RedEdge-MX: 1280 px across a 4.8 mm sensor (3.75 um pixels), 5.4 mm lens.
constexpr double kSensorWidthMm = 4.8;
constexpr double kFocalMm = 5.4;

// The metadata of band camera `band` in capture `id`, for an image of the
// given size: what a RedEdge-MX writes, with made-up but typical radiometry.
io::RigBandImage band_metadata(const RigBandCamera& band, const core::Intrinsics& k,
                               const std::string& id, double exposure_s) {
  io::RigBandImage b;
  b.capture_id = id;
  b.rig_index = band.index;
  b.band_name = band.name;
  b.centre_nm = band.centre_nm;
  b.fwhm_nm = band.fwhm_nm;
  b.px_per_mm = double(k.width) / kSensorWidthMm;
  b.focal_length_mm = k.fx / b.px_per_mm;
  b.principal_point_mm = {k.cx / b.px_per_mm, k.cy / b.px_per_mm};
  b.distortion = {0, 0, 0, 0, 0};
  b.rig_relatives_deg = band.relatives_deg;
  b.width = k.width;
  b.height = k.height;
  b.bits = 16;
  io::RigRadiometry& r = b.radiometry;
  r.black_level = 4800;
  r.has_black_level = true;
  r.exposure_s = exposure_s;
  r.iso_speed = 100;
  r.calibration = {2.6e-4 + 1e-5 * band.index, 5e-8, 1e-5};
  // About 30 % darker in the corners than in the centre.
  const double corner = 0.5 * std::hypot(double(k.width), double(k.height));
  r.vignetting_centre_px = {0.5 * k.width + 1.5, 0.5 * k.height - 1.0};
  r.vignetting_polynomial = {0.0, -0.3 / (corner * corner)};
  r.irradiance = band.irradiance;
  r.irradiance_tag = "SpectralIrradiance";
  return b;
}

std::string band_file(const std::string& stem, int index) {
  return stem + "_" + std::to_string(index) + ".tif";
}

// A capture's file stem: "IMG_0007" for prefix "IMG" and index 7.
std::string capture_stem(const char* prefix, int index) {
  char stem[32];
  std::snprintf(stem, sizeof stem, "%s_%04d", prefix, index);
  return stem;
}

// A band camera's true placement against its factory one: a rotation
// vector (rad) and a centre offset (m, which are scene units), both in
// camera 1's axes (the rig's frame; camera 1 has none), so that a point at
// x in camera 1's axes is at T R(rotation) (x - offset) in the camera's,
// T its factory rotation (io/rig/rig_layout.h).
struct RigDrift {
  core::Vec3 rotation_rad, offset;
};

std::vector<RigDrift> rig_drifts(const SynthConfig& config, const std::vector<RigBandCamera>& rig) {
  std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), 0x716d7u};
  std::mt19937_64 rng(seq);
  auto uniform = [&] { return double(rng() >> 11) * 0x1.0p-53; };
  std::vector<RigDrift> out(rig.size());
  for (size_t i = 0; i < rig.size(); ++i) {
    // An axis uniform on the sphere; an offset across the rig's face (x, y).
    const double z = 2 * uniform() - 1, phi = 2 * kPi * uniform(), psi = 2 * kPi * uniform();
    if (rig[i].index == 1) continue;
    const double r = std::sqrt(1 - z * z);
    out[i].rotation_rad =
        core::Vec3{r * std::cos(phi), r * std::sin(phi), z} * (config.rig_perturb_deg * kPi / 180);
    out[i].offset = core::Vec3{std::cos(psi), std::sin(psi), 0} * (config.rig_offset_cm / 100);
  }
  return out;
}

std::vector<double> scaled(const core::Vec3& v, double scale) {
  return {v.x * scale, v.y * scale, v.z * scale};
}

}  // namespace

std::vector<double> capture_light_factors(const SynthConfig& config) {
  if (!config.light_factors.empty()) return config.light_factors;
  std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), 0x11647u};
  std::mt19937_64 rng(seq);
  std::uniform_real_distribution<double> change(-config.light_change, config.light_change);
  std::vector<double> factors;
  for (int c = 0; c < config.views; ++c)
    factors.push_back(config.light_change > 0 ? 1 + change(rng) : 1.0);
  return factors;
}

std::vector<RigBandCamera> rededge_rig() {
  return {{1, "Blue", 475, 32, {0, 0, 0}, 1.05, 0.52},
          {2, "Green", 560, 27, {0.45, -0.30, 0.20}, 1.30, 0.53},
          {3, "Red", 668, 14, {-0.50, 0.25, -0.10}, 1.25, 0.53},
          {4, "NIR", 842, 57, {0.30, 0.60, 0.35}, 0.95, 0.51},
          {5, "Red edge", 717, 12, {-0.25, -0.55, 0.30}, 1.15, 0.52}};
}

SynthResult write_synthetic_rig(const SynthConfig& config, const fs::path& out, bool force) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  SynthResult result;
  const std::vector<RigBandCamera> rig = rededge_rig();
  const std::vector<RigDrift> drift = rig_drifts(config, rig);
  std::vector<double> wavelengths;
  for (const RigBandCamera& b : rig) wavelengths.push_back(b.centre_nm);
  io::write_folder_atomically({out, io::OutputKind::Scene, force, {}}, [&](const fs::path& tmp) {
    for (const char* sub :
         {"captures", "panel", "truth/bands", "truth/clean", "cubes/hyperspectral", "cubes/clean"})
      fs::create_directories(tmp / sub);
    PlantScene scene = PlantScene::build(config.seed, config.ground);
    NoiseModel noise;
    noise.scale = config.noise_scale;
    RigOptions options = rig_options(config);
    options.k1 = 0;  // the band images' metadata records no lens distortion
    const Flight flight{config.lines, config.overlap, config.side_overlap, config.altitude_m};
    const std::vector<core::Camera> references =
        config.nadir ? nadir_survey(scene, options, flight) : turntable_rig(scene, options);
    // Before the field grows the ground (the automatic height depends on it).
    const std::vector<core::Camera> novel =
        config.novel_views ? between_captures(scene, options, flight) : std::vector<core::Camera>{};
    if (config.field_spacing_m > 0)
      plant_field(scene, references, config.field_spacing_m, config.seed);
    const core::Intrinsics& k = references.front().intrinsics;
    const std::vector<double> light = capture_light_factors(config);
    const WorldPlacement place = world_placement(config);
    // A survey's truths: the clean scene straight down over the flight's
    // footprint, and marks on the ground, in the projected CRS; printed on
    // the ground as targets when asked.
    OrthoGrid grid;
    nlohmann::json control_points;
    if (config.nadir) {
      grid = flight_footprint(references, place);
      control_points = ground_control_points(place, grid, scene.ground_radius);
      if (config.gcp_targets)
        for (const auto& p : control_points)
          scene.targets.push_back({p["world_xyz"][0].get<double>(), p["world_xyz"][1].get<double>(),
                                   kGcpTargetHalfPixels * grid.pixel});
    }
    // Each capture's GPS error (east, north, up; metres), drawn from its own
    // stream so the images stay as they are without it.
    std::vector<core::Vec3> gps_error(references.size());
    if (config.gps_noise_m > 0) {
      std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), 0x6b5e0u};
      std::mt19937_64 rng(seq);
      std::normal_distribution<double> normal(0.0, config.gps_noise_m);
      for (core::Vec3& e : gps_error) e = {normal(rng), normal(rng), normal(rng)};
    }
    // After the targets: their paint has its own slots.
    const SpectralSetup setup = make_spectral_setup(scene, wavelengths, noise);

    // The panel capture as one is taken in the field: a grey panel (radiance
    // albedo x irradiance / pi) lying off-centre on textured tarmac, a
    // printed QR label (white and black modules) beside it, shot at a
    // shorter exposure; each band camera sees it a little shifted, as its
    // own rotation turns it.
    for (const RigBandCamera& band : rig) {
      io::RigBandImage b = band_metadata(band, k, "panel", 0.0003);
      b.file = tmp / "panel" / band_file("PANL_0000", band.index);
      const int64_t h = b.height, w = b.width, side = std::min(h, w) * 3 / 10;
      const double e = band.irradiance / kPi;
      std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), uint32_t(band.index),
                        0x9a4e1u};
      std::mt19937_64 rng(seq);
      auto uniform = [&rng](std::vector<int64_t> shape) {
        torch::Tensor t = torch::empty(shape, torch::kFloat);
        std::uniform_real_distribution<float> u(0.0f, 1.0f);
        float* v = t.data_ptr<float>();
        for (int64_t i = 0; i < t.numel(); ++i) v[i] = u(rng);
        return t;
      };
      const torch::Tensor coarse = uniform({1, 1, h / 16 + 2, w / 16 + 2});
      const torch::Tensor texture =
          torch::upsample_bilinear2d(coarse, {h, w}, false).squeeze(0).squeeze(0);
      torch::Tensor radiance = (0.06 + 0.05 * texture + 0.01 * uniform({h, w})) * float(e);
      const int64_t shift = int64_t(band.index) * side / 40;
      const int64_t px = w * 11 / 20 + shift, py = (h - side) / 2 + shift / 2;
      radiance.slice(0, py, py + side).slice(1, px, px + side).fill_(float(band.panel_albedo * e));
      // The label: white card with a grid of black and white modules.
      const int64_t lx = px - side * 4 / 5, label = side * 2 / 3, modules = 21;
      const torch::Tensor bits = (uniform({1, 1, modules, modules}) > 0.5f).to(torch::kFloat);
      const int64_t code = label * 4 / 5;
      const torch::Tensor pattern =
          torch::upsample_nearest2d(bits, {code, code}).squeeze(0).squeeze(0);
      torch::Tensor card = radiance.slice(0, py, py + label).slice(1, lx, lx + label);
      card.fill_(float(0.85 * e));
      card.slice(0, label / 10, label / 10 + code)
          .slice(1, label / 10, label / 10 + code)
          .copy_((0.05 + 0.80 * pattern) * float(e));
      io::write_rig_band_image(b, io::radiance_to_counts(b, radiance));
    }

    io::TransformsFile truth;
    // The truth scene's band order is by wavelength, as a scene's grid is.
    std::vector<int> order(rig.size());
    for (size_t i = 0; i < rig.size(); ++i) order[i] = int(i);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return rig[size_t(a)].centre_nm < rig[size_t(b)].centre_nm; });
    std::vector<int> scene_band(rig.size());
    for (size_t i = 0; i < order.size(); ++i) {
      truth.wavelengths_nm.push_back(rig[size_t(order[i])].centre_nm);
      scene_band[size_t(order[i])] = int(i);
    }
    truth.ply_file_path = "points.ply";
    // The rig as its metadata describes it (the truth's frames have the true poses).
    truth.rig = io::TransformsRig{1, 1.0, {}};
    for (const RigBandCamera& b : rig)
      truth.rig->cameras.push_back({b.index, b.name, b.relatives_deg});
    // The same captures as registered cubes: every band from the reference
    // pose (the rig's camera without rotation), as a hyperspectral camera
    // would take them; for comparing a band-per-view scene with one.
    io::TransformsFile cubes;
    cubes.wavelengths_nm = truth.wavelengths_nm;
    cubes.ply_file_path = "points.ply";
    const torch::Tensor band_order =
        torch::tensor(std::vector<int64_t>(order.begin(), order.end()));
    std::vector<float> xyz, spectra;
    // One capture as a registered cube under cubes/: its noisy bands (times
    // its light factor) and clean ones, and its frame; returns the frame's
    // file.
    auto write_cube = [&](const std::string& stem, const core::Camera& camera, std::mt19937_64& rng,
                          double light_factor) {
      const torch::Tensor clean = render_clean(scene, setup, camera, config.supersample);
      const torch::Tensor noisy = add_noise(clean, setup, rng);
      const std::string name = stem + ".npy";
      io::write_npy(tmp / "cubes" / "hyperspectral" / name,
                    (noisy * float(light_factor)).index_select(2, band_order).contiguous());
      io::write_npy(tmp / "cubes" / "clean" / name, clean.index_select(2, band_order).contiguous());
      io::TransformsFrame frame;
      frame.hyperspectral_file_path = "hyperspectral/" + name;
      frame.intrinsics = camera.intrinsics;
      frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(camera.world_to_camera);
      cubes.frames.push_back(frame);
      return frame.hyperspectral_file_path;
    };
    core::ProgressBar bar("synth rig", int64_t(references.size() + novel.size()));
    for (int c = 0; c < int(references.size()); ++c) {
      const std::string stem = capture_stem("IMG", c);
      std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), uint32_t(c), 0x51600u};
      std::mt19937_64 rng(seq);
      write_cube(stem, references[size_t(c)], rng, light[size_t(c)]);
      for (size_t i = 0; i < rig.size(); ++i) {
        const RigBandCamera& band = rig[i];
        core::Camera camera = references[size_t(c)];
        const core::Mat3 rotation = io::rig_relative_rotation(band.relatives_deg) *
                                    io::rotation_from_vector(drift[i].rotation_rad);
        camera.world_to_camera = core::Mat4::from(rotation, (rotation * drift[i].offset) * -1.0) *
                                 camera.world_to_camera;
        const torch::Tensor clean_all = render_clean(scene, setup, camera, config.supersample);
        const torch::Tensor noisy_all = add_noise(clean_all, setup, rng);
        const torch::Tensor clean = clean_all.select(2, int64_t(i)).contiguous();
        const torch::Tensor noisy = noisy_all.select(2, int64_t(i)).contiguous();
        io::RigBandImage b = band_metadata(band, k, "capture" + std::to_string(c), 0.0004);
        b.file = tmp / "captures" / band_file(stem, band.index);
        // The rig's GPS: where camera 1 (the reference pose) truly is.
        const GpsFix fix = gps_fix(
            place, references[size_t(c)].camera_to_world().translation() + gps_error[size_t(c)]);
        b.has_position = true;
        b.latitude_deg = fix.latitude_deg;
        b.longitude_deg = fix.longitude_deg;
        b.altitude_m = fix.altitude_m;
        // The clean value is the reflectance factor a perfect conversion
        // recovers: radiance = value x irradiance / pi, under the capture's
        // own light (its factor), which the DLS record does not show.
        io::write_rig_band_image(
            b, io::radiance_to_counts(b, noisy * float(light[size_t(c)] * band.irradiance / kPi)));
        const std::string name = stem + "_" + std::to_string(band.index) + ".npy";
        io::write_npy(tmp / "truth" / "bands" / name, clean.unsqueeze(2));
        io::write_npy(tmp / "truth" / "clean" / name, clean.unsqueeze(2));
        io::TransformsFrame frame;
        frame.hyperspectral_file_path = "bands/" + name;
        frame.intrinsics = camera.intrinsics;
        frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(camera.world_to_camera);
        frame.bands = {scene_band[i]};
        frame.rig_camera = band.index;
        truth.frames.push_back(frame);
        if (i == 0) {  // points from the reference camera, spectra from every band later
          const int per_view = (config.points + config.views - 1) / config.views;
          ViewPoints points =
              sample_points(scene, camera, clean_all, per_view, config.point_jitter, rng);
          xyz.insert(xyz.end(), points.xyz.begin(), points.xyz.end());
          for (size_t p = 0; p < points.pixels.size(); ++p)
            for (int j : order) spectra.push_back(points.spectra[p * rig.size() + size_t(j)]);
        }
      }
      bar.update(c + 1);
    }
    // Held-out captures the flight did not take: cubes only (no raw
    // captures, no points), each under the survey's nominal light, in the
    // test split beside the flight's own held-out captures.
    if (!novel.empty()) {
      std::vector<int> train_views, test_views;
      io::hypernerf_split(int(references.size()), train_views, test_views);
      for (int c : train_views)
        cubes.train_files.push_back("hyperspectral/" + capture_stem("IMG", c) + ".npy");
      for (int c : test_views)
        cubes.test_files.push_back("hyperspectral/" + capture_stem("IMG", c) + ".npy");
      for (int c = 0; c < int(novel.size()); ++c) {
        std::seed_seq seq{uint32_t(config.seed), uint32_t(config.seed >> 32), uint32_t(c),
                          0x40e1du};
        std::mt19937_64 rng(seq);
        cubes.test_files.push_back(write_cube(capture_stem("NOVEL", c), novel[size_t(c)], rng, 1));
        bar.update(int64_t(references.size()) + c + 1);
      }
    }
    bar.finish();
    io::PointCloud cloud;
    const int64_t count = int64_t(xyz.size() / 3);
    cloud.xyz = torch::from_blob(xyz.data(), {count, 3}, torch::kFloat32).clone();
    cloud.spectra =
        torch::from_blob(spectra.data(), {count, int64_t(rig.size())}, torch::kFloat32).clone();
    io::write_point_ply(tmp / "truth" / "points.ply", cloud);
    io::write_transforms(tmp / "truth" / "transforms.json", truth);
    io::write_point_ply(tmp / "cubes" / "points.ply", cloud);
    io::write_transforms(tmp / "cubes" / "transforms.json", cubes);
    if (config.nadir) {
      io::write_npy(tmp / "truth" / "ortho.npy",
                    render_orthographic(scene, setup, grid, config.supersample)
                        .index_select(2, band_order)
                        .contiguous());
    }

    nlohmann::json j;
    j["generator"] = "ddhgs synth";
    j["preset"] = config.preset;
    j["seed"] = config.seed;
    j["captures"] = references.size();
    j["width"] = config.width;
    j["height"] = config.height;
    j["fov_deg"] = config.fov_deg;
    j["rings"] = config.rings;
    j["flight"] = config.nadir ? "nadir strip" : "ring";
    if (config.nadir) {
      j["overlap"] = config.overlap;
      j["lines"] = config.lines;
      j["side_overlap"] = config.side_overlap;
      j["altitude_m"] = references.front().camera_to_world().translation().z;
      j["field_spacing_m"] = config.field_spacing_m;
      j["plants"] = scene.plants.size();
      if (!novel.empty())
        j["novel_views"] = {
            {"count", novel.size()},
            {"files", "cubes/hyperspectral/NOVEL_NNNN.npy (cubes/ only, its test split)"},
            {"where", "midway between neighbouring captures and lines, the flight's height"}};
    }
    j["light_factors"] = light;
    j["supersample"] = config.supersample;
    j["unit_m"] = 1.0;
    j["rig_perturb_deg"] = config.rig_perturb_deg;
    j["rig_offset_cm"] = config.rig_offset_cm;
    j["noise_scale"] = config.noise_scale;
    j["layout"] =
        "captures/IMG_NNNN_k.tif (raw counts), panel/PANL_0000_k.tif, truth/ (a "
        "band-per-view scene: true poses, clean reflectance), cubes/ (the same captures as "
        "registered five-band cubes from the reference pose)";
    nlohmann::json cameras = nlohmann::json::array();
    std::vector<double> albedo;
    for (size_t i = 0; i < rig.size(); ++i) {
      const RigBandCamera& b = rig[i];
      // The truth beside the factory RigRelatives the metadata keeps: the
      // drift in camera 1's axes (RigDrift).
      cameras.push_back({{"rig_index", b.index},
                         {"band", b.name},
                         {"centre_nm", b.centre_nm},
                         {"rig_relatives_deg", b.relatives_deg},
                         {"true_rotation_error_deg", scaled(drift[i].rotation_rad, 180 / kPi)},
                         {"true_offset_cm", scaled(drift[i].offset, 100)},
                         {"irradiance", b.irradiance},
                         {"panel_albedo", b.panel_albedo}});
      albedo.push_back(b.panel_albedo);
    }
    j["cameras"] = cameras;
    j["georeference"] = {
        {"gps_origin_deg", {config.gps_latitude_deg, config.gps_longitude_deg}},
        {"epsg", place.zone.epsg()},
        {"world_origin_crs_m", {place.easting_m, place.northing_m, place.height_m}},
        {"world_to_crs",
         "easting = x + world_origin_crs_m[0], northing = y + [1], height = z + [2]"}};
    if (config.nadir) {
      j["ortho"] = {{"file", "truth/ortho.npy"},
                    {"epsg", place.zone.epsg()},
                    {"geotransform", geotransform(place, grid)},
                    {"width", grid.width},
                    {"height", grid.height},
                    {"wavelengths_nm", truth.wavelengths_nm}};
      j["ground_control_points"] = control_points;
      if (config.gcp_targets)
        j["gcp_targets"] = {{"side_m", 2 * kGcpTargetHalfPixels * grid.pixel},
                            {"pattern",
                             "2 x 2 checker centred on each point, north-east and "
                             "south-west quarters black (reflectance 0.04), the others "
                             "white (0.6)"}};
    }
    if (config.gps_noise_m > 0) {
      nlohmann::json errors = nlohmann::json::array();
      for (const core::Vec3& e : gps_error) errors.push_back({e.x, e.y, e.z});
      j["gps_noise"] = {{"sigma_m", config.gps_noise_m},
                        {"axes", "east, north, up"},
                        {"capture_error_m", errors}};
    }
    j["panel_albedo"] = albedo;
    io::write_file_atomically(tmp / "synth.json", j.dump(2) + "\n");
    // The rig's lever arms as its maker's drawing gives them (the true
    // offsets; the turns are what drifts), in the form
    // camera_refinement.rig_start reads.
    if (config.rig_offset_cm > 0) {
      nlohmann::json arms = nlohmann::json::array();
      for (size_t i = 0; i < rig.size(); ++i)
        if (rig[i].index != 1)
          arms.push_back({{"rig_camera", rig[i].index},
                          {"band", rig[i].name},
                          {"offset_cm", scaled(drift[i].offset, 100)}});
      const nlohmann::json file = {{"axes", "camera 1's (OpenCV: x right, y down, z forward)"},
                                   {"cameras", arms}};
      io::write_file_atomically(tmp / "lever_arms.json", file.dump(2) + "\n");
    }
    result.views = int(references.size() * rig.size());
    result.points = int(count);
  });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace ddhgs::synth
