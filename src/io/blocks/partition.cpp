#include "io/blocks/partition.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "core/error.h"
#include "core/log.h"
#include "io/blocks/ground.h"
#include "io/files/output_folder.h"
#include "io/ply/ply.h"
#include "io/scene/backdrop.h"
#include "io/scene/scene.h"
#include "io/transforms/transforms.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

std::pair<int, int> grid_shape(int blocks, double length_u, double length_v) {
  std::pair<int, int> best{1, blocks};
  double best_error = 1e300;
  for (int rows = 1; rows <= blocks; ++rows) {
    if (blocks % rows != 0) continue;
    const int cols = blocks / rows;
    // How far a cell is from square, on a log scale (a flat footprint: 1 x N).
    const double cell_u = std::max(length_u, 1e-12) / cols;
    const double cell_v = std::max(length_v, 1e-12) / rows;
    const double error = std::abs(std::log(cell_u / cell_v));
    if (error < best_error - 1e-9) {
      best_error = error;
      best = {rows, cols};
    }
  }
  return best;
}

torch::Tensor flight_backdrop(const Scene& scene, const std::vector<int>& views) {
  std::vector<bool> held(size_t(scene.bands()), false);
  for (const int v : views) {
    const std::vector<int>& bands = scene.views[size_t(v)].bands;
    if (bands.empty()) held.assign(held.size(), true);
    for (const int b : bands) held[size_t(b)] = true;
  }
  for (size_t b = 0; b < held.size(); ++b)
    core::require(held[b], scene.root,
                  "no training view holds band " + std::to_string(b) + " (" +
                      core::format_g(scene.wavelengths_nm[b]) +
                      " nm): the flight's backdrop needs every band");
  return sampled_colour(scene, views, kBackdropViews, kBackdropPixels);
}

namespace {

// A frame's path relative to the scene, refused when it leaves the folder.
std::string inside(const fs::path& transforms, size_t frame, const std::string& rel) {
  const fs::path p = fs::path(rel).lexically_normal();
  core::require(!p.empty() && p.is_relative() && *p.begin() != "..", transforms,
                "frames[" + std::to_string(frame) + "]: " + rel +
                    " lies outside the scene folder; partition copies each block's files "
                    "beside its transforms.json");
  return p.generic_string();
}

// A hard link where the file system allows (a block costs no disk for its
// views), else a copy.
void place(const fs::path& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  std::error_code ec;
  fs::create_hard_link(from, to, ec);
  if (ec) fs::copy_file(from, to);
}

struct Source {
  fs::path root, transforms_path;
  TransformsFile transforms;
  std::unique_ptr<Scene> scene;
  std::vector<size_t> frame_of_view;  // frames[] index of each loaded view
  std::set<int> test;                 // held-out views
  PointCloud points;
  bool has_points = false;
};

Source open_source(const fs::path& root) {
  Source s;
  s.root = root;
  s.transforms_path = root / "transforms.json";
  core::require(fs::is_regular_file(s.transforms_path), root,
                "partition needs a scene with a transforms.json (a COLMAP-only folder: run "
                "ddhgs process first)");
  s.transforms = read_transforms(s.transforms_path);
  const bool rgb =
      std::all_of(s.transforms.frames.begin(), s.transforms.frames.end(),
                  [](const TransformsFrame& f) { return f.hyperspectral_file_path.empty(); });
  std::map<std::string, size_t> by_path;
  for (size_t i = 0; i < s.transforms.frames.size(); ++i) {
    const TransformsFrame& f = s.transforms.frames[i];
    const std::string rel =
        inside(s.transforms_path, i, rgb ? f.file_path : f.hyperspectral_file_path);
    core::require(fs::exists(root / rel), s.transforms_path,
                  "frames[" + std::to_string(i) + "]: missing file " + (root / rel).string() +
                      " (a block would lose the view)");
    by_path[(root / rel).lexically_normal().string()] = i;
  }
  s.scene = load_scene(root);
  for (const View& v : s.scene->views) {
    const auto it = by_path.find(v.data_path.lexically_normal().string());
    core::require(it != by_path.end(), s.transforms_path, "no frame names " + v.data_path.string());
    s.frame_of_view.push_back(it->second);
  }
  s.test.insert(s.scene->test.begin(), s.scene->test.end());
  if (!s.transforms.ply_file_path.empty()) {
    s.points = read_point_ply(root / s.transforms.ply_file_path);
    s.has_points = s.points.xyz.defined() && s.points.xyz.size(0) > 0;
  }
  return s;
}

std::vector<core::Vec3> point_list(const PointCloud& cloud) {
  std::vector<core::Vec3> out;
  if (!cloud.xyz.defined()) return out;
  const torch::Tensor xyz = cloud.xyz.to(torch::kFloat64).contiguous();
  const double* p = xyz.data_ptr<double>();
  for (int64_t i = 0; i < xyz.size(0); ++i) out.push_back({p[3 * i], p[3 * i + 1], p[3 * i + 2]});
  return out;
}

// The rows of a point cloud whose index is in keep.
PointCloud subset(const PointCloud& cloud, const std::vector<int64_t>& keep) {
  const torch::Tensor index = torch::tensor(keep, torch::kInt64);
  PointCloud out;
  out.xyz = cloud.xyz.index_select(0, index);
  if (cloud.rgb.defined()) out.rgb = cloud.rgb.index_select(0, index);
  if (cloud.spectra.defined()) out.spectra = cloud.spectra.index_select(0, index);
  return out;
}

// One block's scene folder in `folder`: its frames, files and points.
void write_block(const Source& s, const std::vector<int>& views, const std::vector<int64_t>& points,
                 const BlockContext& context, const fs::path& folder, BlockRecord* record) {
  fs::create_directories(folder);
  TransformsFile tf = s.transforms;
  tf.frames.clear();
  tf.train_files.clear();
  tf.test_files.clear();
  for (const int v : views) {
    const size_t i = s.frame_of_view[size_t(v)];
    const TransformsFrame& f = s.transforms.frames[i];
    tf.frames.push_back(f);
    std::string key;
    for (const std::string& rel : {f.hyperspectral_file_path, f.file_path}) {
      if (rel.empty()) continue;
      const std::string within = inside(s.transforms_path, i, rel);
      if (key.empty()) key = within;
      if (fs::exists(s.root / within) && !fs::exists(folder / within))
        place(s.root / within, folder / within);
    }
    const fs::path& clean = s.scene->views[size_t(v)].clean_path;
    if (!clean.empty()) place(clean, folder / "clean" / clean.filename());
    (s.test.count(v) ? tf.test_files : tf.train_files).push_back(key);
    (s.test.count(v) ? record->test_views : record->train_views).push_back(key);
  }
  if (s.has_points && !points.empty()) {
    tf.ply_file_path = "points.ply";
    write_point_ply(folder / "points.ply", subset(s.points, points));
  } else {
    tf.ply_file_path.clear();
  }
  record->points = int64_t(points.size());
  write_transforms(folder / "transforms.json", tf);
  write_block_context(folder / kBlockContextFile, context);
  // The scene's other top-level files: wavelengths, georeferencing, notes.
  const fs::path ply = s.transforms.ply_file_path.empty()
                           ? fs::path()
                           : (s.root / s.transforms.ply_file_path).lexically_normal();
  for (const auto& entry : fs::directory_iterator(s.root)) {
    const std::string name = entry.path().filename().string();
    // A block's own block.json is this cut's, never its source's (a block
    // cut again is a flight of its own).
    if (!entry.is_regular_file() || name.empty() || name[0] == '.' || name == "transforms.json" ||
        name == kBlockContextFile || entry.path().lexically_normal() == ply ||
        fs::exists(folder / name))
      continue;
    place(entry.path(), folder / name);
  }
  mark_output_folder(folder, OutputKind::Scene);
}

}  // namespace

BlocksFile partition_scene(const PartitionOptions& options) {
  core::require(options.overlap >= 0 && options.overlap <= 1,
                "--overlap " + std::to_string(options.overlap) + ": expected 0 to 1");
  const OutputRequest request{options.out, OutputKind::Blocks, options.force, {options.scene}};
  check_output_folder(request);
  const Source s = open_source(options.scene);
  core::require(!s.scene->views.empty(), s.transforms_path, "no views to partition");

  std::vector<core::Camera> cameras;
  for (const View& v : s.scene->views) cameras.push_back(v.camera);
  BlocksFile file;
  file.scene = fs::absolute(options.scene).lexically_normal();
  BlockGrid& grid = file.grid;
  grid.frame = ground_frame(point_list(s.points), cameras);
  grid.overlap = options.overlap;
  std::vector<GroundBox> seen;
  for (const core::Camera& c : cameras) {
    seen.push_back(view_footprint(grid.frame, c, s.has_points));
    const GroundBox& b = seen.back();
    if (seen.size() == 1) grid.footprint = b;
    grid.footprint = {std::min(grid.footprint.u0, b.u0), std::max(grid.footprint.u1, b.u1),
                      std::min(grid.footprint.v0, b.v0), std::max(grid.footprint.v1, b.v1)};
  }
  GroundBox& fp = grid.footprint;
  // A footprint without width (one line of camera centres, no points):
  // widen it to square cells' size so the cells have an area.
  const double extent = std::max({fp.u1 - fp.u0, fp.v1 - fp.v0, 1e-6});
  if (fp.u1 - fp.u0 < 1e-9 * extent)
    fp = {fp.u0 - 0.5 * extent, fp.u1 + 0.5 * extent, fp.v0, fp.v1};
  if (fp.v1 - fp.v0 < 1e-9 * extent)
    fp = {fp.u0, fp.u1, fp.v0 - 0.5 * extent, fp.v1 + 0.5 * extent};
  if (options.rows > 0) {
    grid.rows = options.rows;
    grid.cols = options.cols;
  } else {
    std::tie(grid.rows, grid.cols) = grid_shape(options.blocks, fp.u1 - fp.u0, fp.v1 - fp.v0);
  }
  core::require(grid.blocks() >= 1 && grid.blocks() <= 10000,
                "--blocks: expected 1 to 10000 blocks, got " + std::to_string(grid.blocks()));

  const std::vector<core::Vec3> points = point_list(s.points);
  std::vector<std::vector<int>> views(size_t(grid.blocks()));
  std::vector<std::vector<int64_t>> members(size_t(grid.blocks()));
  for (int b = 0; b < grid.blocks(); ++b) {
    const GroundBox box = grid.margined(b);
    for (size_t v = 0; v < seen.size(); ++v) {
      const GroundBox& f = seen[v];
      const bool in =
          f.area() > 0 ? box.shared(f) >= kViewShare * f.area() : box.contains(f.u0, f.v0);
      if (in) views[size_t(b)].push_back(int(v));
    }
    for (size_t p = 0; p < points.size(); ++p)
      if (box.contains(grid.frame.along(points[p]), grid.frame.across(points[p])))
        members[size_t(b)].push_back(int64_t(p));
    const std::string name = block_name(b, grid.blocks());
    const size_t train = size_t(std::count_if(views[size_t(b)].begin(), views[size_t(b)].end(),
                                              [&](int v) { return s.test.count(v) == 0; }));
    core::require(train > 0, s.transforms_path,
                  name + " (row " + std::to_string(b / grid.cols) + ", column " +
                      std::to_string(b % grid.cols) + " of " + std::to_string(grid.rows) + "x" +
                      std::to_string(grid.cols) +
                      ") has no training view: use fewer blocks or more --overlap");
  }

  // What a block needs to train as the flight's model would have trained
  // its ground: the flight's training views and extent.
  BlockContext context;
  context.frame = grid.frame;
  context.flight_train_views = int64_t(s.scene->train.size());
  context.flight_extent = scene_extent(*s.scene, s.scene->train);
  const torch::Tensor backdrop = flight_backdrop(*s.scene, s.scene->train);
  context.background.assign(backdrop.data_ptr<float>(),
                            backdrop.data_ptr<float>() + backdrop.numel());
  core::log_info("partition: the flight's backdrop, which every block draws over: " +
                 describe_colour(backdrop));
  write_folder_atomically(request, [&](const fs::path& tmp) {
    for (int b = 0; b < grid.blocks(); ++b) {
      BlockRecord record;
      record.name = block_name(b, grid.blocks());
      record.row = b / grid.cols;
      record.col = b % grid.cols;
      context.name = record.name;
      context.cell = grid.cell(b);
      context.margined = grid.margined(b);
      write_block(s, views[size_t(b)], members[size_t(b)], context, tmp / record.name, &record);
      core::log_info("partition: " + record.name + ": " +
                     std::to_string(record.train_views.size()) + " training and " +
                     std::to_string(record.test_views.size()) + " held-out views, " +
                     std::to_string(record.points) + " points");
      file.blocks.push_back(std::move(record));
    }
    write_blocks_file(tmp / "blocks.json", file);
  });
  return file;
}

}  // namespace ddhgs::io
