#include "process/rig.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <optional>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "io/colmap/colmap.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_radiometry.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"
#include "process/georeference.h"

namespace ddhgs::process {
namespace fs = std::filesystem;

namespace {

std::string stem_of(const std::string& name) {
  return fs::path(name).stem().string();
}

// The reference images as 8-bit PNGs for COLMAP, one stretch for all: 0 to
// the 99.5th percentile of their reflectance.
void write_reference_pngs(const std::vector<std::pair<std::string, torch::Tensor>>& images,
                          const fs::path& dir) {
  fs::create_directories(dir);
  std::vector<torch::Tensor> samples;
  for (const auto& [name, image] : images) samples.push_back(image.flatten().slice(0, 0, -1, 7));
  const torch::Tensor all = torch::cat(samples);
  const int64_t rank = std::max<int64_t>(1, int64_t(0.995 * double(all.numel())));
  const double top = std::max(1e-6, std::get<0>(all.kthvalue(rank)).item<double>());
  for (const auto& [name, image] : images) {
    const torch::Tensor grey = (image / top).clamp(0, 1).mul(255).round().to(torch::kUInt8);
    io::write_png(dir / (name + ".png"), grey.unsqueeze(2).expand({-1, -1, 3}).contiguous());
  }
}

// A band image as an 8-bit picture (0 to its 99.5th percentile), the panel
// region's outline drawn in red where there is one, and the QR label that
// placed it (if one did) in blue.
void write_panel_picture(const fs::path& path, const torch::Tensor& counts,
                         const io::PanelRegion* region) {
  const torch::Tensor flat = counts.flatten().slice(0, 0, -1, 3).to(torch::kFloat);
  const int64_t rank = std::max<int64_t>(1, int64_t(0.995 * double(flat.numel())));
  const double top = std::max(1e-6, std::get<0>(flat.kthvalue(rank)).item<double>());
  torch::Tensor grey =
      (counts.to(torch::kFloat) / float(top)).clamp(0, 1).mul(255).round().to(torch::kUInt8);
  torch::Tensor rgb = grey.unsqueeze(2).expand({-1, -1, 3}).contiguous();
  if (region && region->mask.defined()) {
    // The outline: region pixels within 2 px of a pixel outside it.
    const torch::Tensor inside = region->mask.to(torch::kFloat).unsqueeze(0).unsqueeze(0);
    const torch::Tensor core = -torch::max_pool2d(-inside, {5, 5}, {1, 1}, {2, 2});
    const torch::Tensor edge = (inside - core).squeeze(0).squeeze(0) > 0.5f;
    rgb.select(2, 0).masked_fill_(edge, 255);
    rgb.select(2, 1).masked_fill_(edge, 0);
    rgb.select(2, 2).masked_fill_(edge, 0);
  }
  if (region && !region->label.empty()) {
    // The QR label that placed it: its outline in blue.
    const int64_t height = rgb.size(0), width = rgb.size(1);
    uint8_t* p = rgb.data_ptr<uint8_t>();
    for (size_t i = 0; i < 4; ++i) {
      const auto& a = region->label_corners[i];
      const auto& b = region->label_corners[(i + 1) % 4];
      const int steps = int(2 * std::hypot(b[0] - a[0], b[1] - a[1])) + 1;
      for (int t = 0; t <= steps; ++t) {
        const double x = a[0] + (b[0] - a[0]) * t / steps, y = a[1] + (b[1] - a[1]) * t / steps;
        for (int64_t dy = -1; dy <= 1; ++dy)
          for (int64_t dx = -1; dx <= 1; ++dx) {
            const int64_t px = std::lround(x) + dx, py = std::lround(y) + dy;
            if (px < 0 || py < 0 || px >= width || py >= height) continue;
            uint8_t* rgb_at = p + 3 * (py * width + px);
            rgb_at[0] = 0, rgb_at[1] = 0, rgb_at[2] = 255;
          }
      }
    }
  }
  io::write_png(path, rgb);
}

// The scene's georeference from the posed captures' GPS (the reference
// camera's centre; a rig's cameras share one GPS) and, for a single strip,
// the rig's viewing axis; nullopt, with a note, when the captures carry none.
template <typename ReferenceOf>
std::optional<io::Georeference> georeference_from_gps(
    const std::vector<const io::RigCapture*>& posed,
    const std::map<std::string, const io::ColmapImage*>& pose_of, const io::ColmapModel& model,
    const ReferenceOf& reference_of) {
  std::vector<GpsCapture> located;
  std::vector<std::string> without;
  for (const io::RigCapture* capture : posed) {
    const io::RigBandImage& ref = *reference_of(*capture);
    if (!ref.has_position) {
      without.push_back(capture->id);
      continue;
    }
    const core::Camera camera = io::colmap_camera(model, *pose_of.at(ref.file.stem().string()));
    // The rig's own axis (the frame its RigRelatives are given in), which the
    // nadir assumption is about, turned back from the posed camera's.
    const core::Vec3 rig_axis =
        camera.camera_to_world().rotation() *
        (io::rig_relative_rotation(ref.rig_relatives_deg) * core::Vec3{0, 0, 1});
    located.push_back({capture->id, ref.latitude_deg, ref.longitude_deg, ref.altitude_m,
                       camera.center(), rig_axis});
  }
  if (located.empty()) {
    core::log_info("process: the captures carry no GPS; the scene is not georeferenced");
    return std::nullopt;
  }
  if (!without.empty())
    core::log_warn("process: " + std::to_string(without.size()) + " posed captures carry no GPS (" +
                   without.front() + (without.size() > 1 ? ", ..." : "") +
                   "); the georeference is fitted to the others");
  if (located.size() < 3) {
    core::log_warn("process: only " + std::to_string(located.size()) +
                   " posed captures carry GPS; at least 3 are needed: the scene is not "
                   "georeferenced");
    return std::nullopt;
  }
  try {
    const io::Georeference georef = fit_georeference(located);
    core::log_info("process: georeferenced to " + io::describe_georeference(georef));
    return georef;
  } catch (const core::Error& e) {
    // GPS without a fix (every capture at one place) must not cost the scene.
    core::log_warn(std::string("process: the scene is not georeferenced: ") + e.what());
    return std::nullopt;
  }
}

}  // namespace

ProcessResult process_rig(const RigProcessOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path out = output_folder(options.out);
  const bool run_sfm = options.poses.empty();
  if (run_sfm) check_colmap_options(options.colmap);
  const io::OutputRequest request{out,
                                  io::OutputKind::Scene,
                                  options.force,
                                  {options.captures_dir, options.panel_dir, options.poses}};
  io::check_output_folder(request);
  if (options.panel_dir.empty() && !options.panel_albedo.empty())
    throw core::Error("--panel-albedo", "needs --panel DIR, the panel capture it describes");
  if (!options.panel_dir.empty() && options.panel_albedo.empty())
    throw core::Error("--panel",
                      "needs --panel-albedo a,b,... (the panel's albedo per band camera)");
  if (run_sfm) find_colmap(options.colmap);
  io::ColmapModel given;
  if (!run_sfm) given = read_given_poses(options.poses);
  // Given poses in a transforms.json: its points and its rig's unit.
  std::optional<io::TransformsFile> given_file;
  if (!run_sfm && fs::is_regular_file(options.poses))
    given_file = io::read_transforms(options.poses);

  const std::vector<io::RigCapture> captures = io::read_rig_captures(options.captures_dir);
  const std::vector<io::RigBandImage>& cameras = captures.front().bands;
  // Posing and training need three captures: refused before any work.
  if (captures.size() < 3)
    throw core::Error(options.captures_dir,
                      "holds " + std::to_string(captures.size()) + " capture" +
                          (captures.size() == 1 ? "" : "s") +
                          " of the rig; at least 3 overlapping captures are needed to pose and "
                          "train (a panel capture goes to --panel)");
  // The camera COLMAP poses: the one asked for, else (chosen once the
  // reflectance is known) the brightest, whose images have the most texture
  // to match: NIR over vegetation, where the blue camera sees little.
  std::string numbers;
  for (const io::RigBandImage& b : cameras)
    numbers += (numbers.empty() ? "" : ", ") + std::to_string(b.rig_index);
  int reference = options.reference_camera.value_or(-1);
  auto reference_of = [&](const io::RigCapture& c) -> const io::RigBandImage* {
    for (const io::RigBandImage& b : c.bands)
      if (b.rig_index == reference) return &b;
    return nullptr;
  };
  if (options.reference_camera && !reference_of(captures.front()))
    throw core::Error("--reference-camera",
                      std::to_string(reference) + " is not a band camera of the rig in " +
                          options.captures_dir.string() + " (its cameras: " + numbers + ")");
  for (const auto& [index, box] : options.panel_regions) {
    bool known = index == -1;
    for (const io::RigBandImage& b : cameras) known = known || b.rig_index == index;
    if (!known)
      throw core::Error("--panel-region",
                        std::to_string(index) +
                            " is not a band camera of the rig (its cameras: " + numbers + ")");
  }
  std::vector<io::ReflectanceCalibration> panel;
  std::vector<io::RigBandImage> panel_images;
  const fs::path panel_picture = (out.parent_path().empty() ? fs::path(".") : out.parent_path()) /
                                 (out.filename().string() + ".panel.png");
  if (!options.panel_dir.empty()) {
    const std::vector<io::RigCapture> panels = io::read_rig_captures(options.panel_dir);
    if (panels.size() != 1)
      throw core::Error(options.panel_dir, "holds " + std::to_string(panels.size()) +
                                               " captures; give the folder of one panel capture");
    panel_images = panels.front().bands;
    std::error_code ec;
    fs::remove(panel_picture, ec);
    try {
      panel = io::panel_calibration(panels.front(), cameras, options.panel_albedo,
                                    options.panel_regions);
    } catch (const io::PanelNotFound& e) {
      // The picture a person looks at to say where the panel lies.
      write_panel_picture(panel_picture, io::read_band_counts(e.image), nullptr);
      throw core::Error(std::string(e.what()) + " (the band image: " + panel_picture.string() +
                        ")");
    }
    for (const io::ReflectanceCalibration& c : panel) {
      char line[240];
      std::snprintf(line, sizeof line,
                    "process: panel in %s: region %s, %lld px, raw mean %.1f (spread %.1f), "
                    "radiance %.6g, irradiance %.6g W/m2/nm",
                    c.panel_file.filename().string().c_str(),
                    !c.region.found          ? "given"
                    : c.region.label.empty() ? "found"
                                             : ("placed by label " + c.region.label).c_str(),
                    (long long)c.region.pixels, c.raw_mean, c.raw_spread, c.panel_radiance,
                    c.irradiance);
      core::log_info(line);
    }
  }
  // The scene's band grid: the cameras' centre wavelengths, ascending.
  std::vector<std::pair<double, int>> by_wavelength;
  for (const io::RigBandImage& b : cameras) by_wavelength.emplace_back(b.centre_nm, b.rig_index);
  std::sort(by_wavelength.begin(), by_wavelength.end());
  std::map<int, int> scene_band;
  io::TransformsFile transforms;
  for (size_t i = 0; i < by_wavelength.size(); ++i) {
    if (i > 0 && by_wavelength[i].first == by_wavelength[i - 1].first)
      throw core::Error(captures.front().bands.front().file,
                        "two band cameras of the rig share the centre wavelength " +
                            std::to_string(by_wavelength[i].first) + " nm");
    scene_band[by_wavelength[i].second] = int(i);
    transforms.wavelengths_nm.push_back(by_wavelength[i].first);
  }
  core::log_info("process: " + std::to_string(captures.size()) + " captures of " +
                 std::to_string(cameras.size()) + " band cameras; reflectance from " +
                 (panel.empty() ? std::string("each capture's DLS irradiance")
                                : "the panel capture in " + options.panel_dir.string()) +
                 "; poses from " + (run_sfm ? std::string("COLMAP") : options.poses.string()));

  const fs::path failed_log = colmap_log_beside(out);
  ProcessResult result;
  result.views = int(captures.size() * cameras.size());
  io::write_folder_atomically(request, [&](const fs::path& tmp) {
    fs::create_directories(tmp / "bands");
    if (!panel.empty()) {
      fs::create_directories(tmp / "panel");
      for (const io::ReflectanceCalibration& c : panel)
        for (const io::RigBandImage& b : panel_images)
          if (b.file == c.panel_file)
            write_panel_picture(tmp / "panel" / (b.file.stem().string() + ".png"),
                                io::read_band_counts(b), &c.region);
    }
    std::map<int, io::ReflectanceCalibration> used;  // by camera (the last capture's for DLS)
    std::map<int, double> brightness;                // mean reflectance by camera
    {
      core::ProgressBar bar("reflectance", int64_t(result.views));
      int64_t done = 0;
      for (const io::RigCapture& capture : captures)
        for (const io::RigBandImage& b : capture.bands) {
          const io::ReflectanceCalibration calibration = io::reflectance_calibration(b, panel);
          used[b.rig_index] = calibration;
          const torch::Tensor reflectance = io::read_band_reflectance(b, calibration);
          io::write_npy(tmp / "bands" / (b.file.stem().string() + ".npy"),
                        reflectance.unsqueeze(2).contiguous());
          brightness[b.rig_index] += reflectance.mean().item<double>();
          bar.update(++done);
        }
      bar.finish();
    }
    if (!options.reference_camera) {
      reference = cameras.front().rig_index;
      for (const auto& [index, sum] : brightness)
        if (sum > brightness[reference]) reference = index;
    }
    const io::RigBandImage& reference_band = *reference_of(captures.front());
    core::log_info("process: poses of camera " + std::to_string(reference) + " (" +
                   reference_band.band_name + ") from " +
                   (run_sfm ? std::string("COLMAP") : options.poses.string()) +
                   "; the other cameras follow by their rig rotations");
    io::ColmapModel model;
    if (run_sfm) {
      std::vector<std::pair<std::string, torch::Tensor>> reference_images;
      for (const io::RigCapture& capture : captures) {
        const std::string stem = reference_of(capture)->file.stem().string();
        const io::Cube written = io::read_cube(tmp / "bands" / (stem + ".npy"));
        reference_images.emplace_back(stem, written.data.squeeze(2));
      }
      write_reference_pngs(reference_images, tmp / "images");
      // The reference camera's intrinsics are known: COLMAP keeps them.
      const core::Intrinsics k = io::rig_intrinsics(reference_band);
      ColmapOptions colmap = options.colmap;
      colmap.camera_model = "PINHOLE";
      colmap.settings.insert(
          colmap.settings.begin(),
          {"ImageReader.camera_params=" + core::join_numbers({k.fx, k.fy, k.cx, k.cy}),
           "Mapper.ba_refine_focal_length=0", "Mapper.ba_refine_principal_point=0",
           "Mapper.ba_refine_extra_params=0"});
      run_colmap(colmap, tmp / "images", tmp / "colmap", failed_log);
      model = largest_colmap_model(tmp / "colmap" / "sparse");
    } else {
      model = std::move(given);
    }
    std::map<std::string, const io::ColmapImage*> pose_of;
    for (const io::ColmapImage& image : model.images) pose_of[stem_of(image.name)] = &image;

    std::vector<const io::RigCapture*> posed;
    std::vector<std::string> unposed;
    for (const io::RigCapture& capture : captures)
      (pose_of.count(reference_of(capture)->file.stem().string()) ? posed.push_back(&capture)
                                                                  : unposed.push_back(capture.id));
    result.registered = int(posed.size() * cameras.size());
    result.unregistered = unposed;
    const std::string source = run_sfm ? failed_log.string() : options.poses.string();
    core::require(posed.size() >= 3, source,
                  std::to_string(posed.size()) + " of " + std::to_string(captures.size()) +
                      " captures posed (camera " + std::to_string(reference) +
                      "'s images); at least 3 are needed to train");
    std::vector<int> train, test;
    io::hypernerf_split(int(posed.size()), train, test);
    // Fewer than 10 captures leave the Hyper-NeRF rule nothing to test on:
    // the middle capture is held out instead (a strip's best-covered one).
    if (test.empty() && posed.size() >= 4) test = {int(posed.size() / 2)};
    std::vector<bool> is_test(posed.size(), false);
    for (int t : test) is_test[size_t(t)] = true;
    for (size_t c = 0; c < posed.size(); ++c) {
      const io::RigBandImage& ref = *reference_of(*posed[c]);
      const io::ColmapImage& image = *pose_of.at(ref.file.stem().string());
      const core::Mat4 ref_w2c = io::colmap_camera(model, image).world_to_camera;
      const core::Mat3 ref_rotation = io::rig_relative_rotation(ref.rig_relatives_deg);
      for (const io::RigBandImage& b : posed[c]->bands) {
        const core::Mat3 turn =
            io::rig_relative_rotation(b.rig_relatives_deg) * ref_rotation.transposed();
        io::TransformsFrame frame;
        frame.hyperspectral_file_path = "bands/" + b.file.stem().string() + ".npy";
        frame.intrinsics = io::rig_intrinsics(b);
        frame.camera_to_world_gl =
            core::opencv_w2c_to_opengl_c2w(core::Mat4::from(turn, {0, 0, 0}) * ref_w2c);
        frame.bands = {scene_band.at(b.rig_index)};
        frame.rig_camera = b.rig_index;
        transforms.frames.push_back(frame);
        (is_test[c] ? transforms.test_files : transforms.train_files)
            .push_back(frame.hyperspectral_file_path);
      }
    }
    const std::optional<io::Georeference> georef =
        georeference_from_gps(posed, pose_of, model, reference_of);
    if (georef) write_georeference(tmp / io::kGeorefFile, *georef);
    // The rig as its metadata describes it, for training's per-camera
    // corrections (camera_refinement.rig); metres per unit when the given
    // poses say it, else the georeference's scale (COLMAP's frame fitted to
    // the GPS), so corrections and lever arms can be given in cm.
    transforms.rig = io::TransformsRig{reference, 0, {}};
    for (const io::RigBandImage& b : cameras)
      transforms.rig->cameras.push_back({b.rig_index, b.band_name, b.rig_relatives_deg});
    if (given_file && given_file->rig && given_file->rig->unit_m > 0)
      transforms.rig->unit_m = given_file->rig->unit_m;
    else if (georef)
      transforms.rig->unit_m = georef->scene_to_crs.scale;
    io::PointCloud cloud = io::colmap_points(model);
    if (cloud.xyz.defined() && cloud.xyz.size(0) > 0) {
      io::write_point_ply(tmp / "points.ply", cloud);
      transforms.ply_file_path = "points.ply";
      result.points = cloud.xyz.size(0);
    } else if (given_file) {
      const fs::path ply = options.poses.parent_path() / given_file->ply_file_path;
      if (!given_file->ply_file_path.empty() && fs::is_regular_file(ply)) {
        io::PointCloud points = io::read_point_ply(ply);
        points.spectra = torch::Tensor();  // its bands need not be this scene's
        io::write_point_ply(tmp / "points.ply", points);
        transforms.ply_file_path = "points.ply";
        result.points = points.xyz.size(0);
      }
    }
    io::write_transforms(tmp / "transforms.json", transforms);

    nlohmann::json calibration = nlohmann::json::array();
    for (const io::RigBandImage& b : cameras) {
      const io::ReflectanceCalibration& c = used.at(b.rig_index);
      nlohmann::json entry = {{"rig_index", b.rig_index},
                              {"band", b.band_name},
                              {"centre_nm", b.centre_nm},
                              {"rig_relatives_deg", b.rig_relatives_deg},
                              {"reflectance_from", c.source}};
      if (c.source == "panel") {
        nlohmann::json corners = nlohmann::json::array();
        for (const auto& corner : c.region.corners) corners.push_back({corner[0], corner[1]});
        if (!c.region.label.empty()) {
          nlohmann::json label_corners = nlohmann::json::array();
          for (const auto& corner : c.region.label_corners)
            label_corners.push_back({corner[0], corner[1]});
          entry["panel_label"] = {{"serial", c.region.label}, {"corners_xy", label_corners}};
        }
        entry["panel_albedo"] = c.albedo;
        entry["panel_radiance"] = c.panel_radiance;
        entry["panel"] = {{"file", fs::absolute(c.panel_file).string()},
                          {"region", io::panel_region_source(c.region)},
                          {"corners_xy", corners},
                          {"pixels", c.region.pixels},
                          {"raw_mean", c.raw_mean},
                          {"raw_spread", c.raw_spread},
                          {"saturated_pixels", c.saturated},
                          {"irradiance", c.irradiance},
                          {"picture", "panel/" + c.panel_file.stem().string() + ".png"}};
        // The whole panel's side where the finder measured it (a placed or
        // given region says nothing of the panel around it).
        if (c.region.panel_side_px > 0) entry["panel"]["panel_side_px"] = c.region.panel_side_px;
      } else {
        entry["dls_irradiance_tag"] = b.radiometry.irradiance_tag;
        entry["dls_correction"] = b.radiometry.irradiance_correction;
      }
      calibration.push_back(entry);
    }
    nlohmann::json summary = {
        {"generator", "ddhgs process --rig"},
        {"captures_dir", fs::absolute(options.captures_dir).string()},
        {"captures", captures.size()},
        {"band_images", result.views},
        {"posed_band_images", result.registered},
        {"unposed_captures", unposed},
        {"reference_camera", reference},
        {"cameras", calibration},
        {"reflectance", panel.empty()
                            ? "DLS irradiance of each capture (pi L / E)"
                            : "panel capture " + fs::absolute(options.panel_dir).string()},
        {"points", result.points},
        {"poses", run_sfm ? "colmap" : fs::absolute(options.poses).string()},
        {"georeference", georef ? nlohmann::json(io::kGeorefFile) : nlohmann::json()}};
    if (run_sfm) fs::rename(failed_log, tmp / "colmap.log");
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    summary["seconds"] = result.seconds;
    io::write_file_atomically(tmp / "process.json", summary.dump(2) + "\n");
  });
  if (!result.unregistered.empty()) {
    std::string names;
    for (const auto& n : result.unregistered) names += (names.empty() ? "" : ", ") + n;
    core::log_warn("process: " + std::to_string(result.unregistered.size()) + " of " +
                   std::to_string(captures.size()) +
                   " captures have no pose and are left out: " + names);
  }
  return result;
}

}  // namespace ddhgs::process
