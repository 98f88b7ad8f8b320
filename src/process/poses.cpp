#include "process/poses.h"

#include <map>

#include "core/error.h"
#include "core/log.h"
#include "io/cube/cube.h"
#include "io/scene/scene.h"

namespace ddhgs::process {
namespace fs = std::filesystem;
using namespace io;

namespace {

std::map<std::string, size_t> cube_index_by_name(const CubeSet& cubes) {
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < cubes.names.size(); ++i) index[cubes.names[i]] = i;
  return index;
}

std::string image_stem(const std::string& name) {
  return fs::path(name).stem().string();
}

}  // namespace

std::vector<int64_t> cube_of_images(const ColmapModel& model, const CubeSet& cubes) {
  auto index = cube_index_by_name(cubes);
  std::vector<int64_t> out;
  for (const auto& image : model.images) {
    auto it = index.find(image_stem(image.name));
    out.push_back(it == index.end() ? -1 : int64_t(it->second));
  }
  return out;
}

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
    // A camera with lens distortion keeps it: the scene's views are
    // undistorted when they load (io/undistort).
    core::Camera camera = colmap_camera(model, *image);
    const auto& k = camera.intrinsics;
    const std::string origin = "COLMAP camera " + std::to_string(image->camera_id);
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
    ColmapCamera camera = colmap_camera_of(f.intrinsics);
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

}  // namespace ddhgs::process
