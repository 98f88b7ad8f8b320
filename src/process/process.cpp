// `ddhgs process`, last step: COLMAP poses -> transforms.json, sparse points
// with per-band spectra, and the whole command built in a temporary folder.
#include <nlohmann/json.hpp>

#include <chrono>
#include <map>

#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/ply/ply.h"
#include "io/scene/scene.h"
#include "process/poses.h"
#include "process/process.h"
#include "process/pseudo_rgb_images.h"

namespace ddhgs::process {
using namespace io;
namespace fs = std::filesystem;

fs::path output_folder(const fs::path& requested) {
  fs::path out = requested.lexically_normal();
  return out.filename().empty() ? out.parent_path() : out;
}

fs::path colmap_log_beside(const fs::path& out) {
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  fs::create_directories(parent);
  const fs::path log = parent / (out.filename().string() + ".colmap.log");
  fs::remove(log);
  return log;
}

ColmapModel read_given_poses(const fs::path& poses) {
  if (fs::is_directory(poses)) {
    auto dir = find_colmap_model(poses);
    if (!dir && (fs::exists(poses / "cameras.bin") || fs::exists(poses / "cameras.txt")))
      dir = poses;
    core::require(dir.has_value(), poses,
                  "holds no COLMAP model (cameras, images, points3D .bin or .txt)");
    return read_colmap(*dir);
  }
  core::require(fs::is_regular_file(poses), poses,
                "does not exist (expected a COLMAP model folder or a transforms.json)");
  return colmap_from_transforms(read_transforms(poses));
}

ColmapModel largest_colmap_model(const fs::path& sparse) {
  std::vector<ColmapModel> models;
  std::vector<fs::path> dirs;
  if (fs::is_directory(sparse))
    for (const auto& entry : fs::directory_iterator(sparse))
      if (entry.is_directory()) dirs.push_back(entry.path());
  std::sort(dirs.begin(), dirs.end());
  for (const auto& dir : dirs) models.push_back(read_colmap(dir));
  auto best = largest_model(models);
  core::require(best.has_value(), sparse, "COLMAP wrote no model");
  if (models.size() > 1)
    core::log_info("process: COLMAP found " + std::to_string(models.size()) +
                   " separate models; keeping " + dirs[*best].filename().string() + " with " +
                   std::to_string(models[*best].images.size()) + " views");
  return std::move(models[*best]);
}

namespace {

PointCloud points_of(const ColmapModel& model, const CubeSet& cubes) {
  PointCloud cloud = colmap_points(model);
  if (!model.points.empty()) cloud.spectra = sample_point_spectra(model, cubes);
  return cloud;
}

std::string relative_to(const fs::path& file, const fs::path& dir) {
  fs::path rel = fs::relative(fs::absolute(file), fs::absolute(dir));
  return (rel.empty() ? fs::absolute(file) : rel).generic_string();
}

}  // namespace

ProcessResult process_cubes(const ProcessOptions& options) {
  auto start = std::chrono::steady_clock::now();
  const fs::path out = output_folder(options.out);
  const bool run_sfm = options.poses.empty();
  if (run_sfm) check_colmap_options(options.colmap);
  const OutputRequest request{
      out, OutputKind::Scene, options.force, {options.cubes_dir, options.poses}};
  check_output_folder(request);
  if (run_sfm) find_colmap(options.colmap);
  // Given poses are read before the cubes: a missing or broken poses file is
  // named as such, not as a problem of the cubes found later.
  ColmapModel given_poses;
  if (!run_sfm) given_poses = read_given_poses(options.poses);
  const CubeSet raw = scan_cubes(options.cubes_dir, options.wavelengths);
  core::log_info("process: " + std::to_string(raw.files.size()) + " cubes of " +
                 std::to_string(raw.width) + "x" + std::to_string(raw.height) + " px, " +
                 std::to_string(raw.bands) + " bands" +
                 (raw.white_refs.empty() ? "" : " (Specim IQ captures with their references)"));
  // The references are checked before anything is written.
  const bool calibrate = calibrates(raw, options.reflectance);
  std::optional<Calibration> calibration;
  if (calibrate) calibration = plan_calibration(raw, options.reflectance);

  const fs::path failed_log = colmap_log_beside(out);
  ProcessResult result;
  result.views = int(raw.files.size());
  write_folder_atomically(request, [&](const fs::path& tmp) {
    nlohmann::json summary = {{"generator", "ddhgs process"},
                              {"cubes_dir", fs::absolute(options.cubes_dir).string()}};
    // The scene holds reflectance: the pseudo-RGB images, the poses' cubes
    // and the points' spectra all come from it.
    const CubeSet cubes =
        calibrate ? write_reflectance_cubes(raw, *calibration, tmp / "reflectance", summary) : raw;
    Stretch stretch = write_pseudo_rgb_images(cubes, options.pseudo_rgb, tmp / "images");
    ColmapModel model;
    if (run_sfm) {
      run_colmap(options.colmap, tmp / "images", tmp / "colmap", failed_log);
      model = largest_colmap_model(tmp / "colmap" / "sparse");
    } else {
      model = std::move(given_poses);
    }
    std::vector<int64_t> cube_of = cube_of_images(model, cubes);
    std::vector<bool> posed(cubes.names.size(), false);
    for (int64_t c : cube_of)
      if (c >= 0) posed[size_t(c)] = true;
    for (size_t c = 0; c < posed.size(); ++c)
      if (!posed[c]) result.unregistered.push_back(cubes.names[c]);
    result.registered = result.views - int(result.unregistered.size());
    const std::string source = run_sfm ? failed_log.string() : options.poses.string();
    core::require(result.registered >= 3, source,
                  std::to_string(result.registered) + " of " + std::to_string(result.views) +
                      " views posed; at least 3 are needed to train");

    std::vector<std::string> cube_paths;
    for (size_t c = 0; c < cubes.files.size(); ++c)
      cube_paths.push_back(calibrate ? "reflectance/" + cubes.files[c].filename().string()
                                     : relative_to(cubes.files[c], out));
    TransformsFile transforms = transforms_from_colmap(model, cubes, cube_paths);
    PointCloud cloud = points_of(model, cubes);
    if (cloud.xyz.defined()) {
      write_point_ply(tmp / "points.ply", cloud);
      transforms.ply_file_path = "points.ply";
      result.points = cloud.xyz.size(0);
    }
    write_transforms(tmp / "transforms.json", transforms);
    write_colmap_binary(tmp / "sparse" / "0", model);

    summary["views"] = result.views;
    summary["registered"] = result.registered;
    summary["unregistered"] = result.unregistered;
    summary["points"] = result.points;
    summary["pseudo_rgb"] = options.pseudo_rgb_spec;
    summary["stretch_linear"] = {stretch.low, stretch.high};
    summary["poses"] = run_sfm ? "colmap" : fs::absolute(options.poses).string();
    if (run_sfm) {
      summary["matcher"] = options.colmap.matcher;
      summary["camera_model"] = options.colmap.camera_model;
      summary["colmap_settings"] = options.colmap.settings;
      fs::rename(failed_log, tmp / "colmap.log");
    }
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    summary["seconds"] = result.seconds;
    write_file_atomically(tmp / "process.json", summary.dump(2) + "\n");
  });
  if (!result.unregistered.empty()) {
    std::string names;
    for (const auto& n : result.unregistered) names += (names.empty() ? "" : ", ") + n;
    core::log_warn("process: " + std::to_string(result.unregistered.size()) + " of " +
                   std::to_string(result.views) + " views have no pose and are left out: " + names);
  }
  return result;
}

}  // namespace ddhgs::process
