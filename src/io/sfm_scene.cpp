// `ddhgs process`, last step: COLMAP poses -> transforms.json, sparse points
// with per-band spectra, and the whole command built in a temporary folder.
#include <nlohmann/json.hpp>

#include <chrono>
#include <map>

#include "core/error.h"
#include "core/log.h"
#include "io/atomic_file.h"
#include "io/dataset.h"
#include "io/files/output_folder.h"
#include "io/ply.h"
#include "io/sfm.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

std::map<std::string, size_t> cube_index_by_name(const CubeSet& cubes) {
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < cubes.names.size(); ++i) index[cubes.names[i]] = i;
  return index;
}

std::string stem_of(const std::string& name) {
  return fs::path(name).stem().string();
}

// The cube index of every image of model whose name matches a cube; -1 otherwise.
std::vector<int64_t> cube_of_images(const ColmapModel& model, const CubeSet& cubes) {
  auto index = cube_index_by_name(cubes);
  std::vector<int64_t> out;
  for (const auto& image : model.images) {
    auto it = index.find(stem_of(image.name));
    out.push_back(it == index.end() ? -1 : int64_t(it->second));
  }
  return out;
}

// Poses given with --poses: a COLMAP model folder (.bin or .txt) or a
// transforms.json, as a COLMAP model.
ColmapModel read_poses(const fs::path& poses) {
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

TransformsFile transforms_from_colmap(const ColmapModel& model, const CubeSet& cubes,
                                      const std::vector<std::string>& cube_paths) {
  TransformsFile file;
  file.wavelengths_nm = cubes.wavelengths_nm;
  std::vector<int64_t> cube_of = cube_of_images(model, cubes);
  std::vector<const ColmapImage*> image_of_cube(cubes.names.size(), nullptr);
  for (size_t i = 0; i < model.images.size(); ++i)
    if (cube_of[i] >= 0) image_of_cube[size_t(cube_of[i])] = &model.images[i];
  for (size_t c = 0; c < cubes.names.size(); ++c) {
    const ColmapImage* image = image_of_cube[c];
    if (!image) continue;
    core::Camera camera = colmap_camera(model, *image);
    const auto& k = camera.intrinsics;
    const std::string origin = "COLMAP camera " + std::to_string(image->camera_id);
    core::require(!k.has_distortion(),
                  origin +
                      " has lens distortion; ddhgs renders undistorted pinhole cameras "
                      "(undistort first, e.g. colmap image_undistorter)");
    core::require(k.width == cubes.width && k.height == cubes.height,
                  origin + " is " + std::to_string(k.width) + "x" + std::to_string(k.height) +
                      " pixels, but the cubes are " + std::to_string(cubes.width) + "x" +
                      std::to_string(cubes.height));
    TransformsFrame frame;
    frame.file_path = "images/" + cubes.names[c] + ".png";
    frame.hyperspectral_file_path = cube_paths[c];
    frame.intrinsics = k;
    frame.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(camera.world_to_camera);
    file.frames.push_back(frame);
  }
  return file;
}

ColmapModel colmap_from_transforms(const TransformsFile& file) {
  ColmapModel model;
  for (size_t i = 0; i < file.frames.size(); ++i) {
    const auto& f = file.frames[i];
    const auto& k = f.intrinsics;
    ColmapCamera camera;
    camera.model = k.has_distortion() ? "OPENCV" : "PINHOLE";
    camera.width = k.width;
    camera.height = k.height;
    camera.params = {k.fx, k.fy, k.cx, k.cy};
    if (k.has_distortion()) camera.params.insert(camera.params.end(), {k.k1, k.k2, k.p1, k.p2});
    int id = 0;
    for (const auto& [existing_id, existing] : model.cameras)
      if (existing.model == camera.model && existing.width == camera.width &&
          existing.height == camera.height && existing.params == camera.params)
        id = existing_id;
    if (id == 0) {
      id = int(model.cameras.size()) + 1;
      camera.camera_id = id;
      model.cameras[id] = camera;
    }
    core::Mat4 w2c = core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl);
    ColmapImage image;
    image.image_id = int(i) + 1;
    image.camera_id = id;
    image.name = f.file_path.empty() ? f.hyperspectral_file_path : f.file_path;
    image.qvec = core::rotation_to_quat(w2c.rotation());
    image.tvec = w2c.translation();
    model.images.push_back(image);
  }
  return model;
}

torch::Tensor sample_point_spectra(const ColmapModel& model, const CubeSet& cubes) {
  const int64_t points = int64_t(model.points.size()), bands = cubes.bands;
  std::map<int64_t, int64_t> point_index;
  for (int64_t i = 0; i < points; ++i) point_index[model.points[size_t(i)].point3d_id] = i;
  std::vector<int64_t> cube_of = cube_of_images(model, cubes);

  torch::Tensor sums = torch::zeros({points, bands}, torch::kFloat64);  // [P, N]
  torch::Tensor counts = torch::zeros({points}, torch::kFloat64);       // [P]
  core::ProgressBar bar("point spectra", int64_t(model.images.size()));
  for (size_t i = 0; i < model.images.size(); ++i) {
    bar.update(int64_t(i) + 1);
    const ColmapImage& image = model.images[i];
    if (cube_of[i] < 0) continue;
    std::vector<int64_t> pixel, owner;
    for (size_t k = 0; k < image.point3d_ids.size(); ++k) {
      auto it = point_index.find(image.point3d_ids[k]);
      if (it == point_index.end()) continue;
      // COLMAP puts pixel centres at (x + 0.5, y + 0.5), as ddhgs does.
      auto x = int64_t(std::floor(image.xys[k][0])), y = int64_t(std::floor(image.xys[k][1]));
      if (x < 0 || y < 0 || x >= cubes.width || y >= cubes.height) continue;
      pixel.push_back(y * cubes.width + x);
      owner.push_back(it->second);
    }
    if (pixel.empty()) continue;
    const fs::path& file = cubes.files[size_t(cube_of[i])];
    Cube cube = read_cube(file);
    require_bands(file, cube.bands(), bands);
    torch::Tensor values = cube_to_float(cube).reshape({-1, bands});  // [H * W, N]
    torch::Tensor rows = values.index_select(0, torch::tensor(pixel)).to(torch::kFloat64);
    torch::Tensor who = torch::tensor(owner);
    sums.index_add_(0, who, rows);
    counts.index_add_(0, who, torch::ones({int64_t(owner.size())}, torch::kFloat64));
  }
  bar.finish();
  torch::Tensor seen = counts > 0;
  torch::Tensor spectra = sums / counts.clamp_min(1).unsqueeze(1);
  if (seen.any().item<bool>()) {
    torch::Tensor fallback = spectra.index({seen}).mean(0);  // [N]
    spectra.index_put_({~seen}, fallback);
  }
  return spectra.to(torch::kFloat32);
}

ProcessResult process_cubes(const ProcessOptions& options) {
  auto start = std::chrono::steady_clock::now();
  // "scene/" names the folder scene: the temporary sibling needs its name.
  fs::path out = options.out.lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  const bool run_sfm = options.poses.empty();
  if (run_sfm) check_colmap_options(options.colmap);
  const OutputRequest request{
      out, OutputKind::Scene, options.force, {options.cubes_dir, options.poses}};
  check_output_folder(request);
  if (run_sfm) find_colmap(options.colmap);
  CubeSet cubes = scan_cubes(options.cubes_dir, options.wavelengths);
  core::log_info("process: " + std::to_string(cubes.files.size()) + " cubes of " +
                 std::to_string(cubes.width) + "x" + std::to_string(cubes.height) + " px, " +
                 std::to_string(cubes.bands) + " bands");

  fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  fs::create_directories(parent);
  // The log lives beside the output while COLMAP runs, so a failed run keeps it.
  fs::path failed_log = parent / (out.filename().string() + ".colmap.log");
  fs::remove(failed_log);
  ProcessResult result;
  result.views = int(cubes.files.size());
  write_folder_atomically(request, [&](const fs::path& tmp) {
    Stretch stretch = write_pseudo_rgb_images(cubes, options.pseudo_rgb, tmp / "images");
    ColmapModel model;
    if (run_sfm) {
      run_colmap(options.colmap, tmp / "images", tmp / "colmap", failed_log);
      model = largest_colmap_model(tmp / "colmap" / "sparse");
    } else {
      model = read_poses(options.poses);
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
    for (const auto& file : cubes.files) cube_paths.push_back(relative_to(file, out));
    TransformsFile transforms = transforms_from_colmap(model, cubes, cube_paths);
    PointCloud cloud = points_of(model, cubes);
    if (cloud.xyz.defined()) {
      write_point_ply(tmp / "points.ply", cloud);
      transforms.ply_file_path = "points.ply";
      result.points = cloud.xyz.size(0);
    }
    write_transforms(tmp / "transforms.json", transforms);
    write_colmap_binary(tmp / "sparse" / "0", model);

    nlohmann::json summary = {{"generator", "ddhgs process"},
                              {"cubes_dir", fs::absolute(options.cubes_dir).string()},
                              {"views", result.views},
                              {"registered", result.registered},
                              {"unregistered", result.unregistered},
                              {"points", result.points},
                              {"pseudo_rgb", options.pseudo_rgb_spec},
                              {"stretch_linear", {stretch.low, stretch.high}},
                              {"poses", run_sfm ? "colmap" : fs::absolute(options.poses).string()}};
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

}  // namespace ddhgs::io
