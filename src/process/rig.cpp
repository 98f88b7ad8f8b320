#include "process/rig.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <map>

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

  const std::vector<io::RigCapture> captures = io::read_rig_captures(options.captures_dir);
  const std::vector<io::RigBandImage>& cameras = captures.front().bands;
  std::vector<io::ReflectanceCalibration> panel;
  if (!options.panel_dir.empty()) {
    const std::vector<io::RigCapture> panels = io::read_rig_captures(options.panel_dir);
    if (panels.size() != 1)
      throw core::Error(options.panel_dir, "holds " + std::to_string(panels.size()) +
                                               " captures; give the folder of one panel capture");
    panel = io::panel_calibration(panels.front(), options.panel_albedo);
  }
  // The camera COLMAP poses: the one asked for, else (chosen once the
  // reflectance is known) the brightest, whose images have the most texture
  // to match: NIR over vegetation, where the blue camera sees little.
  int reference = options.reference_camera;
  auto reference_of = [&](const io::RigCapture& c) -> const io::RigBandImage* {
    for (const io::RigBandImage& b : c.bands)
      if (b.rig_index == reference) return &b;
    return nullptr;
  };
  if (reference > 0 && !reference_of(captures.front()))
    throw core::Error("--reference-camera", std::to_string(reference) +
                                                " is not a band camera of the rig (cameras 1 to " +
                                                std::to_string(cameras.back().rig_index) + ")");
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
    if (reference == 0) {
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
        transforms.frames.push_back(frame);
        (is_test[c] ? transforms.test_files : transforms.train_files)
            .push_back(frame.hyperspectral_file_path);
      }
    }
    io::PointCloud cloud = io::colmap_points(model);
    if (cloud.xyz.defined() && cloud.xyz.size(0) > 0) {
      io::write_point_ply(tmp / "points.ply", cloud);
      transforms.ply_file_path = "points.ply";
      result.points = cloud.xyz.size(0);
    } else if (!run_sfm && fs::is_regular_file(options.poses)) {
      const io::TransformsFile given_file = io::read_transforms(options.poses);
      const fs::path ply = options.poses.parent_path() / given_file.ply_file_path;
      if (!given_file.ply_file_path.empty() && fs::is_regular_file(ply)) {
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
        entry["panel_albedo"] = c.albedo;
        entry["panel_radiance"] = c.panel_radiance;
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
        {"poses", run_sfm ? "colmap" : fs::absolute(options.poses).string()}};
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
