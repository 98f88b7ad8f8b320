// load_scene: detects the layout on disk and gathers cameras, file paths,
// wavelengths, points and the split, reading only the first cube's header.
#include "io/scene/scene.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <set>

#include "core/error.h"
#include "core/log.h"
#include "io/colmap/colmap.h"
#include "io/transforms/transforms.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// A view found in the dataset description, at full resolution.
struct Candidate {
  std::string name;
  std::string sort_key;
  core::Camera camera;
  fs::path data_path;  // empty when missing on disk
  fs::path clean_path;
  std::vector<std::string> split_keys;  // normalised relative paths
};

struct Found {
  std::string layout;
  std::vector<Candidate> views;
  std::vector<std::string> warnings;
  std::vector<double> wavelengths_nm;
  std::optional<double> scale;
  PointCloud points;
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

Found from_transforms(const fs::path& root, const LoadOptions& options) {
  fs::path file = root / "transforms.json";
  TransformsFile tf = read_transforms(file);
  Found found;
  found.layout = "transforms.json";
  found.wavelengths_nm = tf.wavelengths_nm;
  found.scale = tf.scale;
  bool any_cube = false, all_cubes = true;
  for (const auto& f : tf.frames) {
    any_cube = any_cube || !f.hyperspectral_file_path.empty();
    all_cubes = all_cubes && !f.hyperspectral_file_path.empty();
  }
  if (any_cube && !all_cubes && !options.rgb)
    throw core::Error(file, "some frames have hyperspectral_file_path and some do not");
  found.rgb = options.rgb || !any_cube;

  int repaired = 0;
  for (size_t i = 0; i < tf.frames.size(); ++i) {
    const auto& f = tf.frames[i];
    const std::string& rel = found.rgb ? f.file_path : f.hyperspectral_file_path;
    if (rel.empty())
      throw core::Error(file,
                        "frames[" + std::to_string(i) + "] has no file_path (needed by --rgb)");
    Candidate c;
    c.name = fs::path(rel).stem().string();
    c.sort_key = normal(f.file_path.empty() ? rel : f.file_path);
    c.split_keys = {normal(rel)};
    if (!f.file_path.empty()) c.split_keys.push_back(normal(f.file_path));
    if (!orthonormal(f.camera_to_world_gl.rotation())) ++repaired;
    c.camera.intrinsics = f.intrinsics;
    c.camera.world_to_camera = core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl);
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

  if (!tf.ply_file_path.empty()) {
    fs::path ply = root / tf.ply_file_path;
    if (fs::exists(ply))
      found.points = read_point_ply(ply);
    else
      found.warnings.push_back(file.string() + ": ply_file_path " + ply.string() +
                               " does not exist; no initial points");
  }
  return found;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

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
    Candidate c;
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

// Assumed grid when neither the dataset nor the cubes name wavelengths: the
// two sensors of the Hyper-NeRF data by band count, else BaySpec's range.
std::vector<double> assumed_wavelengths(int64_t bands, std::string* range) {
  double lo = 400, hi = 1100;
  if (bands == 128) lo = 370;
  *range = std::to_string(int(lo)) + "-" + std::to_string(int(hi)) + " nm";
  std::vector<double> out;
  for (int64_t b = 0; b < bands; ++b)
    out.push_back(bands > 1 ? lo + (hi - lo) * double(b) / double(bands - 1) : lo);
  return out;
}

void select_bands(Scene& scene, const std::vector<double>& source_nm, const fs::path& origin) {
  const LoadOptions& o = scene.options;
  core::require(o.bin >= 1, "--bin must be at least 1");
  std::vector<int> kept;
  for (size_t b = 0; b < source_nm.size(); ++b)
    if (source_nm[b] >= o.band_min_nm && source_nm[b] <= o.band_max_nm) kept.push_back(int(b));
  if (kept.empty())
    throw core::Error(origin, "no band lies in the requested range " +
                                  std::to_string(o.band_min_nm) + "-" +
                                  std::to_string(o.band_max_nm) + " nm");
  size_t groups = kept.size() / size_t(o.bin);
  if (groups == 0)
    throw core::Error(origin, "only " + std::to_string(kept.size()) +
                                  " bands selected, fewer than --bin " + std::to_string(o.bin));
  if (kept.size() % size_t(o.bin) != 0)
    scene.warnings.push_back("binning by " + std::to_string(o.bin) + " drops the last " +
                             std::to_string(kept.size() % size_t(o.bin)) + " band(s)");
  kept.resize(groups * size_t(o.bin));
  scene.band_index = kept;
  scene.wavelengths_nm.clear();
  for (size_t g = 0; g < groups; ++g) {
    double sum = 0;
    for (int k = 0; k < o.bin; ++k) sum += source_nm[size_t(kept[g * size_t(o.bin) + size_t(k)])];
    scene.wavelengths_nm.push_back(sum / o.bin);
  }
}

void assign_split(Scene& scene, const Found& found, const std::vector<Candidate>& kept,
                  const fs::path& origin) {
  if (!found.explicit_split) {
    hypernerf_split(int(kept.size()), scene.train, scene.test);
    return;
  }
  auto in = [](const std::set<std::string>& keys, const Candidate& c) {
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
  scene->points = found.points;

  // Sorted as nerfstudio sorts frames, so split indices match its own.
  std::vector<Candidate> kept;
  for (auto& c : found.views)
    if (!c.data_path.empty()) kept.push_back(c);
  std::stable_sort(kept.begin(), kept.end(),
                   [](const Candidate& a, const Candidate& b) { return a.sort_key < b.sort_key; });
  if (kept.empty())
    throw core::Error(origin, "none of the " + std::to_string(found.views.size()) +
                                  " listed views has its file on disk");

  CubeInfo first = probe_cube(kept.front().data_path, CubeReadOptions{options.layout});
  scene->stored_type = first.type;
  scene->source_bands = first.bands;
  scene->scale = options.scale ? *options.scale
                 : found.scale ? *found.scale
                               : default_scale(first.type);
  core::require(scene->scale > 0, "--scale must be positive");

  std::vector<double> source_nm;
  if (found.rgb) {
    core::require(first.bands == 3, kept.front().data_path,
                  "expected an RGB image (3 channels), found " + std::to_string(first.bands));
    source_nm = rgb_wavelengths_nm();
  } else if (!found.wavelengths_nm.empty()) {
    if (int64_t(found.wavelengths_nm.size()) != first.bands)
      throw core::Error(origin, "lists " + std::to_string(found.wavelengths_nm.size()) +
                                    " wavelengths, but " + kept.front().data_path.string() +
                                    " has " + std::to_string(first.bands) + " bands");
    source_nm = found.wavelengths_nm;
  } else if (int64_t(first.wavelengths_nm.size()) == first.bands) {
    source_nm = first.wavelengths_nm;
  } else {
    std::string range;
    source_nm = assumed_wavelengths(first.bands, &range);
    scene->warnings.push_back("no wavelengths in the dataset or its cubes; assuming " +
                              std::to_string(first.bands) + " bands evenly spaced over " + range);
  }
  select_bands(*scene, source_nm, origin);

  for (const auto& c : kept) {
    View v;
    v.name = c.name;
    v.camera = c.camera;
    v.camera.intrinsics = c.camera.intrinsics.downscaled(options.downscale);
    v.data_path = c.data_path;
    v.clean_path = c.clean_path;
    scene->views.push_back(std::move(v));
  }
  area_factor(kept.front().data_path, first.height, first.width,
              scene->views.front().camera.intrinsics, options.downscale);

  assign_split(*scene, found, kept, origin);
  const size_t shown = 5;
  for (size_t i = 0; i < scene->warnings.size() && i < shown; ++i)
    core::log_warn(scene->warnings[i]);
  if (scene->warnings.size() > shown)
    core::log_warn("... and " + std::to_string(scene->warnings.size() - shown) +
                   " more warnings (ddhgs info lists them all)");
  return scene;
}

}  // namespace ddhgs::io
