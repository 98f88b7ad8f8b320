// load_scene: detects the layout on disk and gathers cameras, file paths,
// wavelengths, points and the split, reading only the first cube's header.
#include "io/scene/scene.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "core/error.h"
#include "core/text.h"
#include "io/colmap/colmap.h"
#include "io/scene/band_grid.h"
#include "io/scene/colmap_beside.h"
#include "io/transforms/transforms.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// A view found in the dataset description, at full resolution.
struct LayoutCandidate {
  std::string name;
  std::string sort_key;
  core::Camera camera;
  fs::path data_path;  // empty when missing on disk
  fs::path clean_path;
  std::vector<std::string> split_keys;  // normalised relative paths
  std::vector<int> bands;               // source bands the file holds (empty: all)
  int rig_camera = -1;
  // After band selection: the scene band and file band of each one kept.
  std::vector<int> scene_bands, file_bands;
};

struct Found {
  std::string layout;
  std::vector<LayoutCandidate> views;
  std::vector<std::string> warnings, notes;
  std::vector<double> wavelengths_nm;
  std::optional<double> scale;
  std::optional<TransformsRig> rig;
  PointCloud points;
  fs::path points_file;  // points.ply, when the points came from one
  bool rgb = false;
  bool explicit_split = false;
  std::set<std::string> train_keys, test_keys;
};

std::string normal(const std::string& relative) {
  return fs::path(relative).lexically_normal().generic_string();
}

// rel = "images/r_0.png", d = 2: "images_2/r_0.png" when that file exists.
fs::path existing_data(const fs::path& root, const fs::path& rel, int d) {
  fs::path norm = rel.lexically_normal();
  if (d > 1 && norm.has_parent_path()) {
    auto first = norm.begin();
    fs::path reduced = root / (first->string() + "_" + std::to_string(d));
    for (auto it = std::next(first); it != norm.end(); ++it) reduced /= *it;
    if (fs::exists(reduced)) return reduced;
  }
  return fs::exists(root / norm) ? root / norm : fs::path();
}

// Clean ground truth beside the dataset: clean/<file name>, or clean_<d>/.
fs::path clean_for(const fs::path& root, const fs::path& data, int d) {
  return existing_data(root, fs::path("clean") / data.filename(), d);
}

bool orthonormal(const core::Mat3& r) {
  core::Mat3 rtr = r.transposed() * r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (std::abs(rtr(i, j) - (i == j ? 1.0 : 0.0)) > 1e-6) return false;
  return true;
}

// A transforms.json whose cubes are all missing (Hyper-NeRF's published
// files point at cubes that were never released): one error instead of a
// warning per frame, naming --rgb when the frames' RGB images are there.
void require_some_cube(const fs::path& root, const TransformsFile& tf, const fs::path& file,
                       int downscale) {
  size_t images = 0;
  for (const auto& f : tf.frames) {
    if (!existing_data(root, f.hyperspectral_file_path, downscale).empty()) return;
    if (!f.file_path.empty() && !existing_data(root, f.file_path, downscale).empty()) ++images;
  }
  std::string n = std::to_string(tf.frames.size());
  std::string message = "none of the " + n +
                        " hyperspectral cubes (hyperspectral_file_path) is on disk, e.g. " +
                        (root / tf.frames.front().hyperspectral_file_path).string();
  if (images > 0)
    message += "; the frames' RGB images (file_path) are there for " + std::to_string(images) +
               " of " + n + " frames: train on those as a 3-band scene with --rgb";
  throw core::Error(file, message);
}

// Initial points: the file's ply_file_path, else the COLMAP model beside it
// when it shares (or can be mapped into) the file's frame.
void find_points(const fs::path& root, const TransformsFile& tf, const fs::path& file,
                 Found& found) {
  if (!tf.ply_file_path.empty()) {
    fs::path ply = root / tf.ply_file_path;
    if (fs::exists(ply)) {
      found.points = read_point_ply(ply);
      found.points_file = ply;
    } else
      found.warnings.push_back(file.string() + ": ply_file_path " + ply.string() +
                               " does not exist; no initial points");
    return;
  }
  auto model_dir = find_colmap_model(root);
  if (!model_dir) return;
  PointsBeside beside = points_beside(*model_dir, tf, file);
  found.points = beside.points;
  (beside.points.xyz.defined() ? found.notes : found.warnings).push_back(beside.message);
}

Found from_transforms(const fs::path& root, const LoadOptions& options) {
  fs::path file = root / "transforms.json";
  TransformsFile tf = read_transforms(file);
  Found found;
  found.layout = "transforms.json";
  found.wavelengths_nm = tf.wavelengths_nm;
  found.scale = tf.scale;
  found.rig = tf.rig;
  bool any_cube = false, all_cubes = true;
  for (const auto& f : tf.frames) {
    any_cube = any_cube || !f.hyperspectral_file_path.empty();
    all_cubes = all_cubes && !f.hyperspectral_file_path.empty();
  }
  if (any_cube && !all_cubes && !options.rgb)
    throw core::Error(file, "some frames have hyperspectral_file_path and some do not");
  found.rgb = options.rgb || !any_cube;
  if (!found.rgb) require_some_cube(root, tf, file, options.downscale);

  int repaired = 0;
  for (size_t i = 0; i < tf.frames.size(); ++i) {
    const auto& f = tf.frames[i];
    const std::string& rel = found.rgb ? f.file_path : f.hyperspectral_file_path;
    if (rel.empty())
      throw core::Error(file,
                        "frames[" + std::to_string(i) + "] has no file_path (needed by --rgb)");
    LayoutCandidate c;
    c.name = fs::path(rel).stem().string();
    c.sort_key = normal(f.file_path.empty() ? rel : f.file_path);
    c.split_keys = {normal(rel)};
    if (!f.file_path.empty()) c.split_keys.push_back(normal(f.file_path));
    if (!orthonormal(f.camera_to_world_gl.rotation())) ++repaired;
    c.camera.intrinsics = f.intrinsics;
    c.camera.world_to_camera = core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl);
    c.bands = f.bands;
    c.rig_camera = f.rig_camera;
    c.data_path = existing_data(root, rel, options.downscale);
    if (c.data_path.empty())
      found.warnings.push_back("frames[" + std::to_string(i) + "]: missing file " +
                               (root / rel).string() + "; frame skipped");
    else if (!found.rgb)
      c.clean_path = clean_for(root, rel, options.downscale);
    found.views.push_back(std::move(c));
  }
  if (repaired > 0)
    found.warnings.push_back(file.string() + ": " + std::to_string(repaired) +
                             " frame(s) have scaled or non-orthonormal rotations "
                             "(re-orthonormalised)");

  found.explicit_split = !tf.train_files.empty() || !tf.test_files.empty();
  for (const auto& s : tf.train_files) found.train_keys.insert(normal(s));
  for (const auto& s : tf.test_files) found.test_keys.insert(normal(s));

  find_points(root, tf, file, found);
  return found;
}

using core::lower;

// Cube files of a folder by stem; .hdr stands for an ENVI pair.
std::map<std::string, fs::path> cubes_by_stem(const fs::path& dir) {
  static const std::vector<std::string> exts = {".npy", ".pt", ".hdr", ".tif", ".tiff"};
  std::map<std::string, fs::path> out;
  if (!fs::is_directory(dir)) return out;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    auto rank = std::find(exts.begin(), exts.end(), lower(entry.path().extension().string()));
    if (rank == exts.end()) continue;
    std::string stem = entry.path().stem().string();
    auto it = out.find(stem);
    // Several formats with one stem: the earlier extension in the list wins.
    if (it == out.end() ||
        rank < std::find(exts.begin(), exts.end(), lower(it->second.extension().string())))
      out[stem] = entry.path();
  }
  return out;
}

bool is_reserved_folder(const std::string& name) {
  for (const char* prefix : {"images", "sparse", "colmap", "clean"})
    if (name.rfind(prefix, 0) == 0) return true;
  return name.empty() || name[0] == '.';
}

// The folder of cubes: hyperspectral/, cubes/, else any folder holding a cube
// named like a COLMAP image. Empty when there is none (an RGB dataset).
fs::path find_cube_folder(const fs::path& root, const std::set<std::string>& stems) {
  std::vector<fs::path> order = {root / "hyperspectral", root / "cubes"};
  std::vector<fs::path> others;
  for (const auto& entry : fs::directory_iterator(root))
    if (entry.is_directory() && !is_reserved_folder(entry.path().filename().string()))
      others.push_back(entry.path());
  std::sort(others.begin(), others.end());
  order.insert(order.end(), others.begin(), others.end());
  for (const auto& dir : order)
    for (const auto& [stem, path] : cubes_by_stem(dir))
      if (stems.count(stem)) return dir;
  return {};
}

Found from_colmap(const fs::path& root, const fs::path& model_dir, const LoadOptions& options) {
  ColmapModel model = read_colmap(model_dir);
  core::require(!model.images.empty(), model_dir, "the COLMAP model has no images");
  Found found;
  found.layout = "colmap";
  std::set<std::string> stems;
  for (const auto& image : model.images) stems.insert(fs::path(image.name).stem().string());
  fs::path cube_dir = options.rgb ? fs::path() : find_cube_folder(root, stems);
  found.rgb = cube_dir.empty();
  std::map<std::string, fs::path> cubes = cubes_by_stem(cube_dir);
  std::map<std::string, fs::path> reduced_cubes;
  if (!cube_dir.empty() && options.downscale > 1)
    reduced_cubes = cubes_by_stem(cube_dir.string() + "_" + std::to_string(options.downscale));

  for (const auto& image : model.images) {
    LayoutCandidate c;
    c.name = fs::path(image.name).stem().string();
    c.sort_key = image.name;
    c.split_keys = {normal(image.name)};
    c.camera = colmap_camera(model, image);
    if (found.rgb) {
      c.data_path = existing_data(root, fs::path("images") / image.name, options.downscale);
    } else if (reduced_cubes.count(c.name)) {
      c.data_path = reduced_cubes[c.name];
    } else if (cubes.count(c.name)) {
      c.data_path = cubes[c.name];
    }
    if (c.data_path.empty())
      found.warnings.push_back("COLMAP image " + image.name + ": no " +
                               (found.rgb ? "image under " + (root / "images").string()
                                          : "cube named " + c.name + " in " + cube_dir.string()) +
                               "; view skipped");
    else if (!found.rgb)
      c.clean_path = clean_for(root, c.data_path, options.downscale);
    found.views.push_back(std::move(c));
  }

  found.points = colmap_points(model);
  return found;
}

// Views of cameras with lens distortion share one Undistortion per distinct
// camera and see its pinhole camera from here on.
void undistort_cameras(Scene& scene, const fs::path& origin) {
  std::vector<std::shared_ptr<const Undistortion>> lenses;
  size_t distorted = 0;
  for (View& v : scene.views) {
    const core::Intrinsics& lens = v.camera.intrinsics;
    if (!lens.has_distortion()) continue;
    ++distorted;
    auto same = std::find_if(lenses.begin(), lenses.end(),
                             [&](const auto& u) { return u->lens() == lens; });
    if (same == lenses.end()) {
      try {
        lenses.push_back(std::make_shared<const Undistortion>(lens));
      } catch (const core::Error& e) {
        throw core::Error(origin, e.what());
      }
      same = std::prev(lenses.end());
    }
    v.undistortion = *same;
    v.camera.intrinsics = (*same)->pinhole();
  }
  if (distorted == 0) return;
  double lo = INFINITY, hi = 0;
  for (const auto& u : lenses) {
    lo = std::min(lo, u->pinhole().fx / u->lens().fx);
    hi = std::max(hi, u->pinhole().fx / u->lens().fx);
  }
  char scale[64];
  std::snprintf(scale, sizeof scale, lo == hi ? "%.4g" : "%.4g-%.4g", lo, hi);
  scene.notes.push_back("undistorting " + std::to_string(distorted) + " views (" +
                        std::to_string(lenses.size()) +
                        " camera(s) with lens distortion) to pinhole cameras of the same size, "
                        "focal lengths x" +
                        scale + ": cropped to what the lens saw, no blank pixels");
}

void assign_split(Scene& scene, const Found& found, const std::vector<LayoutCandidate>& kept,
                  const fs::path& origin) {
  if (!found.explicit_split) {
    hypernerf_split(int(kept.size()), scene.train, scene.test);
    return;
  }
  auto in = [](const std::set<std::string>& keys, const LayoutCandidate& c) {
    return std::any_of(c.split_keys.begin(), c.split_keys.end(),
                       [&](const std::string& k) { return keys.count(k) > 0; });
  };
  for (size_t i = 0; i < kept.size(); ++i) {
    bool train = in(found.train_keys, kept[i]), test = in(found.test_keys, kept[i]);
    if (train && test)
      throw core::Error(origin, kept[i].split_keys.front() +
                                    " is listed in both train_filenames and test_filenames");
    if (train) scene.train.push_back(int(i));
    if (test) scene.test.push_back(int(i));
    if (!train && !test)
      scene.warnings.push_back(kept[i].split_keys.front() +
                               " is in neither train_filenames nor test_filenames; unused");
  }
  core::require(!scene.train.empty(), origin, "train_filenames matches no frame on disk");
}

}  // namespace

std::unique_ptr<Scene> load_scene(const fs::path& dir, const LoadOptions& options) {
  fs::path root = fs::is_regular_file(dir) ? dir.parent_path() : dir;
  core::require(fs::is_directory(root), root, "dataset folder does not exist");
  core::require(options.downscale >= 1, "--downscale must be at least 1");

  Found found;
  fs::path origin = root / "transforms.json";
  if (fs::exists(origin)) {
    found = from_transforms(root, options);
  } else if (auto model_dir = find_colmap_model(root)) {
    origin = *model_dir;
    found = from_colmap(root, *model_dir, options);
  } else {
    throw core::Error(root,
                      "expected transforms.json or a COLMAP model (sparse/0 or "
                      "colmap/sparse/0) in the dataset folder");
  }

  auto scene = std::make_unique<Scene>();
  scene->root = root;
  scene->layout = found.layout;
  scene->options = options;
  scene->warnings = found.warnings;
  scene->notes = found.notes;
  scene->points = found.points;
  scene->rig = found.rig;
  scene->georef = find_georeference(root);

  // Sorted as nerfstudio sorts frames, so split indices match its own.
  std::vector<LayoutCandidate> kept;
  for (auto& c : found.views)
    if (!c.data_path.empty()) kept.push_back(c);
  std::stable_sort(
      kept.begin(), kept.end(),
      [](const LayoutCandidate& a, const LayoutCandidate& b) { return a.sort_key < b.sort_key; });
  if (kept.empty())
    throw core::Error(origin, "none of the " + std::to_string(found.views.size()) +
                                  " listed views has its file on disk");

  // A band-per-view scene: frames name the bands their files hold.
  const bool per_view = std::any_of(kept.begin(), kept.end(),
                                    [](const LayoutCandidate& c) { return !c.bands.empty(); });
  if (per_view && (found.rgb || options.bin > 1 || options.band_step > 1))
    throw core::Error(origin, std::string("frames name the bands their files hold (a band-per-view "
                                          "scene), which ") +
                                  (found.rgb         ? "--rgb cannot load"
                                   : options.bin > 1 ? "cannot be binned (--bin)"
                                                     : "cannot hold bands out (data.band_step)"));
  CubeInfo first = probe_cube(kept.front().data_path, CubeReadOptions{options.layout});
  scene->stored_type = first.type;
  scene->source_bands = per_view ? int64_t(found.wavelengths_nm.size()) : first.bands;
  if (per_view && !kept.front().bands.empty())
    require_named_bands(kept.front().data_path, first.bands, int64_t(kept.front().bands.size()));
  // LoadOptions::scale, then the dataset's scale, then the cube's own (ENVI's
  // reflectance scale factor), then the sample type's maximum.
  scene->scale = options.scale        ? *options.scale
                 : found.scale        ? *found.scale
                 : first.scale_factor ? *first.scale_factor
                                      : default_scale(first.type);
  core::require(scene->scale > 0, "--scale must be positive");

  select_bands(*scene,
               source_wavelengths(*scene, found.rgb, found.wavelengths_nm, first.wavelengths_nm,
                                  scene->source_bands, origin, kept.front().data_path),
               found.rgb, origin);
  const fs::path first_path = kept.front().data_path;
  if (per_view) {
    // Each view keeps the selected bands its file holds, in scene order.
    std::vector<int> scene_band_of(size_t(scene->source_bands), -1);
    for (size_t b = 0; b < scene->band_index.size(); ++b)
      scene_band_of[size_t(scene->band_index[b])] = int(b);
    std::vector<LayoutCandidate> with_bands;
    for (LayoutCandidate& c : kept) {
      if (c.bands.empty()) {
        with_bands.push_back(std::move(c));
        continue;
      }
      std::vector<std::pair<int, int>> pairs;  // scene band, file band
      for (size_t j = 0; j < c.bands.size(); ++j)
        if (scene_band_of[size_t(c.bands[j])] >= 0)
          pairs.emplace_back(scene_band_of[size_t(c.bands[j])], int(j));
      std::sort(pairs.begin(), pairs.end());
      for (const auto& [scene_band, file_band] : pairs) {
        c.scene_bands.push_back(scene_band);
        c.file_bands.push_back(file_band);
      }
      if (!pairs.empty()) with_bands.push_back(std::move(c));
    }
    if (with_bands.size() < kept.size())
      scene->notes.push_back(std::to_string(kept.size() - with_bands.size()) +
                             " view(s) hold no band in the selected range; left out");
    if (with_bands.empty()) throw core::Error(origin, "no view holds a band in the selected range");
    kept = std::move(with_bands);
  }

  // Spectra per point are the cubes' bands (before --band-range and --bin).
  const torch::Tensor& spectra = found.points.spectra;
  if (!found.rgb && spectra.defined() && spectra.size(1) != scene->source_bands)
    throw core::Error(found.points_file, "holds " + std::to_string(spectra.size(1)) +
                                             " spectral values per point (spec_*)" +
                                             ", but the cubes have " +
                                             std::to_string(scene->source_bands) + " bands");
  // A downscale that leaves nothing of a view is a mistyped flag, said as
  // such before anything is read.
  for (const auto& c : kept) {
    const int w = int(c.camera.intrinsics.width), h = int(c.camera.intrinsics.height);
    if (std::min(w, h) / options.downscale < 1)
      throw core::Error("--downscale " + std::to_string(options.downscale) + ": view " + c.name +
                        " is " + std::to_string(w) + " x " + std::to_string(h) +
                        " px, which leaves no pixel; at most " +
                        std::to_string(std::max(1, std::min(w, h))));
  }
  for (const auto& c : kept)
    if (const std::string problem = core::camera_problem(c.camera); !problem.empty())
      throw core::Error(origin, "view " + c.name + ": " + problem);
  for (const auto& c : kept) {
    View v;
    v.name = c.name;
    v.camera = c.camera;
    v.camera.intrinsics = c.camera.intrinsics.downscaled(options.downscale);
    v.data_path = c.data_path;
    v.clean_path = c.clean_path;
    v.bands = c.scene_bands;
    v.file_bands = c.file_bands;
    v.file_band_count = int64_t(c.bands.size());
    v.rig_camera = c.rig_camera;
    scene->views.push_back(std::move(v));
  }
  if (kept.front().data_path == first_path)
    area_factor(first_path, first.height, first.width, scene->views.front().camera.intrinsics,
                options.downscale);
  undistort_cameras(*scene, origin);

  assign_split(*scene, found, kept, origin);
  return scene;
}

}  // namespace ddhgs::io
